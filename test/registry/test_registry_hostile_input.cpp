// The register_textile / resimulate validators under hostile input: oversized outlines and named-point
// lists, names that are not names, absurd coordinates, and a randomized fuzz of requests. Every request
// is either stored or refused with db::InvalidInputError / db::NotFoundError naming the field; refused
// requests store nothing, and the database stays consistent.
#include <gtest/gtest.h>

#include <sys/stat.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "textile_handling/db/database_errors.h"
#include "registry_test_support.h"
#include "textile_handling/registry/textile_registry.h"

namespace textile_handling {
namespace registry {
namespace {

using test_support::expectRefused;
using test_support::smallOptions;
using test_support::tempDb;

TextileRegistration square(const std::string& name) {
  TextileRegistration r;
  r.name = name;
  r.outline = {Vec2(0, 0), Vec2(0.3, 0), Vec2(0.3, 0.3), Vec2(0, 0.3)};
  return r;
}

// A convex polygon of n vertices on a 0.3 m circle (valid but for its size).
std::vector<Vec2> circle(int n) {
  std::vector<Vec2> out;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * M_PI * k / n;
    out.emplace_back(0.3 + 0.3 * std::cos(a), 0.3 + 0.3 * std::sin(a));
  }
  return out;
}

}  // namespace

TEST(RegistryHostileInput, OversizedAndMalformedRequestsAreRefusedAtOnce) {
  TextileRegistry reg(tempDb("sizes"), smallOptions());
  TextileRegistration r = square("huge_outline");
  r.outline = circle(100000);
  expectRefused(reg, r, "limit", "100,000-vertex outline");
  r = square("many_points");
  for (int k = 0; k < 100000; ++k) r.named_points.push_back({"p" + std::to_string(k), "grasp", Vec2(0.15, 0.15)});
  expectRefused(reg, r, "limit", "100,000 named points");
  r = square("injection");
  r.named_points = {{"x'); DROP TABLE grasp_points;--", "grasp", Vec2(0.15, 0.15)}};
  expectRefused(reg, r, "name", "named point with SQL in its name");
  r = square("blank_point");
  r.named_points = {{"", "corner", Vec2(0, 0)}};
  expectRefused(reg, r, "name", "empty named-point name");
  r = square("far_away");
  r.outline = {Vec2(0, 0), Vec2(1e300, 0), Vec2(1e300, 1e300), Vec2(0, 1e300)};
  expectRefused(reg, r, "", "outline of 1e300 m");
  r = square("inf");
  r.outline[1] = Vec2(std::numeric_limits<double>::infinity(), 0);
  expectRefused(reg, r, "outline", "infinite vertex");
  r = square("tiny");
  r.outline = {Vec2(0, 0), Vec2(1e-300, 0), Vec2(1e-300, 1e-300), Vec2(0, 1e-300)};
  expectRefused(reg, r, "", "outline of 1e-300 m");
  r = square("yaml_bomb");
  r.material_yaml = std::string(2 << 20, '[');
  expectRefused(reg, r, "material", "2 MiB of YAML");
  EXPECT_TRUE(reg.list().empty());
  // A legal polygon at the vertex limit's order of magnitude is validated and stored.
  r = square("round_cloth");
  r.outline = circle(1000);
  EXPECT_NO_THROW(reg.registerTextile(r));
  EXPECT_EQ(reg.list().size(), 1u);
}

TEST(RegistryHostileInput, DatabaseDirectoriesGetMode0755UnderUmask000) {
  const std::string root = std::filesystem::path(tempDb("mode")).parent_path().string();
  const std::string path = root + "/a/b/drapes.sqlite";
  const mode_t saved = ::umask(0);
  { TextileRegistry reg(path, smallOptions()); }
  ::umask(saved);
  for (const std::string& dir : {root + "/a", root + "/a/b"}) {
    struct stat st {};
    ASSERT_EQ(::stat(dir.c_str(), &st), 0) << dir;
    EXPECT_EQ(st.st_mode & 07777, 0755u) << dir;
  }
  struct stat st {};
  ASSERT_EQ(::stat(path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 022, 0u) << "the database file is group- or world-writable";
  // A directory that cannot be created is a clear error naming it.
  const std::string blocked = root + "/file";
  { std::ofstream(blocked) << "x"; }
  try {
    TextileRegistry reg(blocked + "/sub/drapes.sqlite", smallOptions());
    ADD_FAILURE() << "opened a database below a file";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find(blocked), std::string::npos) << e.what();
  }
}

TEST(RegistryHostileInput, RandomRequestsAreStoredOrRefusedCleanly) {
  TextileRegistry reg(tempDb("fuzz"), smallOptions());
  std::mt19937 rng(15);
  auto pick = [&](auto const& v) { return v[std::uniform_int_distribution<std::size_t>(0, v.size() - 1)(rng)]; };
  const std::vector<double> coords{0,     0.3,  0.15, -0.2, 1.0,  1e300, -1e300, 1e-300,
                                   std::nan(""), std::numeric_limits<double>::infinity(), -0.0, 0.299999};
  const std::vector<std::string> names{"napkin", "", "a b", std::string(65, 'x'), "tow\xc3\xa9l", "t;--", "ok_name.1",
                                       "..", "-", "x'); DROP TABLE textiles;--", std::string(1, '\0') + "z"};
  const std::vector<std::string> yamls{"", "name: m\nareal_density: -1\n", "{", "[1, 2", "name: x\n",
                                       "areal_density: .nan\n", std::string(300, '{')};
  const std::vector<std::string> models{"", "particle_kes", "choi_ko", "yarn", "\n"};
  int accepted = 0;
  for (int it = 0; it < 300; ++it) {
    // A valid request with 0-2 random faults (so that both answers occur).
    TextileRegistration r = square("cloth" + std::to_string(it));
    r.named_points = {{"tip", "corner", Vec2(0.3, 0.3)}};
    r.hold_point_spacing = 0.15;
    const int faults = std::uniform_int_distribution<int>(0, 2)(rng);
    for (int f = 0; f < faults; ++f) {
      switch (std::uniform_int_distribution<int>(0, 6)(rng)) {
        case 0: r.name = pick(names); break;
        case 1: r.outline[std::uniform_int_distribution<std::size_t>(0, 3)(rng)] = Vec2(pick(coords), pick(coords)); break;
        case 2: r.outline.resize(std::uniform_int_distribution<std::size_t>(0, 5)(rng), Vec2(pick(coords), pick(coords))); break;
        case 3: r.named_points.push_back({pick(names), pick(names), Vec2(pick(coords), pick(coords))}); break;
        case 4: r.material_yaml = pick(yamls); break;
        case 5: r.hold_point_spacing = pick(coords); break;
        default: r.model = pick(models); break;
      }
    }
    try {
      reg.registerTextile(r);
      ++accepted;
    } catch (const db::InvalidInputError& e) {
      EXPECT_GT(std::string(e.what()).size(), 5u) << "iteration " << it;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "iteration " << it << ": wrong exception type: " << e.what();
    }
    ResimulationRequest q;
    q.textile_id = std::uniform_int_distribution<int>(-2, 3)(rng);
    q.spacing = pick(coords);
    q.model = pick(models);
    q.material_yaml = pick(yamls);
    try {
      reg.resimulate(q);
    } catch (const db::DrapeDatabaseError& e) {
      EXPECT_GT(std::string(e.what()).size(), 5u) << "iteration " << it;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "iteration " << it << ": wrong exception type in resimulate: " << e.what();
    }
  }
  // What was stored is exactly what was accepted, and every stored textile is valid.
  const auto list = reg.list();
  EXPECT_EQ(static_cast<int>(list.size()), accepted);
  for (const TextileSummary& s : list) {
    std::string why;
    EXPECT_TRUE(validateTextileOutline(s.record.outline, &why)) << s.record.outline.name << ": " << why;
  }
  db::HangingDrapeDatabase check(reg.databasePath());
  EXPECT_TRUE(check.consistencyProblems().empty());
  std::printf("fuzzed 300 registrations: %d accepted\n", accepted);
}

}  // namespace registry
}  // namespace textile_handling
