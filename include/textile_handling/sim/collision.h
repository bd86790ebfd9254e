// Self-collision and obstacle handling for the drape simulator (thesis section 3.3 / summary section 7),
// as post-step passes run by DrapeSimulation after every accepted step. ROS-free. See docs/collision.md
// for the algorithms, the decisions on the thesis's open points and the known failure cases.
//
//  - ClothTriangles: the thesis triangulation of the particle grid (each particle p0 owns the
//    triangles (p0, right, up) and (p0, left, down)), its edges and adjacency;
//  - SelfCollisionPass: the three versions of the thesis (v1 point path, v2 edge test, v3 edge test
//    with candidate set and rollback), with a spatial-hash broad phase; v3 adds a proximity stage
//    that keeps resting cloth-on-cloth contact at a thickness (persistent contact);
//  - ContactForceModel / withContactForces(): feed the proximity stage's contact forces into the
//    implicit solve, which makes resting contact a fixed point;
//  - ObstaclePass: planes, boxes and spheres with a contact distance and Coulomb-like friction;
//  - PostStepPassChain: runs several passes in order and sums their event counts;
//  - countIntersectingTrianglePairs(): an independent exact checker (Devillers-Guigue).
//
// Positions are 3 DOFs per particle (ParticleClothModel). Lengths in m, velocities in m/s.
#pragma once

#include <array>
#include <memory>
#include <cstdint>
#include <unordered_map>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/cloth_topology.h"

namespace textile_handling {

// ---- triangulation -------------------------------------------------------------------------------

/// The thesis triangulation of a particle grid plus the adjacency the collision passes need.
struct ClothTriangles {
  Index num_vertices = 0;
  Real spacing = 0.01;  ///< rest distance d of the grid [m] (cell size of the broad phase)
  /// Corners of each triangle: (p0, right, up) or (p0, left, down), in that order.
  std::vector<std::array<Index, 3>> triangles;
  /// p0 of each triangle.
  std::vector<Index> owner;
  /// Per particle: [0] = its (p0, right, up) triangle, [1] = its (p0, left, down) triangle; -1 if the
  /// triangle does not exist (a corner is missing).
  std::vector<std::array<Index, 2>> owned;
  /// Unique edges (a < b): first the grid edges between neighbours, then the cell diagonals
  /// (right-up of an upper triangle = left-down of a lower triangle) that are not grid edges.
  std::vector<std::array<Index, 2>> edges;
  Index num_grid_edges = 0;  ///< edges[0 .. num_grid_edges) are grid edges, the rest diagonals
  /// The three edges of each triangle (ids into `edges`).
  std::vector<std::array<Index, 3>> triangle_edges;
  /// Triangles incident to each vertex (CSR; ascending ids).
  std::vector<Index> vertex_triangle_start, vertex_triangle_list;
  /// Version-3 candidate set of each particle p0 (CSR; ascending ids): every triangle that shares a
  /// vertex with one of p0's two triangles (p0's own triangles included). Empty when p0 owns none.
  std::vector<Index> candidate_start, candidate_list;
  /// Mass of each particle, relative (the area it represents: the cloth is uniform). Weights the
  /// momentum-conserving impulses of the proximity stage; empty = equal masses.
  std::vector<Real> vertex_mass;

  Index numTriangles() const { return static_cast<Index>(triangles.size()); }
  Index numEdges() const { return static_cast<Index>(edges.size()); }
  bool triangleHasVertex(Index t, Index v) const {
    const auto& c = triangles[static_cast<size_t>(t)];
    return c[0] == v || c[1] == v || c[2] == v;
  }
  bool trianglesShareVertex(Index s, Index t) const {
    const auto& c = triangles[static_cast<size_t>(s)];
    return triangleHasVertex(t, c[0]) || triangleHasVertex(t, c[1]) || triangleHasVertex(t, c[2]);
  }

  /// Builds the triangulation of a particle topology (thesis section 7: a triangle exists when all
  /// three of its corners exist).
  static ClothTriangles fromTopology(const ParticleTopology& topo);
};

/// A list that one thread appends to, on cache lines of its own: the lists of several threads
/// sit side by side in a std::vector, and without the alignment the vector headers that every
/// append writes would share a cache line (false sharing).
template <class T>
struct alignas(64) ThreadList {
  std::vector<T> items;
};

/// Pinned-particle mask (1 = pinned) of size n from a PinnedNodes list.
std::vector<char> pinnedMask(Index num_particles, const PinnedNodes& pins);

// ---- independent checker --------------------------------------------------------------------------

/// All pairs (s, t), s < t, of triangles that share no vertex and intersect (closed triangles, exact
/// predicates, see geom::triangleTriangleIntersect), sorted. Broad phase: a uniform AABB grid.
std::vector<std::pair<Index, Index>> findIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x);
/// Size of findIntersectingTrianglePairs().
long countIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x);
/// Same, by testing all pairs (O(T^2)); for checking the broad phase in tests.
long countIntersectingTrianglePairsBruteForce(const ClothTriangles& tris, const VecX& x);

// ---- self-collision ---------------------------------------------------------------------------------

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

/// Self-collision pass. Construct once per simulation (the triangulation is copied); apply() is called
/// by DrapeSimulation after every accepted step. Pinned particles are never moved and their velocity
/// is never changed. Results do not depend on the number of OpenMP threads.
class SelfCollisionPass : public PostStepPass {
 public:
  SelfCollisionPass(ClothTriangles tris, std::vector<char> pinned_mask, SelfCollisionOptions options = {});
  SelfCollisionPass(const ParticleTopology& topo, const PinnedNodes& pins, SelfCollisionOptions options = {});

  long apply(const VecX& x_old, VecX& x, VecX& v) override;

  const SelfCollisionOptions& options() const { return options_; }
  void setOptions(const SelfCollisionOptions& o) {
    options_ = o;
    list_valid_ = false;
    cand_valid_ = false;
  }
  const ClothTriangles& triangles() const { return tris_; }
  const SelfCollisionStats& lastStats() const { return last_; }
  const SelfCollisionStats& totalStats() const { return total_; }
  long calls() const { return calls_; }
  /// Contact forces of the last step as accelerations per DOF [m/s^2] (force = particle mass x
  /// acceleration; they sum to zero momentum); empty when there are none or no ContactForceModel
  /// uses them.
  const VecX& contactAccelerations() const { return contact_accel_; }
  /// Forgets the contact forces of the last step.
  void resetContactForces() {
    contact_memory_.clear();
    contact_accel_.resize(0);
  }
  void resetStats() {
    total_ = SelfCollisionStats{};
    calls_ = 0;
  }

 private:
  struct Hit {
    Index a;  // edge id (v2, v3) or particle (v1)
    Index t;  // triangle id
    bool operator<(const Hit& o) const { return a != o.a ? a < o.a : t < o.t; }
    bool operator==(const Hit& o) const { return a == o.a && t == o.t; }
  };

  /// boxes_[t]: the box swept by triangle t from x_old to x (and `ahead` steps further along the same
  /// motion when > 0), inflated by `inflate`.
  void computeTriangleBoxes(const VecX& x_old, const VecX& x, Real inflate, Real ahead);
  geom::Aabb triangleBox(Index t, const VecX& x_old, const VecX& x, Real inflate, Real ahead) const;
  // The swept triangle and edge boxes of the step (computeTriangleBoxes(.., 0, 0) and
  // computeEdgeBoxes) in one parallel region: each region's start costs about 13 us on the 2-core
  // VM with passive waiting, more than one of these loops.
  void computeSweptBoxes(const VecX& x_old, const VecX& x);
  void buildHash(const VecX& x_old, const VecX& x, Real inflate);
  void computeEdgeBoxes(const VecX& x_old, const VecX& x);
  geom::Aabb edgeBox(Index e, const VecX& x_old, const VecX& x) const;
  bool edgeCrosses(Index e, Index t, const VecX& x) const;
  const Index* ownedEdges(Index t) const { return owned_list_.data() + owned_start_[static_cast<size_t>(t)]; }
  int numOwnedEdges(Index t) const {
    return static_cast<int>(owned_start_[static_cast<size_t>(t) + 1] - owned_start_[static_cast<size_t>(t)]);
  }
  // All edge-triangle crossings among edges [0, num_edges_considered).
  void detectEdges(Index num_edges_considered, const VecX& x, std::vector<Hit>& hits) const;
  // The crossings of pairs with a particle in `moved` (moved during the last pass).
  void detectIncremental(const std::vector<Index>& moved, Index num_edges_considered, const VecX& x,
                         std::vector<Hit>& hits) const;
  long applyV1(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st);
  long applyV2(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st);
  long applyV3(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st);
  // v3 helpers.
  bool sideChanged(Index q, Index t, const VecX& x_old, const VecX& x) const;
  bool rollback(Index p, const VecX& x_old, VecX& x, std::vector<Index>& moved) const;
  void reflect(Index p, const Vec3& n, VecX& v) const;
  // Velocity response of a collision between group a (moving along +n) and group b (along -n).
  void respond(const Index* a, int na, const Index* b, int nb, const Vec3& n, VecX& v) const;
  // Proximity stage (docs/collision.md, "Persistent contact").
  struct ProxPair {
    int type;       // 0: vertex a - triangle b; 1: edge a - edge b (a < b)
    Index a, b;
    Index idx[4];   // particles: the a side first
    Real w[4];      // relative-displacement weights: +weights on the a side, -weights on the b side
    Vec3 n;         // unit normal at x_old, from the b side toward the a side
    Real gap;       // distance along n at x_old (> 0)
    bool operator<(const ProxPair& o) const {
      return type != o.type ? type < o.type : (a != o.a ? a < o.a : b < o.b);
    }
  };
  void detectProximity(const VecX& x_old, Real thickness, std::vector<ProxPair>& pairs) const;
  void buildProximityCache(const VecX& x_old, Real radius);
  // Proximity search radius R = proximity_search_factor T; the radius Rp of the proximity list (R
  // plus its margin) and the inflation Rc >= Rp of the candidate triangle-pair list.
  Real proximitySearchRadius(Real thickness) const { return options_.proximity_search_factor * thickness; }
  Real proximityListRadius(Real thickness) const {
    return (options_.proximity_search_factor + options_.proximity_list_margin) * thickness;
  }
  Real candidateListRadius(Real thickness) const {
    return (options_.proximity_search_factor + options_.proximity_list_margin + options_.candidate_list_margin) *
           thickness;
  }
  // Reference configuration of a Verlet list: the positions at its build.
  struct MotionReference {
    VecX x;
    bool valid = false;
  };
  void setReference(MotionReference& ref, const VecX& y) const;
  // True when every distance between features of y is larger than the same distance at the
  // reference minus `budget`: the motion since then, less the best-fitting rigid motion (or none),
  // moved no two particles apart by more than `budget` (docs/collision.md, "Broad phase and cost").
  bool movedLessThan(const MotionReference& ref, const VecX& y, Real budget) const;
  // The candidate boxes also cover the step continued by this many steps (a moving cloth keeps its
  // candidate list for more steps; docs/collision.md).
  static constexpr Real kCandidateLookahead = 1.0;
  // All pairs of triangles whose stored boxes overlap (into cand_), and the first crossing
  // detection of a pass from them.
  // `ahead` > 0 extends each swept box to x + ahead (x - x_old), the same step's motion continued.
  void collectCandidates(const VecX& x_old, const VecX& x, Real inflate, Real ahead = 0);
  // `pairs`: cand_, or prox_tri_ when that covers x (applyV3).
  void detectFromCandidates(const std::vector<std::pair<Index, Index>>& pairs, Index num_edges_considered,
                            const VecX& x, std::vector<Hit>& hits) const;
  long resolveProximity(const std::vector<ProxPair>& pairs, Real thickness, const VecX& x_old, const VecX& x_pred,
                        VecX& x, VecX& v, SelfCollisionStats& st);
  // Step size h of the last step when x = x_old + h v holds (implicit integrators), else -1.
  Real estimateStep(const VecX& x_old, const VecX& x_pred, const VecX& v) const;
  static std::uint64_t pairKey(const ProxPair& p) {
    return (static_cast<std::uint64_t>(p.type) << 62) | (static_cast<std::uint64_t>(p.a) << 31) |
           static_cast<std::uint64_t>(p.b);
  }

  ClothTriangles tris_;
  std::vector<char> pinned_;
  SelfCollisionOptions options_;
  geom::SpatialHash hash_;
  std::vector<geom::Aabb> boxes_;       // swept triangle boxes of the current apply()
  std::vector<geom::Aabb> edge_boxes_;  // swept edge boxes of the current apply()
  std::vector<std::array<Index, 2>> groups_;  // broad-phase cells: 1 or 2 triangles (-1: none)
  // Neighbouring cells of each cell (cells with a common vertex; CSR, ascending), and the triangle
  // pairs of neighbouring cells that share no vertex (each once, a < b).
  std::vector<Index> neighbour_group_start_, neighbour_group_list_;
  std::vector<std::pair<Index, Index>> near_pairs_;
  std::vector<geom::Aabb> group_boxes_;
  geom::SpatialHash group_hash_;
  std::vector<std::pair<Index, Index>> cand_;  // triangle pairs with overlapping stored boxes (a < b)
  // Triangles sharing a vertex, by topology: the edge-triangle pairs that can cross, and the
  // vertex-triangle and edge-edge pairs of the proximity stage (no shared vertex).
  std::vector<std::pair<Index, Index>> adj_cross_, adj_vt_, adj_ee_;
  std::vector<Index> owned_start_, owned_list_;  // edges owned by each triangle (CSR)
  std::vector<Index> orphan_edges_;     // edges that belong to no triangle
  std::vector<Index> edge_owner_;       // triangle owning each edge, -1 for orphans
  std::vector<Index> vertex_edge_start_, vertex_edge_list_;  // edges incident to each vertex (CSR)
  std::vector<Index> owned_vertex_start_, owned_vertex_list_;  // vertices owned by each triangle (CSR)
  std::vector<Real> inv_mass_;          // relative inverse masses, 0 for pinned particles
  // Contact-force feedback (ContactForceModel): the contact multipliers of the last step as
  // accelerations, per pair (by key) and summed per particle.
  bool force_feedback_ = false;
  Real last_h_ = -1;  // step size of the last step it could be estimated for
  // Proximity candidate list (Verlet list): vertex-triangle and edge-edge pairs within the list
  // radius Rp at the positions x_old of its build (prox_ref_).
  std::vector<std::pair<Index, Index>> prox_cache_vt_, prox_cache_ee_;
  // The candidate triangle pairs not proven farther apart than Rp at that build: every
  // vertex-disjoint pair that touches at a y with movedLessThan(prox_ref_, y, Rp) (crossing
  // detection then needs no more).
  std::vector<std::pair<Index, Index>> prox_tri_;
  // Validity of the proximity list: reference positions, radius and settings.
  MotionReference prox_ref_;
  Real list_radius_ = 0;
  bool list_edges_ = true;
  bool list_valid_ = false;
  // Validity of the candidate triangle-pair list cand_: the swept box of every particle at the build
  // (per DOF), the positions x at the build (cand_ref_), the inflation Rc.
  std::vector<Real> list_lo_, list_hi_;
  MotionReference cand_ref_;
  Real cand_radius_ = 0;
  bool cand_valid_ = false;
  // Scratch kept between calls (no allocation per step): per-thread pair lists, boxes at x_old.
  std::vector<ThreadList<std::pair<Index, Index>>> local_pairs_, local_vt_, local_ee_, local_tri_;
  mutable std::vector<ThreadList<ProxPair>> local_prox_;  // scratch of detectProximity
  std::vector<geom::Aabb> prox_tbox_, prox_ebox_;
  bool hash_current_ = false;           // hash_ holds this apply()'s boxes
  std::unordered_map<std::uint64_t, Vec3> contact_memory_;
  VecX contact_accel_;
  friend class ContactForceModel;
  // Scratch marks of detectIncremental (epoch-stamped, so no O(n) clearing per pass).
  mutable std::vector<std::uint32_t> tri_mark_, work_mark_, edge_mark_;
  mutable std::uint32_t epoch_ = 0;
  SelfCollisionStats last_, total_;
  long calls_ = 0;
};

/// A cloth model that adds the contact forces of a SelfCollisionPass's proximity stage (the
/// multipliers of its last step, as forces) to the forces of another model, so that the implicit
/// solve of the next step sees the support the contacts give (docs/collision.md, "Persistent
/// contact"): without them every step lets the supported cloth sag and the pass pushes it back,
/// which at rest never stops. Everything else is forwarded. Creating one switches the pass to
/// contact-force feedback; the pass must stay alive as long as this model is used. The contact
/// forces are part of internalState(), so save/resume continues exactly.
class ContactForceModel : public ClothModel {
 public:
  ContactForceModel(std::unique_ptr<ClothModel> base, SelfCollisionPass& pass);
  ContactForceModel(ClothModel& base, SelfCollisionPass& pass);

  ClothModel& base() { return base_; }
  const ClothModel& base() const { return base_; }
  const SelfCollisionPass& pass() const { return pass_; }
  std::string name() const override { return base_.name(); }
  Index numNodes() const override { return base_.numNodes(); }
  int dofsPerNode() const override { return base_.dofsPerNode(); }
  const VecX& massPerDof() const override { return base_.massPerDof(); }
  const BlockPattern& jacobianPattern() const override { return base_.jacobianPattern(); }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override { return base_.potentialEnergy(x); }
  Vec3 nodePosition(const VecX& x, Index node) const override { return base_.nodePosition(x, node); }
  Real maxEdgeStretch(const VecX& x) const override { return base_.maxEdgeStretch(x); }
  void acceptStep(const VecX& x, const VecX& v) override { base_.acceptStep(x, v); }
  std::vector<Real> internalState() const override;
  bool setInternalState(const std::vector<Real>& state) override;

 private:
  std::unique_ptr<ClothModel> owned_;
  ClothModel& base_;
  SelfCollisionPass& pass_;
};

/// Wraps `model` in a ContactForceModel when the pass runs v3 with the proximity stage and
/// options().contact_forces (what a scene does), else returns it unchanged. `pass` must outlive the
/// returned model.
std::unique_ptr<ClothModel> withContactForces(std::unique_ptr<ClothModel> model, SelfCollisionPass& pass);

// ---- obstacles -----------------------------------------------------------------------------------

/// Solid half-space {y : (y - point) . normal < 0} (a floor with normal +z).
struct PlaneObstacle {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  ///< outward, normalised on construction of the pass
  Vec3 velocity = Vec3::Zero();
};

/// Solid box: centre + R * [-half, half]^3 (R = identity: axis-aligned, e.g. a table; a rotated box:
/// a gripper jaw). `velocity` is the obstacle's rigid translation velocity (for moving jaws; the
/// caller updates the pose between runs).
struct BoxObstacle {
  Vec3 centre = Vec3::Zero();
  Vec3 half_extents = Vec3::Constant(0.5);
  Mat3 rotation = Mat3::Identity();  ///< columns: the box axes in world coordinates
  Vec3 velocity = Vec3::Zero();
  static BoxObstacle axisAligned(const Vec3& lo, const Vec3& hi);
  /// True when p lies inside the box enlarged by `margin` (closed).
  bool contains(const Vec3& p, Real margin = 0) const;
};

struct SphereObstacle {
  Vec3 centre = Vec3::Zero();
  Real radius = 0.05;
  Vec3 velocity = Vec3::Zero();
};

struct ObstacleOptions {
  /// Particles closer than this to a surface (or inside) are projected to this distance [m].
  Real contact_distance = 1e-3;
  /// Coulomb-like friction coefficient mu: on contact the tangential velocity (relative to the
  /// obstacle) is reduced by mu times the removed normal velocity, never reversed. 0 = frictionless.
  Real friction = 0.0;
};

/// Obstacle pass: after every step, each free particle that ends inside an obstacle or within the
/// contact distance of it is projected onto the contact surface (distance contact_distance), its
/// normal velocity into the obstacle is removed and friction is applied. A box entered during the
/// step is left through the face it was entered by (continuous choice from x_old), not the nearest.
/// Particles are independent, so the pass runs in parallel and deterministically.
class ObstaclePass : public PostStepPass {
 public:
  ObstaclePass(std::vector<char> pinned_mask, ObstacleOptions options = {});
  ObstaclePass(Index num_particles, const PinnedNodes& pins, ObstacleOptions options = {});

  void addPlane(const PlaneObstacle& p);
  void addBox(const BoxObstacle& b);
  void addSphere(const SphereObstacle& s);
  std::vector<PlaneObstacle>& planes() { return planes_; }
  std::vector<BoxObstacle>& boxes() { return boxes_; }
  std::vector<SphereObstacle>& spheres() { return spheres_; }
  const ObstacleOptions& options() const { return options_; }

  /// Returns the number of (particle, obstacle) contacts handled.
  long apply(const VecX& x_old, VecX& x, VecX& v) override;
  /// Number of free particles strictly inside any obstacle (a check for tests).
  long countInside(const VecX& x, Real margin = 0) const;

 private:
  std::vector<char> pinned_;
  ObstacleOptions options_;
  std::vector<PlaneObstacle> planes_;
  std::vector<BoxObstacle> boxes_;
  std::vector<SphereObstacle> spheres_;
};

/// Runs several passes in order (e.g. obstacles, then self-collision) and sums their event counts.
/// Non-owning. Recommended order: obstacles first, then self-collision, because the self-collision
/// rollback returns particles to x_old, which already satisfied the obstacles.
class PostStepPassChain : public PostStepPass {
 public:
  PostStepPassChain() = default;
  explicit PostStepPassChain(std::vector<PostStepPass*> passes) : passes_(std::move(passes)) {}
  void add(PostStepPass* p) { passes_.push_back(p); }
  long apply(const VecX& x_old, VecX& x, VecX& v) override;

 private:
  std::vector<PostStepPass*> passes_;
};

}  // namespace textile_handling
