// The self-collision pass of the drape simulator (thesis section 3.3 / summary section 7): the three
// versions of the thesis (v1 point path, v2 edge test, v3 edge test with candidate set and rollback)
// with a spatial-hash broad phase; v3 adds a proximity stage that keeps resting cloth-on-cloth
// contact at a thickness (docs/collision.md). Positions are 3 DOFs per particle, lengths in m,
// velocities in m/s. ROS-free.
//
// The member functions are implemented in src/sim/self_collision_*.cpp, one file per stage:
// construction and apply() (self_collision_pass.cpp), broad phase (self_collision_broad_phase.cpp),
// crossing detection (self_collision_detection.cpp), v1/v2 (self_collision_v1v2.cpp), v3
// (self_collision_v3.cpp), the response to one collision: side test, rollback, velocity response
// (self_collision_response.cpp), the proximity stage (self_collision_proximity.cpp).
#pragma once

#include <array>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/self_collision_options.h"

namespace textile_handling {

/// A list that one thread appends to, on cache lines of its own: the lists of several threads
/// sit side by side in a std::vector, and without the alignment the vector headers that every
/// append writes would share a cache line (false sharing).
template <class T>
struct alignas(64) ThreadList {
  std::vector<T> items;
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

}  // namespace textile_handling
