#include "textile_handling/db/drape_build_members.h"

#include <algorithm>
#include <set>
#include <sstream>

#include "textile_handling/db/database_errors.h"

namespace textile_handling {
namespace db {

std::vector<DrapeMemberSpec> standardDrapeMembers() {
  std::vector<DrapeMemberSpec> out;
  auto add = [&](const std::string& name, const std::string& what) -> DrapeMemberSpec& {
    out.push_back(DrapeMemberSpec{});
    out.back().name = name;
    out.back().description = what;
    return out.back();
  };
  add("base", "the build's own settings (the thesis's flat horizontal release by default)");
  add("heap", "picked from a heap: two random folds, lifted 75 deg by the hold point").start_heap = HeapStart{2, 1, 75};
  {
    DrapeMemberSpec& m = add("tilted", "released tilted 45 deg about the textile's x axis");
    m.start_tilt_deg = 45;
  }
  add("soft_light", "bending and shear x0.5, areal density x0.8").material_variation = MaterialVariation{0.5, 0.5, 0.8};
  add("stiff_heavy", "bending and shear x1.5, areal density x1.2").material_variation = MaterialVariation{1.5, 1.5, 1.2};
  add("heap_b", "picked from a heap: three random folds (other seed), lifted 60 deg").start_heap = HeapStart{3, 2, 60};
  add("self_collision", "flat release with self-collision v3").self_collision = true;
  {
    DrapeMemberSpec& m = add("heap_collision", "picked from a heap (two folds, third seed) with self-collision v3");
    m.start_heap = HeapStart{2, 3, 75};
    m.self_collision = true;
  }
  return out;
}

std::vector<DrapeMemberSpec> drapeMembersByName(const std::string& list) {
  const std::vector<DrapeMemberSpec> known = standardDrapeMembers();
  std::vector<DrapeMemberSpec> out;
  std::set<std::string> seen;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name == "standard") {
      for (const auto& m : known)
        if (seen.insert(m.name).second) out.push_back(m);
      continue;
    }
    const auto it = std::find_if(known.begin(), known.end(), [&](const DrapeMemberSpec& m) { return m.name == name; });
    if (it == known.end()) {
      std::string names;
      for (const auto& m : known) names += (names.empty() ? "" : ", ") + m.name;
      throw InvalidInputError("members: unknown member '" + name + "' (known: " + names + ", standard)");
    }
    if (!seen.insert(name).second) throw InvalidInputError("members: '" + name + "' is listed twice");
    out.push_back(*it);
  }
  if (out.empty()) throw InvalidInputError("members: the list is empty");
  return out;
}

DrapeBuildConfig memberBuildConfig(const DrapeBuildConfig& base, const DrapeMemberSpec& member) {
  if (member.name == "base") return base;
  DrapeBuildConfig c = base;
  c.member = member.name;
  c.start_tilt_deg = member.start_tilt_deg;
  c.start_tilt_axis_deg = member.start_tilt_axis_deg;
  c.start_heap = member.start_heap;
  c.self_collision = member.self_collision;
  c.material_variation = member.material_variation;
  return c;
}

std::string memberOfParameters(const std::string& parameters) {
  std::stringstream ss(parameters);
  std::string line;
  const std::string key = "member: ";
  while (std::getline(ss, line))
    if (line.rfind(key, 0) == 0) return line.substr(key.size());
  return "base";
}

std::map<std::string, int> storedMembers(const HangingDrapeDatabase& db, std::int64_t textile_id) {
  const TextileRecord t = db.textile(textile_id);
  std::map<std::string, int> out;
  for (const SimulationRecord& s : db.simulations(textile_id))
    if (s.active && s.status == SimulationStatus::kDone) ++out[memberOfParameters(s.parameters)];
  return out;
}

std::vector<DrapeBuildReport> buildDrapeMembers(HangingDrapeDatabase& db, const DrapeBuildConfig& base,
                                                const std::vector<DrapeMemberSpec>& members,
                                                const std::function<void(const DrapeMemberSpec&)>& on_member) {
  std::vector<DrapeBuildReport> reports;
  for (const DrapeMemberSpec& m : members) {
    if (base.should_stop && base.should_stop()) break;
    if (on_member) on_member(m);
    DrapeDatabaseBuilder builder(db, memberBuildConfig(base, m));
    reports.push_back(builder.build());
  }
  return reports;
}

}  // namespace db
}  // namespace textile_handling
