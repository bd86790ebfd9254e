// Self-collision and obstacle handling for the drape simulator (thesis section 3.3 / summary section 7),
// as post-step passes run by DrapeSimulation after every accepted step. ROS-free. See docs/collision.md
// for the algorithms, the decisions on the thesis's open points and the known failure cases.
//
//  - ClothTriangles: the thesis triangulation of the particle grid (each particle p0 owns the
//    triangles (p0, right, up) and (p0, left, down)), its edges and adjacency;
//  - SelfCollisionPass: the three versions of the thesis (v1 point path, v2 edge test, v3 edge test
//    with candidate set and rollback), with a spatial-hash broad phase;
//  - ObstaclePass: planes, boxes and spheres with a contact distance and Coulomb-like friction;
//  - PostStepPassChain: runs several passes in order and sums their event counts;
//  - countIntersectingTrianglePairs(): an independent exact checker (Devillers-Guigue).
//
// Positions are 3 DOFs per particle (ParticleClothModel). Lengths in m, velocities in m/s.
#pragma once

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/particle_cloth_model.h"

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
  /// Broad-phase cell size as a multiple of the grid spacing d (1.5 was fastest on the 1 cm towel).
  Real cell_size_factor = 1.5;

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
  void setOptions(const SelfCollisionOptions& o) { options_ = o; }
  const ClothTriangles& triangles() const { return tris_; }
  const SelfCollisionStats& lastStats() const { return last_; }
  const SelfCollisionStats& totalStats() const { return total_; }
  long calls() const { return calls_; }
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

  ClothTriangles tris_;
  std::vector<char> pinned_;
  SelfCollisionOptions options_;
  geom::SpatialHash hash_;
  std::vector<geom::Aabb> boxes_;       // swept triangle boxes of the current apply()
  std::vector<geom::Aabb> edge_boxes_;  // swept edge boxes of the current apply()
  std::vector<Index> owned_start_, owned_list_;  // edges owned by each triangle (CSR)
  std::vector<Index> orphan_edges_;     // edges that belong to no triangle
  std::vector<Index> edge_owner_;       // triangle owning each edge, -1 for orphans
  std::vector<Index> vertex_edge_start_, vertex_edge_list_;  // edges incident to each vertex (CSR)
  // Scratch marks of detectIncremental (epoch-stamped, so no O(n) clearing per pass).
  mutable std::vector<std::uint32_t> tri_mark_, work_mark_, edge_mark_;
  mutable std::uint32_t epoch_ = 0;
  SelfCollisionStats last_, total_;
  long calls_ = 0;
};

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
