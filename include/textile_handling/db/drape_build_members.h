// Database members: several rest shapes per hold point, each made another physically plausible way
// (released flat or tilted, picked from a heap, with and without self-collision, with the material's
// bending, shear and density varied). Every member is one build of the same textile into the same
// generation with its own parameter text (which names the member), so the rows of one hold point form
// one class in the match index whatever made them, and every member's build resumes on its own.
// Builder library (textile_handling_db_builder). See docs/database.md, "Members".
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace db {

/// How one member differs from the base build. Name "base" = the build's own settings (no member line
/// in the parameter text, so rows of builds made before members existed are the base member).
struct DrapeMemberSpec {
  std::string name;
  std::string description;
  Real start_tilt_deg = 0;
  Real start_tilt_axis_deg = 0;
  HeapStart start_heap;
  bool self_collision = false;
  MaterialVariation material_variation;
};

/// The members `drape_db build --members` knows, in the order "standard" adds them: base, heap, tilted,
/// soft_light, stiff_heavy, heap_b, self_collision, heap_collision (descriptions in the returned specs).
std::vector<DrapeMemberSpec> standardDrapeMembers();

/// Members by name from a comma-separated list ("standard" = all of standardDrapeMembers(); "base" first
/// when listed). Throws InvalidInputError naming an unknown or repeated member.
std::vector<DrapeMemberSpec> drapeMembersByName(const std::string& list);

/// `base` made into the build of `member`: its start, self-collision and material variation replace the
/// base's (the base member returns `base` unchanged).
DrapeBuildConfig memberBuildConfig(const DrapeBuildConfig& base, const DrapeMemberSpec& member);

/// The member named in a simulation's parameter text ("base" when it names none).
std::string memberOfParameters(const std::string& parameters);

/// Finished simulations of a textile's active generation per member name.
std::map<std::string, int> storedMembers(const HangingDrapeDatabase& db, std::int64_t textile_id);

/// Builds every member in turn (one DrapeDatabaseBuilder each; `base`'s callbacks apply to every one).
/// `on_member` (optional) is called before each member's build. Stops early, returning the reports so
/// far, when base.should_stop says so. Throws what the builder throws (InvalidInputError before the
/// first write of a member whose settings are bad).
std::vector<DrapeBuildReport> buildDrapeMembers(HangingDrapeDatabase& db, const DrapeBuildConfig& base,
                                                const std::vector<DrapeMemberSpec>& members,
                                                const std::function<void(const DrapeMemberSpec&)>& on_member = {});

}  // namespace db
}  // namespace textile_handling
