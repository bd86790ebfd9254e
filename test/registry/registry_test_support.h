// Shared by the registry suites: temporary database paths, small fast build options, a test textile.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

#include "../test_support.h"
#include "textile_handling/db/database_errors.h"
#include "textile_handling/registry/textile_registry.h"

namespace textile_handling {
namespace registry {
namespace test_support {

/// A database path in a fresh temporary directory unique to the process and `tag`.
inline std::string tempDb(const std::string& tag) {
  return textile_handling::test_support::freshTempDir("th_registry_" + tag) + "/drapes.sqlite";
}

/// Small, fast builds: coarse particle grid (d = 5 cm), 4 views, lattice 15 cm, one worker.
inline RegistryOptions smallOptions() {
  RegistryOptions o;
  o.build.spacing = 0.05;
  o.build.lattice_spacing = 0.15;
  o.build.views.count = 4;
  o.build.views.step_deg = 90;
  o.build.workers = 1;
  o.build.settings.max_time = 6.0;
  o.material_dir = std::string(TEXTILE_HANDLING_SOURCE_DIR) + "/data/materials";
  return o;
}

/// A 30 x 30 cm square with two corners and a middle grasp point.
inline TextileRegistration napkin(const std::string& name = "napkin") {
  TextileRegistration r;
  r.name = name;
  r.outline = {Vec2(0, 0), Vec2(0.3, 0), Vec2(0.3, 0.3), Vec2(0, 0.3)};
  r.named_points = {{"corner_a", "corner", Vec2(0, 0)}, {"corner_b", "corner", Vec2(0.3, 0.3)},
                    {"middle", "grasp", Vec2(0.15, 0.15)}};
  r.material_name = "cotton";
  return r;
}

/// Registers `r` and expects a refusal (db::InvalidInputError) whose message contains `needle`.
inline void expectRefused(TextileRegistry& reg, const TextileRegistration& r, const std::string& needle,
                          const std::string& what) {
  try {
    reg.registerTextile(r);
    ADD_FAILURE() << what << ": accepted";
  } catch (const db::InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << what << ": '" << e.what() << "'";
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << ": wrong exception type: " << e.what();
  }
}

}  // namespace test_support
}  // namespace registry
}  // namespace textile_handling
