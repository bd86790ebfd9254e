// Names, parsing and checking of the self-collision options; summing of the statistics.
#include "textile_handling/sim/self_collision_options.h"
#include "textile_handling/sim/sim_errors.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace textile_handling {

std::string toString(SelfCollisionVersion v) {
  switch (v) {
    case SelfCollisionVersion::kPointPath: return "v1_point_path";
    case SelfCollisionVersion::kEdge: return "v2_edge";
    case SelfCollisionVersion::kRollback: return "v3_rollback";
  }
  return "unknown";
}

SelfCollisionVersion selfCollisionVersionFromString(const std::string& s) {
  if (s == "1" || s == "v1" || s == "point_path" || s == "v1_point_path") return SelfCollisionVersion::kPointPath;
  if (s == "2" || s == "v2" || s == "edge" || s == "v2_edge") return SelfCollisionVersion::kEdge;
  if (s == "3" || s == "v3" || s == "rollback" || s == "v3_rollback") return SelfCollisionVersion::kRollback;
  throw SimError("unknown self-collision version '" + s + "' (expected v1, v2 or v3)");
}

void SelfCollisionStats::add(const SelfCollisionStats& o) {
  crossings += o.crossings;
  events += o.events;
  thesis_events += o.thesis_events;
  fallback_events += o.fallback_events;
  passes += o.passes;
  unresolved += o.unresolved;
  broad_ms += o.broad_ms;
  detect_ms += o.detect_ms;
  resolve_ms += o.resolve_ms;
  point_test_rejections += o.point_test_rejections;
  proximity_pairs += o.proximity_pairs;
  proximity_contacts += o.proximity_contacts;
  proximity_edge_projections += o.proximity_edge_projections;
  proximity_ms += o.proximity_ms;
  proximity_detect_ms += o.proximity_detect_ms;
  candidate_list_builds += o.candidate_list_builds;
  proximity_list_builds += o.proximity_list_builds;
  detections_from_proximity_build += o.detections_from_proximity_build;
}

void validateSelfCollisionOptions(const SelfCollisionOptions& o, const std::string& what) {
  std::ostringstream bad;
  // One line per field outside its range; NaN fails every check (the comparisons are negated).
  auto check = [&bad](bool ok, const char* field, double value, const char* range) {
    if (!ok) bad << "\n  " << field << " = " << value << ", accepted: " << range;
  };
  check(o.d_min >= 0, "d_min", o.d_min, ">= 0 [m]");
  check(o.max_passes >= 1, "max_passes", o.max_passes, ">= 1");
  check(o.cell_size_factor > 0, "cell_size_factor", o.cell_size_factor, "> 0");
  check(o.barycentric_tolerance >= 0, "barycentric_tolerance", o.barycentric_tolerance, ">= 0");
  check(o.restitution >= 0 && o.restitution <= 1, "restitution", o.restitution, "[0, 1]");
  check(o.tangential_damping >= 0 && o.tangential_damping <= 1, "tangential_damping", o.tangential_damping, "[0, 1]");
  check(o.thickness_factor > 0 && o.thickness_factor < 0.35, "thickness_factor", o.thickness_factor, "(0, 0.35)");
  check(o.proximity_separation >= 0 && o.proximity_separation <= 1, "proximity_separation", o.proximity_separation,
        "[0, 1]");
  check(o.proximity_friction >= 0 && std::isfinite(o.proximity_friction), "proximity_friction", o.proximity_friction,
        ">= 0 and finite");
  check(o.proximity_search_factor >= 1 && o.proximity_search_factor <= 3, "proximity_search_factor",
        o.proximity_search_factor, "[1, 3]");
  check(o.proximity_list_margin >= 0 && o.proximity_list_margin <= 4, "proximity_list_margin", o.proximity_list_margin,
        "[0, 4]");
  check(o.candidate_list_margin >= 0 && o.candidate_list_margin <= 4, "candidate_list_margin", o.candidate_list_margin,
        "[0, 4]");
  check(o.proximity_iterations >= 1, "proximity_iterations", o.proximity_iterations, ">= 1");
  if (!bad.str().empty()) throw SimError(what + ": invalid options:" + bad.str());
}

}  // namespace textile_handling
