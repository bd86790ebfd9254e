// Settings and statistics of the self-collision pass (SelfCollisionPass): the thesis version, the
// velocity response, v3's proximity stage (docs/collision.md), the option check, and what one
// apply() did. Lengths are multiples of the grid spacing d where noted, else in m. ROS-free.
#pragma once

#include <string>

#include "textile_handling/sim/types.h"

namespace textile_handling {

enum class SelfCollisionVersion {
  kPointPath = 1,  ///< v1: segment old->new position of each particle vs the triangles
  kEdge = 2,       ///< v2: grid edges vs triangles, side change of the endpoints, push by d_min
  kRollback = 3,   ///< v3 (thesis final): edge test + candidate set + rollback to x_old
};
std::string toString(SelfCollisionVersion v);
/// Parses "1"/"v1"/"point_path", "2"/"v2"/"edge", "3"/"v3"/"rollback"; throws std::invalid_argument.
SelfCollisionVersion selfCollisionVersionFromString(const std::string& s);

/// Velocity response of a collision handled by version 3 (docs/collision.md, "velocity response").
enum class CollisionResponse {
  /// Default: every free particle of a handled collision (the point or edge and the triangle's
  /// corners, all rolled back) stops, v = 0. Consistent with the rollback (the particles did not
  /// move during the step) and dissipative; the only response that let the drape scenes rest.
  kStop,
  /// The thesis: every particle's own velocity is reflected, v' = v_par + e |v_n| n for the
  /// penetrating point and v' = v_par - e |v_n| n for the triangle corners, with the tangential
  /// damping applied to v_par. Gains energy in our runs (docs/collision.md).
  kThesis,
  /// A momentum-conserving impulse on the relative velocity of the point (or edge) and the
  /// triangle: an approaching relative normal velocity u_n becomes -e u_n, the relative tangential
  /// velocity is reduced by the tangential damping; equal particle masses, pinned = immovable.
  kRelative,
};

struct SelfCollisionOptions {
  SelfCollisionVersion version = SelfCollisionVersion::kRollback;
  /// Minimum distance of the push of v1 and v2 [m] (unused by v3).
  Real d_min = 1e-3;
  /// Cap on the repeated passes within one apply() (thesis: repeat until none is left).
  int max_passes = 100;
  /// v3: test the cell diagonals as edges too (they are triangle edges; without them a crossing
  /// that only involves diagonals goes unnoticed). v1/v2 follow the thesis: grid edges only.
  bool include_diagonals = true;
  /// v3: a side change only counts when the linearised crossing point lies inside the candidate
  /// triangle, i.e. its barycentric coordinates are >= -barycentric_tolerance (docs/collision.md).
  bool point_in_triangle_check = true;
  Real barycentric_tolerance = 0.25;
  /// v3: when an edge still crosses a triangle and no candidate side change explained it, roll back
  /// the edge's endpoints and the crossed triangle's corners as well (extension, see docs): makes
  /// the result intersection-free whenever x_old was and the pinned particles did not move.
  bool fallback_rollback = true;
  CollisionResponse response = CollisionResponse::kStop;
  /// Restitution e of kThesis / kRelative and of the v1/v2 pushes: 1 = the thesis's reflection,
  /// 0 = the approaching normal velocity is removed.
  Real restitution = 1.0;
  /// Fraction of the tangential (relative) velocity removed at a collision (kThesis, kRelative,
  /// v1/v2): 0 = the thesis (v_par kept).
  Real tangential_damping = 0.0;
  /// Broad-phase cell size as a multiple of the grid spacing d (v3 hashes grid cells, i.e. pairs of
  /// triangles, with boxes inflated by the candidate-list radius: 3 was fastest on the 1 cm towel).
  Real cell_size_factor = 3.0;

  // ---- v3 proximity stage (this module's addition; docs/collision.md, "Persistent contact").
  // Runs before the crossing detection of v3: every vertex-triangle and edge-edge pair of
  // non-adjacent features closer than 1.5 T (proximity_search_factor) at x_old whose step would
  // bring it closer than the thickness T is projected back to the thickness with a
  // momentum-conserving inelastic correction (Bridson, Fedkiw & Anderson 2002, in positions as in
  // position-based dynamics) with Coulomb friction, the velocities following the corrected step.
  // The rollback stays as the fail-safe for whatever still crosses. With a ContactForceModel the
  // contact forces also enter the next implicit solve, which makes resting contact a fixed point.
  /// Off = v3 exactly as before (rollback only).
  bool proximity = true;
  /// Cloth thickness T as a multiple of the grid spacing d (T = thickness_factor d), in (0, 0.35).
  /// The default keeps the candidate lists (2 T) below the 0.707 d of non-adjacent features in a
  /// flat sheet.
  Real thickness_factor = 0.25;
  /// Fraction of the thickness deficit (T - gap) restored per step for pairs already closer than T
  /// (0 = purely inelastic, the gap is only kept).
  Real proximity_separation = 0.1;
  /// Coulomb friction coefficient mu of cloth on cloth (sticking while the tangential force stays
  /// within mu times the normal force).
  Real proximity_friction = 0.3;
  /// Search radius of the stage in thicknesses: pairs closer than this at x_old are tested, so an
  /// approach of up to (factor - 1) T per step is stopped at the thickness (faster ones are left to
  /// the rollback). In [1, 3]; larger finds more contacts early at a higher cost (docs).
  Real proximity_search_factor = 1.5;
  /// Margin of the proximity candidate list (Verlet list) in thicknesses: the list holds the pairs
  /// within Rp = (proximity_search_factor + proximity_list_margin) T at its build and stays valid
  /// while the particles' motion since then, less the best-fitting rigid motion, moved no two of
  /// them apart by more than the margin (docs/collision.md, "Broad phase and cost"). In [0, 4];
  /// only the cost depends on it (0.75 was slower than 0.5 on the 1 cm towel).
  Real proximity_list_margin = 0.5;
  /// Extra inflation Rc - Rp of the candidate triangle-pair list, in thicknesses (in [0, 4]): with
  /// it the pair list outlives proximity lists, which are then rebuilt from it without the hash.
  /// Only the cost depends on it (0.5 was cheaper than 0 and 1 on the 1 cm towel).
  Real candidate_list_margin = 0.5;
  /// Gauss-Seidel sweeps over the contacts (and the grid edges around them) per step.
  int proximity_iterations = 8;
  /// After each sweep over the contacts, restore the grid edges around the moved particles to their
  /// lengths after the step (Provot 1995 style), so that a contact moves the patch the integrator
  /// moved as one instead of straining the stiff tension springs.
  bool proximity_propagate = true;
  /// Also edge-edge pairs (crossing edges of two layers; pairs of two cell diagonals excepted), not
  /// only vertex-triangle pairs.
  bool proximity_edges = true;
  /// Whether a scene wraps its model in a ContactForceModel (see withContactForces()), so that the
  /// contact forces enter the implicit solve. The pass itself only needs the wrapper to exist.
  bool contact_forces = true;

  /// Version 3 exactly as the thesis describes it, without this module's additions: grid edges only,
  /// no point-in-triangle check, no fallback rollback, the thesis's velocity reflection (e = 1).
  static SelfCollisionOptions thesisLiteral() {
    SelfCollisionOptions o;
    o.include_diagonals = false;
    o.point_in_triangle_check = false;
    o.fallback_rollback = false;
    o.response = CollisionResponse::kThesis;
    o.restitution = 1.0;
    o.tangential_damping = 0.0;
    o.proximity = false;
    return o;
  }
};

/// What one apply() did.
struct SelfCollisionStats {
  long crossings = 0;         ///< edge-triangle crossings (v2, v3) or path hits (v1) found in the first pass
  long events = 0;            ///< collisions handled (the value apply() returns)
  long thesis_events = 0;     ///< v3: rollbacks triggered by a candidate side change
  long fallback_events = 0;   ///< v3: fallback rollbacks (see SelfCollisionOptions::fallback_rollback)
  int passes = 0;             ///< detection passes that found something to handle
  long unresolved = 0;        ///< crossings still present when apply() returned (cap or unresolvable)
  long point_test_rejections = 0;  ///< v3: side changes discarded by the point-in-triangle check
  long proximity_pairs = 0;     ///< proximity stage: close pairs found (vertex-triangle + edge-edge)
  long proximity_contacts = 0;  ///< proximity stage: pairs whose approach was corrected (contacts)
  long proximity_edge_projections = 0;  ///< proximity stage: grid-edge length restorations
  double proximity_ms = 0;         ///< proximity stage in all (detection, resolution, box refresh)
  double proximity_detect_ms = 0;  ///< of which the detection of close pairs
  long candidate_list_builds = 0;  ///< broad-phase candidate lists built (v3: reused while valid)
  long proximity_list_builds = 0;  ///< proximity candidate lists built (v3: reused while valid)
  /// v3: first detections of a pass that tested only the triangle pairs of the proximity build
  /// (no two particles moved apart by more than its radius since; else the candidate pairs)
  long detections_from_proximity_build = 0;
  double broad_ms = 0;        ///< building boxes and the hash
  double detect_ms = 0;       ///< candidate detection (parallel)
  double resolve_ms = 0;      ///< resolution (sequential, fixed order)
  void add(const SelfCollisionStats& o);
};

/// Checks every option against its accepted range. Throws std::invalid_argument naming each bad field
/// with its value and range (one line per field), prefixed by `what`; returns when all are valid.
void validateSelfCollisionOptions(const SelfCollisionOptions& o, const std::string& what = "SelfCollisionPass");

}  // namespace textile_handling
