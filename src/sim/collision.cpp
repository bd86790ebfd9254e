// Triangulation, the self-collision pass (versions 1-3 of the thesis, with v3's proximity stage) and
// the contact-force model. See docs/collision.md.
#include "textile_handling/sim/collision.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <unordered_map>
#include <utility>
#include <vector>

#include <Eigen/SVD>

#include "textile_handling/sim/timing.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {

namespace {

using Clock = std::chrono::steady_clock;
// Below this many work items a loop runs on one thread: the parallel region would cost more than it
// saves (and far more on an oversubscribed machine).
constexpr Index kParallelMin = 2048;

inline bool overlapInflated(const geom::Aabb& a, const geom::Aabb& b, Real r) {
  return a.lo.x() - r <= b.hi.x() && b.lo.x() <= a.hi.x() + r && a.lo.y() - r <= b.hi.y() && b.lo.y() <= a.hi.y() + r &&
         a.lo.z() - r <= b.hi.z() && b.lo.z() <= a.hi.z() + r;
}

// Cheap separating-axis rejections (the axis between the centres): true when the features are
// farther apart than sqrt(r2). Conservative: the distance is at least the gap of the projections
// onto any axis. For the crossing tests (exact predicates) a gap of 1 um (far above the rounding
// of these few products at cloth coordinates, whatever the axis length) is required.
constexpr Real kApartMargin2 = 1e-12;
inline bool segmentsApart(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, Real r2) {
  const Vec3 w = 0.5 * ((q1 + q2) - (p1 + p2));
  const Real ww = w.squaredNorm();
  const Real s = ww - 0.5 * (std::abs((p2 - p1).dot(w)) + std::abs((q2 - q1).dot(w)));
  return s > 0 && s * s > r2 * ww;
}
inline bool trianglesApart(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                           const Vec3& b2, Real r2) {
  const Vec3 ga = (a0 + a1 + a2) / 3.0, gb = (b0 + b1 + b2) / 3.0;
  const Vec3 w = gb - ga;
  const Real ww = w.squaredNorm();
  const Real s = ww - std::max({(a0 - ga).dot(w), (a1 - ga).dot(w), (a2 - ga).dot(w)}) -
                 std::max({(gb - b0).dot(w), (gb - b1).dot(w), (gb - b2).dot(w)});
  return s > 0 && s * s > r2 * ww;
}
inline bool segmentTriangleApart(const Vec3& p1, const Vec3& p2, const Vec3& a, const Vec3& b, const Vec3& c,
                                 Real r2) {
  const Vec3 g = (a + b + c) / 3.0;
  const Vec3 w = g - 0.5 * (p1 + p2);
  const Real ww = w.squaredNorm();
  const Real s = ww - 0.5 * std::abs((p2 - p1).dot(w)) - std::max({(g - a).dot(w), (g - b).dot(w), (g - c).dot(w)});
  return s > 0 && s * s > r2 * ww;
}
inline bool pointTriangleApart(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c, Real r2) {
  const Vec3 g = (a + b + c) / 3.0;
  const Vec3 w = x - g;
  const Real ww = w.squaredNorm();
  const Real s = ww - std::max({(a - g).dot(w), (b - g).dot(w), (c - g).dot(w)});
  return s > 0 && s * s > r2 * ww;
}

std::uint64_t edgeKey(Index a, Index b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

Vec3 triNormal(const VecX& x, const std::array<Index, 3>& c) {
  const Vec3 a = node3(x, c[0]);
  return (node3(x, c[1]) - a).cross(node3(x, c[2]) - a);
}

}  // namespace

// ---- triangulation -------------------------------------------------------------------------------

ClothTriangles ClothTriangles::fromTopology(const ParticleTopology& topo) {
  ClothTriangles t;
  const Index n = topo.size();
  t.num_vertices = n;
  t.spacing = topo.spacing;
  t.owned.assign(static_cast<size_t>(n), {-1, -1});
  for (Index p = 0; p < n; ++p) {
    const auto& nb = topo.neighbour[static_cast<size_t>(p)];
    if (nb[0] >= 0 && nb[1] >= 0) {  // (p0, right, up)
      t.owned[static_cast<size_t>(p)][0] = static_cast<Index>(t.triangles.size());
      t.triangles.push_back({p, nb[0], nb[1]});
      t.owner.push_back(p);
    }
    if (nb[2] >= 0 && nb[3] >= 0) {  // (p0, left, down)
      t.owned[static_cast<size_t>(p)][1] = static_cast<Index>(t.triangles.size());
      t.triangles.push_back({p, nb[2], nb[3]});
      t.owner.push_back(p);
    }
  }
  // Edges: grid edges (to the right and up neighbours, so each once), then the diagonals.
  std::unordered_map<std::uint64_t, Index> id;
  id.reserve(static_cast<size_t>(4 * n));
  for (Index p = 0; p < n; ++p) {
    for (int d = 0; d < 2; ++d) {
      const Index q = topo.neighbour[static_cast<size_t>(p)][static_cast<size_t>(d)];
      if (q < 0) continue;
      if (id.emplace(edgeKey(p, q), static_cast<Index>(t.edges.size())).second)
        t.edges.push_back({std::min(p, q), std::max(p, q)});
    }
  }
  t.num_grid_edges = static_cast<Index>(t.edges.size());
  t.triangle_edges.resize(t.triangles.size());
  for (size_t k = 0; k < t.triangles.size(); ++k) {
    const auto& c = t.triangles[k];
    const Index pairs[3][2] = {{c[0], c[1]}, {c[0], c[2]}, {c[1], c[2]}};
    for (int e = 0; e < 3; ++e) {
      const auto ins = id.emplace(edgeKey(pairs[e][0], pairs[e][1]), static_cast<Index>(t.edges.size()));
      if (ins.second) t.edges.push_back({std::min(pairs[e][0], pairs[e][1]), std::max(pairs[e][0], pairs[e][1])});
      t.triangle_edges[k][static_cast<size_t>(e)] = ins.first->second;
    }
  }
  // Vertex -> triangles.
  t.vertex_triangle_start.assign(static_cast<size_t>(n) + 1, 0);
  for (const auto& c : t.triangles)
    for (Index v : c) ++t.vertex_triangle_start[static_cast<size_t>(v) + 1];
  for (Index v = 0; v < n; ++v) t.vertex_triangle_start[static_cast<size_t>(v) + 1] += t.vertex_triangle_start[static_cast<size_t>(v)];
  t.vertex_triangle_list.assign(static_cast<size_t>(t.vertex_triangle_start.back()), -1);
  {
    std::vector<Index> fill(t.vertex_triangle_start.begin(), t.vertex_triangle_start.end() - 1);
    for (size_t k = 0; k < t.triangles.size(); ++k)
      for (Index v : t.triangles[k]) t.vertex_triangle_list[static_cast<size_t>(fill[static_cast<size_t>(v)]++)] = static_cast<Index>(k);
  }
  // Candidate sets: triangles sharing a vertex with one of p0's triangles.
  t.candidate_start.assign(static_cast<size_t>(n) + 1, 0);
  std::vector<Index> scratch;
  for (Index p = 0; p < n; ++p) {
    scratch.clear();
    for (Index own : t.owned[static_cast<size_t>(p)]) {
      if (own < 0) continue;
      for (Index v : t.triangles[static_cast<size_t>(own)])
        for (Index k = t.vertex_triangle_start[static_cast<size_t>(v)]; k < t.vertex_triangle_start[static_cast<size_t>(v) + 1]; ++k)
          scratch.push_back(t.vertex_triangle_list[static_cast<size_t>(k)]);
    }
    std::sort(scratch.begin(), scratch.end());
    scratch.erase(std::unique(scratch.begin(), scratch.end()), scratch.end());
    t.candidate_list.insert(t.candidate_list.end(), scratch.begin(), scratch.end());
    t.candidate_start[static_cast<size_t>(p) + 1] = static_cast<Index>(t.candidate_list.size());
  }
  if (topo.area.size() == static_cast<size_t>(n)) t.vertex_mass = topo.area;
  return t;
}

std::vector<char> pinnedMask(Index num_particles, const PinnedNodes& pins) {
  std::vector<char> m(static_cast<size_t>(std::max<Index>(num_particles, 0)), 0);
  for (Index p : pins.nodes)
    if (p >= 0 && p < num_particles) m[static_cast<size_t>(p)] = 1;
  return m;
}

// ---- options ------------------------------------------------------------------------------------

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
  throw std::invalid_argument("unknown self-collision version '" + s + "' (expected v1, v2 or v3)");
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

// ---- self-collision pass --------------------------------------------------------------------------

SelfCollisionPass::SelfCollisionPass(ClothTriangles tris, std::vector<char> pinned_mask, SelfCollisionOptions options)
    : tris_(std::move(tris)), pinned_(std::move(pinned_mask)), options_(options) {
  if (pinned_.empty()) pinned_.assign(static_cast<size_t>(tris_.num_vertices), 0);
  if (static_cast<Index>(pinned_.size()) != tris_.num_vertices)
    throw std::invalid_argument("SelfCollisionPass: pinned mask size differs from the particle count");
  if (!(options_.d_min >= 0) || options_.max_passes < 1 || !(options_.cell_size_factor > 0) ||
      !(options_.barycentric_tolerance >= 0) || !(options_.restitution >= 0 && options_.restitution <= 1) ||
      !(options_.tangential_damping >= 0 && options_.tangential_damping <= 1) ||
      !(options_.thickness_factor > 0 && options_.thickness_factor < 0.35) ||
      !(options_.proximity_separation >= 0 && options_.proximity_separation <= 1) ||
      !(options_.proximity_friction >= 0 && std::isfinite(options_.proximity_friction)) ||
      !(options_.proximity_search_factor >= 1 && options_.proximity_search_factor <= 3) ||
      !(options_.proximity_list_margin >= 0 && options_.proximity_list_margin <= 4) ||
      !(options_.candidate_list_margin >= 0 && options_.candidate_list_margin <= 4) ||
      options_.proximity_iterations < 1)
    throw std::invalid_argument("SelfCollisionPass: invalid options");
  if (!tris_.vertex_mass.empty() && static_cast<Index>(tris_.vertex_mass.size()) != tris_.num_vertices)
    throw std::invalid_argument("SelfCollisionPass: vertex_mass size differs from the particle count");
  // Each edge is owned by the first triangle that contains it; edges in no triangle are orphans.
  std::vector<char> owned(tris_.edges.size(), 0);
  owned_start_.assign(tris_.triangles.size() + 1, 0);
  for (size_t t = 0; t < tris_.triangles.size(); ++t) {
    for (Index e : tris_.triangle_edges[t]) {
      if (owned[static_cast<size_t>(e)]) continue;
      owned[static_cast<size_t>(e)] = 1;
      owned_list_.push_back(e);
    }
    owned_start_[t + 1] = static_cast<Index>(owned_list_.size());
  }
  for (Index e = 0; e < tris_.numEdges(); ++e)
    if (!owned[static_cast<size_t>(e)]) orphan_edges_.push_back(e);
  edge_owner_.assign(tris_.edges.size(), -1);
  for (Index t = 0; t < tris_.numTriangles(); ++t)
    for (int j = 0; j < numOwnedEdges(t); ++j) edge_owner_[static_cast<size_t>(ownedEdges(t)[j])] = t;
  // Vertex -> incident edges (CSR).
  const size_t nv = static_cast<size_t>(tris_.num_vertices);
  vertex_edge_start_.assign(nv + 1, 0);
  for (const auto& ed : tris_.edges)
    for (Index p : ed) ++vertex_edge_start_[static_cast<size_t>(p) + 1];
  for (size_t p = 0; p < nv; ++p) vertex_edge_start_[p + 1] += vertex_edge_start_[p];
  vertex_edge_list_.assign(static_cast<size_t>(vertex_edge_start_.back()), -1);
  std::vector<Index> fill(vertex_edge_start_.begin(), vertex_edge_start_.end() - 1);
  for (Index e = 0; e < tris_.numEdges(); ++e)
    for (Index p : tris_.edges[static_cast<size_t>(e)]) vertex_edge_list_[static_cast<size_t>(fill[static_cast<size_t>(p)]++)] = e;
  // Each vertex is owned by the first triangle that contains it (proximity detection).
  {
    std::vector<char> vowned(nv, 0);
    owned_vertex_start_.assign(tris_.triangles.size() + 1, 0);
    for (size_t t = 0; t < tris_.triangles.size(); ++t) {
      for (Index p : tris_.triangles[t]) {
        if (vowned[static_cast<size_t>(p)]) continue;
        vowned[static_cast<size_t>(p)] = 1;
        owned_vertex_list_.push_back(p);
      }
      owned_vertex_start_[t + 1] = static_cast<Index>(owned_vertex_list_.size());
    }
  }
  // Relative inverse masses (mean mass 1), 0 for pinned particles.
  {
    Real mean = 0;
    for (Real m : tris_.vertex_mass) mean += m;
    mean = tris_.vertex_mass.empty() ? 1 : mean / static_cast<Real>(tris_.vertex_mass.size());
    inv_mass_.assign(nv, 1.0);
    for (size_t p = 0; p < nv; ++p) {
      if (!tris_.vertex_mass.empty()) {
        const Real m = tris_.vertex_mass[p] / mean;
        inv_mass_[p] = m > 0 && std::isfinite(m) ? 1.0 / m : 1.0;
      }
      if (pinned_[p]) inv_mass_[p] = 0;
    }
  }
  // Broad-phase cells: the triangles that share a cell diagonal (edge (c1, c2) of both kinds).
  {
    std::unordered_map<std::uint64_t, Index> by_diagonal;
    for (Index t = 0; t < tris_.numTriangles(); ++t) {
      const auto& c = tris_.triangles[static_cast<size_t>(t)];
      const auto ins = by_diagonal.emplace(edgeKey(c[1], c[2]), static_cast<Index>(groups_.size()));
      if (ins.second) groups_.push_back({t, -1});
      else groups_[static_cast<size_t>(ins.first->second)][1] = t;
    }
  }
  // Neighbouring cells (cells whose triangles share a vertex) always have overlapping boxes; the
  // broad phase skips them, and their triangle pairs that share no vertex are listed once
  // (near_pairs_, box-tested at each build).
  {
    std::vector<Index> group_of(tris_.triangles.size(), -1);
    for (size_t g = 0; g < groups_.size(); ++g)
      for (Index t : groups_[g])
        if (t >= 0) group_of[static_cast<size_t>(t)] = static_cast<Index>(g);
    neighbour_group_start_.assign(groups_.size() + 1, 0);
    neighbour_group_list_.clear();
    std::vector<Index> nb;
    for (size_t g = 0; g < groups_.size(); ++g) {
      nb.clear();
      for (Index t : groups_[g]) {
        if (t < 0) continue;
        for (Index v : tris_.triangles[static_cast<size_t>(t)])
          for (Index k = tris_.vertex_triangle_start[static_cast<size_t>(v)]; k < tris_.vertex_triangle_start[static_cast<size_t>(v) + 1]; ++k) {
            const Index g2 = group_of[static_cast<size_t>(tris_.vertex_triangle_list[static_cast<size_t>(k)])];
            if (g2 != static_cast<Index>(g)) nb.push_back(g2);
          }
      }
      std::sort(nb.begin(), nb.end());
      nb.erase(std::unique(nb.begin(), nb.end()), nb.end());
      neighbour_group_list_.insert(neighbour_group_list_.end(), nb.begin(), nb.end());
      neighbour_group_start_[g + 1] = static_cast<Index>(neighbour_group_list_.size());
      for (Index g2 : nb) {
        if (g2 < static_cast<Index>(g)) continue;
        for (Index a : groups_[g])
          for (Index b : groups_[static_cast<size_t>(g2)])
            if (a >= 0 && b >= 0 && !tris_.trianglesShareVertex(a, b)) near_pairs_.emplace_back(std::min(a, b), std::max(a, b));
      }
    }
  }
  // Triangles that share a vertex are always candidates of each other (their boxes touch): the
  // feature pairs between them that can meet are fixed by the topology and listed once.
  for (Index a = 0; a < tris_.numTriangles(); ++a) {
    std::vector<Index> partners;
    for (Index v : tris_.triangles[static_cast<size_t>(a)])
      for (Index k = tris_.vertex_triangle_start[static_cast<size_t>(v)]; k < tris_.vertex_triangle_start[static_cast<size_t>(v) + 1]; ++k) {
        const Index b = tris_.vertex_triangle_list[static_cast<size_t>(k)];
        if (b > a) partners.push_back(b);
      }
    std::sort(partners.begin(), partners.end());
    partners.erase(std::unique(partners.begin(), partners.end()), partners.end());
    for (Index b : partners) {
      for (const auto& [t, u] : {std::make_pair(a, b), std::make_pair(b, a)}) {
        for (int j = 0; j < numOwnedEdges(t); ++j) {
          const Index e = ownedEdges(t)[j];
          const auto& ed = tris_.edges[static_cast<size_t>(e)];
          if (!tris_.triangleHasVertex(u, ed[0]) && !tris_.triangleHasVertex(u, ed[1])) adj_cross_.emplace_back(e, u);
        }
        for (Index j = owned_vertex_start_[static_cast<size_t>(t)]; j < owned_vertex_start_[static_cast<size_t>(t) + 1]; ++j) {
          const Index p = owned_vertex_list_[static_cast<size_t>(j)];
          if (!tris_.triangleHasVertex(u, p)) adj_vt_.emplace_back(p, u);
        }
      }
      for (int i = 0; i < numOwnedEdges(a); ++i)
        for (int j = 0; j < numOwnedEdges(b); ++j) {
          const Index e1 = ownedEdges(a)[i], e2 = ownedEdges(b)[j];
          const auto& p = tris_.edges[static_cast<size_t>(e1)];
          const auto& q = tris_.edges[static_cast<size_t>(e2)];
          if (p[0] == q[0] || p[0] == q[1] || p[1] == q[0] || p[1] == q[1]) continue;
          if (e1 >= tris_.num_grid_edges && e2 >= tris_.num_grid_edges) continue;  // two cell diagonals
          adj_ee_.emplace_back(std::min(e1, e2), std::max(e1, e2));
        }
    }
  }
  tri_mark_.assign(tris_.triangles.size(), 0);
  work_mark_.assign(tris_.triangles.size(), 0);
  edge_mark_.assign(tris_.edges.size(), 0);
}

SelfCollisionPass::SelfCollisionPass(const ParticleTopology& topo, const PinnedNodes& pins, SelfCollisionOptions options)
    : SelfCollisionPass(ClothTriangles::fromTopology(topo), pinnedMask(topo.size(), pins), options) {}

long SelfCollisionPass::apply(const VecX& x_old, VecX& x, VecX& v) {
  const Index n3 = 3 * tris_.num_vertices;
  if (x_old.size() != n3 || x.size() != n3 || v.size() != n3)
    throw std::invalid_argument("SelfCollisionPass: state size does not match the triangulation");
  SelfCollisionStats st;
  long events = 0;
  if (!tris_.triangles.empty()) {
    switch (options_.version) {
      case SelfCollisionVersion::kPointPath: events = applyV1(x_old, x, v, st); break;
      case SelfCollisionVersion::kEdge: events = applyV2(x_old, x, v, st); break;
      case SelfCollisionVersion::kRollback: events = applyV3(x_old, x, v, st); break;
    }
  }
  st.events = events;
  last_ = st;
  total_.add(st);
  ++calls_;
  return events;
}

geom::Aabb SelfCollisionPass::triangleBox(Index t, const VecX& x_old, const VecX& x, Real inflate, Real ahead) const {
  geom::Aabb b;
  for (Index c : tris_.triangles[static_cast<size_t>(t)]) {
    b.extend(node3(x_old, c));
    b.extend(node3(x, c));
    if (ahead > 0) b.extend(Vec3(node3(x, c) + ahead * (node3(x, c) - node3(x_old, c))));
  }
  if (inflate > 0) b.inflate(inflate);
  return b;
}

void SelfCollisionPass::computeTriangleBoxes(const VecX& x_old, const VecX& x, Real inflate, Real ahead) {
  const Index T = tris_.numTriangles();
  boxes_.resize(static_cast<size_t>(T));
#pragma omp parallel for if (T >= kParallelMin) schedule(static)
  for (Index t = 0; t < T; ++t) boxes_[static_cast<size_t>(t)] = triangleBox(t, x_old, x, inflate, ahead);
}

void SelfCollisionPass::computeSweptBoxes(const VecX& x_old, const VecX& x) {
  const Index T = tris_.numTriangles(), E = tris_.numEdges();
  boxes_.resize(static_cast<size_t>(T));
  edge_boxes_.resize(static_cast<size_t>(E));
#pragma omp parallel if (T + E >= kParallelMin)
  {
#pragma omp for schedule(static) nowait
    for (Index t = 0; t < T; ++t) boxes_[static_cast<size_t>(t)] = triangleBox(t, x_old, x, 0.0, 0.0);
#pragma omp for schedule(static) nowait
    for (Index e = 0; e < E; ++e) edge_boxes_[static_cast<size_t>(e)] = edgeBox(e, x_old, x);
  }
}

void SelfCollisionPass::buildHash(const VecX& x_old, const VecX& x, Real inflate) {
  computeTriangleBoxes(x_old, x, inflate, 0.0);
  hash_.build(boxes_, options_.cell_size_factor * tris_.spacing);
}

geom::Aabb SelfCollisionPass::edgeBox(Index e, const VecX& x_old, const VecX& x) const {
  geom::Aabb b;
  for (Index p : tris_.edges[static_cast<size_t>(e)]) {
    b.extend(node3(x_old, p));
    b.extend(node3(x, p));
  }
  return b;
}

bool SelfCollisionPass::edgeCrosses(Index e, Index t, const VecX& x) const {
  const auto& ed = tris_.edges[static_cast<size_t>(e)];
  const auto& c = tris_.triangles[static_cast<size_t>(t)];
  return geom::segmentTriangleIntersect(node3(x, ed[0]), node3(x, ed[1]), node3(x, c[0]), node3(x, c[1]),
                                        node3(x, c[2]));
}

namespace {
// One empty list per thread (the lists keep their capacity between calls).
template <class T>
void resetThreadLists(std::vector<ThreadList<T>>& local, int threads) {
  local.resize(static_cast<size_t>(threads));
  for (auto& l : local) l.items.clear();
}

// The per-thread lists one after the other, in thread order.
template <class T>
void concatenate(const std::vector<ThreadList<T>>& local, std::vector<T>& out) {
  size_t total = 0;
  for (const auto& l : local) total += l.items.size();
  out.clear();
  out.reserve(total);
  for (const auto& l : local) out.insert(out.end(), l.items.begin(), l.items.end());
}

// Merges per-thread hit lists into one sorted, duplicate-free list (independent of thread count).
template <class HitT>
void mergeSorted(std::vector<ThreadList<HitT>>& local, std::vector<HitT>& out) {
  concatenate(local, out);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

int threadCount() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}
int threadId() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}
}  // namespace

void SelfCollisionPass::computeEdgeBoxes(const VecX& x_old, const VecX& x) {
  const Index E = tris_.numEdges();
  edge_boxes_.resize(static_cast<size_t>(E));
#pragma omp parallel for if (E >= kParallelMin) schedule(static)
  for (Index e = 0; e < E; ++e) edge_boxes_[static_cast<size_t>(e)] = edgeBox(e, x_old, x);
}

void SelfCollisionPass::detectEdges(Index num_edges_considered, const VecX& x, std::vector<Hit>& hits) const {
  // One hash query per triangle (its swept box contains the boxes of the edges it owns) plus one
  // per orphan edge; each candidate (edge, triangle) pair then gets a box test and the exact test.
  const Index T = tris_.numTriangles();
  const Index m = T + static_cast<Index>(orphan_edges_.size());
  std::vector<ThreadList<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
    geom::SpatialHash::Query query(hash_);
    auto test = [&](Index e, Index t2) {
      const auto& ed = tris_.edges[static_cast<size_t>(e)];
      if (tris_.triangleHasVertex(t2, ed[0]) || tris_.triangleHasVertex(t2, ed[1])) return;
      if (!edge_boxes_[static_cast<size_t>(e)].overlaps(boxes_[static_cast<size_t>(t2)])) return;
      if (edgeCrosses(e, t2, x)) out.push_back(Hit{e, t2});
    };
#pragma omp for schedule(dynamic, 128)
    for (Index k = 0; k < m; ++k) {
      if (k < T) {
        const Index* own = ownedEdges(k);
        const int no = numOwnedEdges(k);
        bool any = false;
        for (int j = 0; j < no; ++j) any = any || own[j] < num_edges_considered;
        if (!any) continue;
        query.forEachOverlap(boxes_[static_cast<size_t>(k)], [&](int t2) {
          for (int j = 0; j < no; ++j)
            if (own[j] < num_edges_considered) test(own[j], t2);
        });
      } else {
        const Index e = orphan_edges_[static_cast<size_t>(k - T)];
        if (e >= num_edges_considered) continue;
        query.forEachOverlap(edge_boxes_[static_cast<size_t>(e)], [&](int t2) { test(e, t2); });
      }
    }
  }
  mergeSorted(local, hits);
}

void SelfCollisionPass::collectCandidates(const VecX& x_old, const VecX& x, Real inflate, Real ahead) {
  // Every pair of triangles whose swept boxes are within `inflate` of each other (per axis). The
  // broad phase works on grid cells (the one or two triangles that share a cell diagonal, half as
  // many boxes as triangles): the cell boxes, inflated by `inflate`, go into a hash that is queried
  // once per cell with its own box, keeping the partners with a larger id; the triangle pairs of
  // two such cells are then filtered with the triangle boxes. Neighbouring cells always overlap:
  // they are skipped, and their vertex-disjoint triangle pairs come from near_pairs_.
  const Index G = static_cast<Index>(groups_.size()), T = tris_.numTriangles();
  boxes_.resize(static_cast<size_t>(T));
  group_boxes_.resize(static_cast<size_t>(G));
#pragma omp parallel if (G >= kParallelMin)
  {
#pragma omp for schedule(static)
    for (Index t = 0; t < T; ++t) boxes_[static_cast<size_t>(t)] = triangleBox(t, x_old, x, 0.0, ahead);
#pragma omp for schedule(static)
    for (Index g = 0; g < G; ++g) {
      geom::Aabb b = boxes_[static_cast<size_t>(groups_[static_cast<size_t>(g)][0])];
      const Index t2 = groups_[static_cast<size_t>(g)][1];
      if (t2 >= 0) {
        b.extend(boxes_[static_cast<size_t>(t2)].lo);
        b.extend(boxes_[static_cast<size_t>(t2)].hi);
      }
      if (inflate > 0) b.inflate(inflate);
      group_boxes_[static_cast<size_t>(g)] = b;
    }
  }
  group_hash_.build(group_boxes_, options_.cell_size_factor * tris_.spacing);
  auto& local = local_pairs_;
  resetThreadLists(local, threadCount());
  const Index nn = static_cast<Index>(near_pairs_.size());
#pragma omp parallel if (G >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
    geom::SpatialHash::Query query(group_hash_);
#pragma omp for schedule(dynamic, 256) nowait
    for (Index g = 0; g < G; ++g) {
      const auto& mg = groups_[static_cast<size_t>(g)];
      const Index* nb = neighbour_group_list_.data() + neighbour_group_start_[static_cast<size_t>(g)];
      const Index* nb_end = neighbour_group_list_.data() + neighbour_group_start_[static_cast<size_t>(g) + 1];
      geom::Aabb q = group_boxes_[static_cast<size_t>(g)];
      q.inflate(-inflate);
      query.forEachOverlapAbove(q, static_cast<int>(g), [&](int g2) {
        if (std::binary_search(nb, nb_end, static_cast<Index>(g2))) return;  // a neighbouring cell: near_pairs_
        // Cells that are not neighbours share no vertex, nor do their triangles.
        const auto& m2 = groups_[static_cast<size_t>(g2)];
        for (Index a : mg)
          if (a >= 0)
            for (Index b : m2)
              if (b >= 0 && overlapInflated(boxes_[static_cast<size_t>(a)], boxes_[static_cast<size_t>(b)], inflate))
                out.emplace_back(std::min(a, b), std::max(a, b));
      });
    }
#pragma omp for schedule(static)
    for (Index k = 0; k < nn; ++k) {
      const auto& pr = near_pairs_[static_cast<size_t>(k)];
      if (overlapInflated(boxes_[static_cast<size_t>(pr.first)], boxes_[static_cast<size_t>(pr.second)], inflate))
        out.push_back(pr);
    }
  }
  concatenate(local, cand_);
}

void SelfCollisionPass::detectFromCandidates(const std::vector<std::pair<Index, Index>>& pairs,
                                             Index num_edges_considered, const VecX& x, std::vector<Hit>& hits) const {
  // The first detection of a pass: the candidate triangle pairs (boxes containing the current
  // swept boxes) with the edges each triangle owns against the other triangle, plus the edges that
  // belong to no triangle against the hash.
  const Index nc = static_cast<Index>(pairs.size()), na = static_cast<Index>(adj_cross_.size());
  const Index m = nc + na + static_cast<Index>(orphan_edges_.size());
  std::vector<ThreadList<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (m >= 4 * kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
    geom::SpatialHash::Query query(hash_);
    auto test = [&](Index e, Index t2) {
      if (e >= num_edges_considered) return;
      if (!edge_boxes_[static_cast<size_t>(e)].overlaps(boxes_[static_cast<size_t>(t2)])) return;
      const auto& ed = tris_.edges[static_cast<size_t>(e)];
      if (tris_.triangleHasVertex(t2, ed[0]) || tris_.triangleHasVertex(t2, ed[1])) return;
      if (edgeCrosses(e, t2, x)) out.push_back(Hit{e, t2});
    };
#pragma omp for schedule(dynamic, 1024)  // candidate pairs cost more than the listed ones
    for (Index k = 0; k < m; ++k) {
      if (k >= nc && k < nc + na) {  // triangles sharing a vertex: the listed edge-triangle pairs
        const auto& c = adj_cross_[static_cast<size_t>(k - nc)];
        if (c.first < num_edges_considered &&
            edge_boxes_[static_cast<size_t>(c.first)].overlaps(boxes_[static_cast<size_t>(c.second)])) {
          const auto& ed = tris_.edges[static_cast<size_t>(c.first)];
          const auto& ct = tris_.triangles[static_cast<size_t>(c.second)];
          if (!segmentTriangleApart(node3(x, ed[0]), node3(x, ed[1]), node3(x, ct[0]), node3(x, ct[1]), node3(x, ct[2]),
                                    kApartMargin2) &&
              edgeCrosses(c.first, c.second, x))
            out.push_back(Hit{c.first, c.second});
        }
      } else if (k < nc) {
        const Index a = pairs[static_cast<size_t>(k)].first, b = pairs[static_cast<size_t>(k)].second;
        if (!boxes_[static_cast<size_t>(a)].overlaps(boxes_[static_cast<size_t>(b)])) continue;
        {  // triangles clearly apart at x cannot cross (the margin covers rounding)
          const auto& ca = tris_.triangles[static_cast<size_t>(a)];
          const auto& cb = tris_.triangles[static_cast<size_t>(b)];
          if (trianglesApart(node3(x, ca[0]), node3(x, ca[1]), node3(x, ca[2]), node3(x, cb[0]), node3(x, cb[1]),
                             node3(x, cb[2]), kApartMargin2))
            continue;
        }
        for (int j = 0; j < numOwnedEdges(a); ++j) test(ownedEdges(a)[j], b);
        for (int j = 0; j < numOwnedEdges(b); ++j) test(ownedEdges(b)[j], a);
      } else {
        const Index e = orphan_edges_[static_cast<size_t>(k - nc - na)];
        if (e >= num_edges_considered) continue;
        query.forEachOverlap(edge_boxes_[static_cast<size_t>(e)], [&](int t2) { test(e, t2); });
      }
    }
  }
  mergeSorted(local, hits);
}

void SelfCollisionPass::detectIncremental(const std::vector<Index>& moved, Index num_edges_considered, const VecX& x,
                                          std::vector<Hit>& hits) const {
  // A pair (edge, triangle) can only have started crossing if one of its particles moved. The dirty
  // sets are collected from the moved particles' neighbourhoods (cost independent of the mesh size).
  if (++epoch_ == 0) {
    std::fill(tri_mark_.begin(), tri_mark_.end(), 0);
    std::fill(work_mark_.begin(), work_mark_.end(), 0);
    std::fill(edge_mark_.begin(), edge_mark_.end(), 0);
    epoch_ = 1;
  }
  const std::uint32_t ep = epoch_;
  std::vector<Index> work;
  for (Index p : moved) {
    for (Index k = tris_.vertex_triangle_start[static_cast<size_t>(p)]; k < tris_.vertex_triangle_start[static_cast<size_t>(p) + 1]; ++k) {
      const Index t = tris_.vertex_triangle_list[static_cast<size_t>(k)];
      tri_mark_[static_cast<size_t>(t)] = ep;
      if (work_mark_[static_cast<size_t>(t)] != ep) {
        work_mark_[static_cast<size_t>(t)] = ep;
        work.push_back(t);
      }
    }
    for (Index k = vertex_edge_start_[static_cast<size_t>(p)]; k < vertex_edge_start_[static_cast<size_t>(p) + 1]; ++k) {
      const Index e = vertex_edge_list_[static_cast<size_t>(k)];
      if (e >= num_edges_considered) continue;
      edge_mark_[static_cast<size_t>(e)] = ep;
      const Index owner = edge_owner_[static_cast<size_t>(e)];
      if (owner >= 0 && work_mark_[static_cast<size_t>(owner)] != ep) {
        work_mark_[static_cast<size_t>(owner)] = ep;
        work.push_back(owner);
      }
    }
  }
  std::sort(work.begin(), work.end());
  auto triDirty = [&](Index t) { return tri_mark_[static_cast<size_t>(t)] == ep; };
  auto edgeDirty = [&](Index e) { return e < num_edges_considered && edge_mark_[static_cast<size_t>(e)] == ep; };
  const Index m = static_cast<Index>(work.size()) + static_cast<Index>(orphan_edges_.size());
  std::vector<ThreadList<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
    geom::SpatialHash::Query query(hash_);
    auto test = [&](Index e, Index t2) {
      if (e >= num_edges_considered) return;
      const auto& ed = tris_.edges[static_cast<size_t>(e)];
      if (tris_.triangleHasVertex(t2, ed[0]) || tris_.triangleHasVertex(t2, ed[1])) return;
      if (!edge_boxes_[static_cast<size_t>(e)].overlaps(boxes_[static_cast<size_t>(t2)])) return;
      if (edgeCrosses(e, t2, x)) out.push_back(Hit{e, t2});
    };
#pragma omp for schedule(dynamic, 32)
    for (Index k = 0; k < m; ++k) {
      if (k < static_cast<Index>(work.size())) {
        const Index t = work[static_cast<size_t>(k)];
        const bool td = triDirty(t);
        query.forEachOverlap(boxes_[static_cast<size_t>(t)], [&](int t2) {
          if (td)  // the dirty triangle t against every edge near it
            for (int j = 0; j < numOwnedEdges(t2); ++j) test(ownedEdges(t2)[j], t);
          for (int j = 0; j < numOwnedEdges(t); ++j) {  // t's dirty edges against every triangle
            const Index e = ownedEdges(t)[j];
            if (edgeDirty(e)) test(e, t2);
          }
        });
      } else {
        const Index e = orphan_edges_[static_cast<size_t>(k) - work.size()];
        if (e >= num_edges_considered) continue;
        const bool ed = edgeDirty(e);
        query.forEachOverlap(edge_boxes_[static_cast<size_t>(e)], [&](int t2) {
          if (ed || triDirty(t2)) test(e, t2);
        });
      }
    }
  }
  mergeSorted(local, hits);
}

bool SelfCollisionPass::sideChanged(Index q, Index t, const VecX& x_old, const VecX& x) const {
  const auto& c = tris_.triangles[static_cast<size_t>(t)];
  const int so = geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q));
  if (so == 0) return false;
  const int sn = geom::orient3d(node3(x, c[0]), node3(x, c[1]), node3(x, c[2]), node3(x, q));
  return so * sn < 0;
}

bool SelfCollisionPass::rollback(Index p, const VecX& x_old, VecX& x, std::vector<Index>& moved) const {
  if (pinned_[static_cast<size_t>(p)]) return false;
  auto xp = node3(x, p);
  const auto xo = node3(x_old, p);
  if (xp == xo) return false;
  xp = xo;
  moved.push_back(p);  // once per apply(): afterwards x(p) == x_old(p)
  return true;
}

void SelfCollisionPass::reflect(Index p, const Vec3& n, VecX& v) const {
  if (pinned_[static_cast<size_t>(p)]) return;
  auto vp = node3(v, p);
  const Real vn = vp.dot(n);
  const Vec3 vpar = Vec3(vp) - vn * n;
  vp = (1.0 - options_.tangential_damping) * vpar + options_.restitution * std::abs(vn) * n;  // thesis: v_par + |v_n| n
}

void SelfCollisionPass::respond(const Index* a, int na, const Index* b, int nb, const Vec3& n, VecX& v) const {
  if (options_.response == CollisionResponse::kStop) {
    for (int k = 0; k < na; ++k)
      if (!pinned_[static_cast<size_t>(a[k])]) node3(v, a[k]).setZero();
    for (int k = 0; k < nb; ++k)
      if (!pinned_[static_cast<size_t>(b[k])]) node3(v, b[k]).setZero();
    return;
  }
  if (options_.response == CollisionResponse::kThesis) {
    for (int k = 0; k < na; ++k) reflect(a[k], n, v);
    for (int k = 0; k < nb; ++k) reflect(b[k], -n, v);
    return;
  }
  // Momentum-conserving impulse on the relative velocity of the two groups (equal particle masses;
  // each group moves as one body, pinned particles have infinite mass).
  Vec3 va = Vec3::Zero(), vb = Vec3::Zero();
  int fa = 0, fb = 0;
  for (int k = 0; k < na; ++k) {
    va += node3(v, a[k]);
    fa += pinned_[static_cast<size_t>(a[k])] ? 0 : 1;
  }
  for (int k = 0; k < nb; ++k) {
    vb += node3(v, b[k]);
    fb += pinned_[static_cast<size_t>(b[k])] ? 0 : 1;
  }
  va /= na;
  vb /= nb;
  const Real ima = fa > 0 ? 1.0 / fa : 0.0, imb = fb > 0 ? 1.0 / fb : 0.0;
  if (ima + imb == 0) return;
  const Vec3 u = va - vb;
  const Real un = u.dot(n);
  if (un >= 0) return;  // already separating
  const Vec3 du = -(1.0 + options_.restitution) * un * n - options_.tangential_damping * (u - un * n);
  const Vec3 dva = (ima / (ima + imb)) * du, dvb = -(imb / (ima + imb)) * du;
  for (int k = 0; k < na; ++k)
    if (!pinned_[static_cast<size_t>(a[k])]) node3(v, a[k]) += dva;
  for (int k = 0; k < nb; ++k)
    if (!pinned_[static_cast<size_t>(b[k])]) node3(v, b[k]) += dvb;
}

namespace {

// Linearised crossing of q through the plane of triangle c between the old and new states: the
// barycentric coordinates (of the projection onto the interpolated triangle) at the interpolated
// time where the signed distance vanishes. Returns the smallest coordinate (large negative when
// the crossing is far outside); +inf for a degenerate triangle (accepted).
Real crossingMinBarycentric(Index q, const std::array<Index, 3>& c, const VecX& x_old, const VecX& x) {
  const Vec3 no = triNormal(x_old, c), nn = triNormal(x, c);
  const Real lo = no.norm(), ln = nn.norm();
  if (!(lo > 0) || !(ln > 0)) return std::numeric_limits<Real>::infinity();
  const Real d_old = no.dot(node3(x_old, q) - node3(x_old, c[0])) / lo;
  const Real d_new = nn.dot(node3(x, q) - node3(x, c[0])) / ln;
  const Real den = d_old - d_new;
  const Real s = den != 0 ? std::clamp(d_old / den, 0.0, 1.0) : 0.5;
  auto lerp = [&](Index p) -> Vec3 { return node3(x_old, p) + s * (node3(x, p) - node3(x_old, p)); };
  const Vec3 Q = lerp(q), C0 = lerp(c[0]), C1 = lerp(c[1]), C2 = lerp(c[2]);
  const Vec3 e0 = C1 - C0, e1 = C2 - C0, w = Q - C0;
  const Real d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = w.dot(e0), d21 = w.dot(e1);
  const Real den2 = d00 * d11 - d01 * d01;
  if (!(den2 > 1e-30 * d00 * d11)) return std::numeric_limits<Real>::infinity();
  const Real b1 = (d11 * d20 - d01 * d21) / den2;
  const Real b2 = (d00 * d21 - d01 * d20) / den2;
  return std::min({1 - b1 - b2, b1, b2});
}

}  // namespace

// ---- proximity stage (persistent contact) ---------------------------------------------------------
//
// Bridson, Fedkiw & Anderson (2002), section 7.1 ("repulsions"), adapted to a post-step pass: the
// pass receives the accepted step x_old -> x (x = x_old + h v for the implicit integrators) and
// corrects the step's displacement and the end velocity of close pairs, instead of the velocity
// that an explicit position update would use. See docs/collision.md, "Persistent contact".

namespace {

// Closest points of the segments p1p2 and q1q2 (Ericson, Real-Time Collision Detection, 5.1.9):
// parameters s (on p) and t (on q). Returns false for (nearly) parallel or degenerate segments.
bool segmentClosestParams(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, Real* s, Real* t) {
  const Vec3 d1 = p2 - p1, d2 = q2 - q1, r = p1 - q1;
  const Real a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  if (!(a > 0) || !(e > 0)) return false;
  const Real c = d1.dot(r), b = d1.dot(d2);
  const Real den = a * e - b * b;
  if (!(den > 1e-6 * a * e)) return false;  // parallel within ~0.06 degrees: vertex-triangle pairs cover it
  Real ss = std::clamp((b * f - c * e) / den, 0.0, 1.0);
  Real tt = (b * ss + f) / e;
  if (tt < 0) {
    tt = 0;
    ss = std::clamp(-c / a, 0.0, 1.0);
  } else if (tt > 1) {
    tt = 1;
    ss = std::clamp((b - c) / a, 0.0, 1.0);
  }
  *s = ss;
  *t = tt;
  return true;
}

}  // namespace

namespace {

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5): returns the
// squared distance.
Real pointTriangleDistance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Real d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Vec3 bp = p - b;
  const Real d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const Real vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + (d1 / (d1 - d3)) * ab)).squaredNorm();
  const Vec3 cp = p - c;
  const Real d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const Real vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + (d2 / (d2 - d6)) * ac)).squaredNorm();
  const Real va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b))).squaredNorm();
  const Real den = va + vb + vc;
  if (!(den != 0)) return std::min({ap.squaredNorm(), bp.squaredNorm(), cp.squaredNorm()});
  const Real v = vb / den, w = vc / den;
  return (p - (a + v * ab + w * ac)).squaredNorm();
}

// Squared distance between the segments p1p2 and q1q2 (Ericson 5.1.9, parallel case included).
Real segmentDistance2(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2) {
  const Vec3 d1 = p2 - p1, d2 = q2 - q1, r = p1 - q1;
  const Real a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  Real s = 0, t = 0;
  if (a <= 0 && e <= 0) return r.squaredNorm();
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const Real c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const Real b = d1.dot(d2), den = a * e - b * b;
      s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p1 + s * d1) - (q1 + t * d2)).squaredNorm();
}

}  // namespace

void SelfCollisionPass::buildProximityCache(const VecX& x_old, Real radius) {
  // Candidate pairs within `radius` at x_old (a Verlet list, as in molecular dynamics): they are
  // re-evaluated every step until the particles have moved relative to each other by more than the
  // list's margin (applyV3). Source: the candidate triangle pairs, which cover `radius` at x_old.
  const Index T = tris_.numTriangles();
  const Index E = tris_.numEdges();
  std::vector<geom::Aabb>& tbox = prox_tbox_;
  std::vector<geom::Aabb>& ebox = prox_ebox_;
  tbox.resize(static_cast<size_t>(T));
  ebox.resize(static_cast<size_t>(E));
  const Real r2 = radius * radius;
  const bool with_edges = options_.proximity_edges;
  // Edge-edge pairs in which at least one edge is a grid edge: the vertex-triangle pairs describe
  // most contacts; pairs of two cell diagonals add little and cost a quarter of the tests.
  const Index ee_limit = tris_.numEdges(), ngrid = tris_.num_grid_edges;
  const Index nc = static_cast<Index>(cand_.size()), nav = static_cast<Index>(adj_vt_.size());
  const Index nae = with_edges ? static_cast<Index>(adj_ee_.size()) : 0;
  const Index m = nc + nav + nae;
  auto& lvt = local_vt_;
  auto& lee = local_ee_;
  auto& ltri = local_tri_;
  resetThreadLists(lvt, threadCount());
  resetThreadLists(lee, threadCount());
  resetThreadLists(ltri, threadCount());
  // One parallel region (its start costs more than a barrier): the boxes at x_old, then the pairs.
#pragma omp parallel if (m >= 4 * kParallelMin)
  {
#pragma omp for schedule(static) nowait
    for (Index t = 0; t < T; ++t) tbox[static_cast<size_t>(t)] = triangleBox(t, x_old, x_old, 0.0, 0.0);
#pragma omp for schedule(static)
    for (Index e = 0; e < E; ++e) ebox[static_cast<size_t>(e)] = edgeBox(e, x_old, x_old);
    auto& ovt = lvt[static_cast<size_t>(threadId())].items;
    auto& oee = lee[static_cast<size_t>(threadId())].items;
    auto& otri = ltri[static_cast<size_t>(threadId())].items;
    // Vertices owned by triangle k against triangle t2.
    auto vt = [&](Index k, Index t2) {
      const auto& c = tris_.triangles[static_cast<size_t>(t2)];
      const geom::Aabb& b2 = tbox[static_cast<size_t>(t2)];
      for (Index j = owned_vertex_start_[static_cast<size_t>(k)]; j < owned_vertex_start_[static_cast<size_t>(k) + 1]; ++j) {
        const Index p = owned_vertex_list_[static_cast<size_t>(j)];
        if (c[0] == p || c[1] == p || c[2] == p) continue;
        const Vec3 xp = node3(x_old, p);
        if ((xp.array() < b2.lo.array() - radius).any() || (xp.array() > b2.hi.array() + radius).any()) continue;
        const Vec3 a0 = node3(x_old, c[0]), a1 = node3(x_old, c[1]), a2 = node3(x_old, c[2]);
        if (pointTriangleApart(xp, a0, a1, a2, r2)) continue;
        if (pointTriangleDistance2(xp, a0, a1, a2) <= r2) ovt.emplace_back(p, t2);
      }
    };
#pragma omp for schedule(dynamic, 512)  // candidate pairs cost more than the listed ones
    for (Index q = 0; q < m; ++q) {
      if (q >= nc) {  // triangles sharing a vertex: the listed feature pairs
        if (q < nc + nav) {
          const auto& c = adj_vt_[static_cast<size_t>(q - nc)];
          const auto& tc = tris_.triangles[static_cast<size_t>(c.second)];
          const Vec3 xp = node3(x_old, c.first);
          const geom::Aabb& b2 = tbox[static_cast<size_t>(c.second)];
          if ((xp.array() < b2.lo.array() - radius).any() || (xp.array() > b2.hi.array() + radius).any()) continue;
          const Vec3 a0 = node3(x_old, tc[0]), a1 = node3(x_old, tc[1]), a2 = node3(x_old, tc[2]);
          if (pointTriangleApart(xp, a0, a1, a2, r2)) continue;
          if (pointTriangleDistance2(xp, a0, a1, a2) <= r2) ovt.push_back(c);
        } else {
          const auto& c = adj_ee_[static_cast<size_t>(q - nc - nav)];
          if (!overlapInflated(ebox[static_cast<size_t>(c.first)], ebox[static_cast<size_t>(c.second)], radius)) continue;
          const auto& pe = tris_.edges[static_cast<size_t>(c.first)];
          const auto& qe = tris_.edges[static_cast<size_t>(c.second)];
          const Vec3 p1 = node3(x_old, pe[0]), p2 = node3(x_old, pe[1]), q1 = node3(x_old, qe[0]), q2 = node3(x_old, qe[1]);
          if (segmentsApart(p1, p2, q1, q2, r2)) continue;
          if (segmentDistance2(p1, p2, q1, q2) <= r2) oee.push_back(c);
        }
        continue;
      }
      const Index k = cand_[static_cast<size_t>(q)].first, t2 = cand_[static_cast<size_t>(q)].second;
      if (!overlapInflated(tbox[static_cast<size_t>(k)], tbox[static_cast<size_t>(t2)], radius)) continue;
      {
        const auto& ck = tris_.triangles[static_cast<size_t>(k)];
        const auto& c2 = tris_.triangles[static_cast<size_t>(t2)];
        if (trianglesApart(node3(x_old, ck[0]), node3(x_old, ck[1]), node3(x_old, ck[2]), node3(x_old, c2[0]),
                           node3(x_old, c2[1]), node3(x_old, c2[2]), r2))
          continue;
      }
      otri.push_back(cand_[static_cast<size_t>(q)]);
      vt(k, t2);
      vt(t2, k);
      if (!with_edges) continue;
      for (int i = 0; i < numOwnedEdges(k); ++i) {
        const Index e1 = ownedEdges(k)[i];
        if (e1 >= ee_limit) continue;
        const auto& pe = tris_.edges[static_cast<size_t>(e1)];
        for (int j = 0; j < numOwnedEdges(t2); ++j) {
          const Index e2 = ownedEdges(t2)[j];
          if (e2 >= ee_limit) continue;
          if (e1 >= ngrid && e2 >= ngrid) continue;  // two cell diagonals: see ee_limit
          const auto& qe = tris_.edges[static_cast<size_t>(e2)];
          if (pe[0] == qe[0] || pe[0] == qe[1] || pe[1] == qe[0] || pe[1] == qe[1]) continue;
          if (!overlapInflated(ebox[static_cast<size_t>(e1)], ebox[static_cast<size_t>(e2)], radius)) continue;
          const Vec3 p1 = node3(x_old, pe[0]), p2 = node3(x_old, pe[1]), q1 = node3(x_old, qe[0]), q2 = node3(x_old, qe[1]);
          if (segmentsApart(p1, p2, q1, q2, r2)) continue;
          if (segmentDistance2(p1, p2, q1, q2) <= r2) oee.emplace_back(std::min(e1, e2), std::max(e1, e2));
        }
      }
    }
  }
  // (The order is the thread's; detectProximity sorts what it finds, so results do not depend on it.)
  concatenate(lvt, prox_cache_vt_);
  concatenate(lee, prox_cache_ee_);
  concatenate(ltri, prox_tri_);
}

void SelfCollisionPass::detectProximity(const VecX& x_old, Real thickness, std::vector<ProxPair>& pairs) const {
  // Pairs closer than the search radius R at x_old, among the candidates of the list.
  const Real R = proximitySearchRadius(thickness);
  // A vertex projecting slightly outside a triangle still counts (the neighbouring triangle of a
  // fold's ridge may not see it either); weights are clamped to the triangle.
  constexpr Real kBaryTol = 0.05;
  // Edge-edge pairs only where the closest points are interior to both edges (elsewhere a
  // vertex-triangle pair describes the contact).
  constexpr Real kEdgeEnd = 1e-3;
  auto vertexTriangle = [&](Index p, Index t2, std::vector<ProxPair>& out) {
    const auto& c = tris_.triangles[static_cast<size_t>(t2)];
    const Vec3 xp = node3(x_old, p);
    const Vec3 a = node3(x_old, c[0]);
    const Vec3 e0 = node3(x_old, c[1]) - a, e1 = node3(x_old, c[2]) - a;
    Vec3 nrm = e0.cross(e1);
    const Real len = nrm.norm();
    if (!(len > 1e-9 * (e0.squaredNorm() + e1.squaredNorm()))) return;  // degenerate triangle
    nrm /= len;
    const Vec3 w = xp - a;
    Real dist = nrm.dot(w);
    if (!(std::abs(dist) < R) || dist == 0) return;
    const Real d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = w.dot(e0), d21 = w.dot(e1);
    const Real den = d00 * d11 - d01 * d01;
    Real b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den, b0 = 1 - b1 - b2;
    if (std::min({b0, b1, b2}) < -kBaryTol) return;
    b0 = std::max(b0, 0.0);
    b1 = std::max(b1, 0.0);
    b2 = std::max(b2, 0.0);
    const Real sum = b0 + b1 + b2;
    if (dist < 0) {
      nrm = -nrm;
      dist = -dist;
    }
    ProxPair pp;
    pp.type = 0;
    pp.a = p;
    pp.b = t2;
    pp.idx[0] = p;
    pp.w[0] = 1;
    for (int k = 0; k < 3; ++k) pp.idx[k + 1] = c[static_cast<size_t>(k)];
    pp.w[1] = -b0 / sum;
    pp.w[2] = -b1 / sum;
    pp.w[3] = -b2 / sum;
    pp.n = nrm;
    pp.gap = dist;
    out.push_back(pp);
  };
  auto edgeEdge = [&](Index e1, Index e2, std::vector<ProxPair>& out) {
    const auto& p = tris_.edges[static_cast<size_t>(e1)];
    const auto& q = tris_.edges[static_cast<size_t>(e2)];
    const Vec3 p1 = node3(x_old, p[0]), p2 = node3(x_old, p[1]), q1 = node3(x_old, q[0]), q2 = node3(x_old, q[1]);
    Real s = 0, t = 0;
    if (!segmentClosestParams(p1, p2, q1, q2, &s, &t)) return;
    if (s < kEdgeEnd || s > 1 - kEdgeEnd || t < kEdgeEnd || t > 1 - kEdgeEnd) return;
    const Vec3 d = (p1 + s * (p2 - p1)) - (q1 + t * (q2 - q1));
    const Real dist = d.norm();
    if (!(dist < R) || !(dist > 0)) return;
    ProxPair pp;
    pp.type = 1;
    pp.a = e1;
    pp.b = e2;
    pp.idx[0] = p[0];
    pp.idx[1] = p[1];
    pp.idx[2] = q[0];
    pp.idx[3] = q[1];
    pp.w[0] = 1 - s;
    pp.w[1] = s;
    pp.w[2] = -(1 - t);
    pp.w[3] = -t;
    pp.n = d / dist;
    pp.gap = dist;
    out.push_back(pp);
  };
  const Index nvt = static_cast<Index>(prox_cache_vt_.size()), nee = static_cast<Index>(prox_cache_ee_.size());
  const Index m = nvt + nee;
  auto& local = local_prox_;
  resetThreadLists(local, threadCount());
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
#pragma omp for schedule(static)
    for (Index k = 0; k < m; ++k) {
      if (k < nvt) {
        const auto& c = prox_cache_vt_[static_cast<size_t>(k)];
        vertexTriangle(c.first, c.second, out);
      } else {
        const auto& c = prox_cache_ee_[static_cast<size_t>(k - nvt)];
        edgeEdge(c.first, c.second, out);
      }
    }
    // Each thread sorts what it found; the sorted lists are merged below (pairs are unique, so
    // the merged order is the sorted order whatever the thread count).
    std::sort(out.begin(), out.end());
  }
  pairs.clear();
  for (auto& l : local) {
    const size_t mid = pairs.size();
    pairs.insert(pairs.end(), l.items.begin(), l.items.end());
    std::inplace_merge(pairs.begin(), pairs.begin() + static_cast<std::ptrdiff_t>(mid), pairs.end());
  }
}

Real SelfCollisionPass::estimateStep(const VecX& x_old, const VecX& x_pred, const VecX& v) const {
  // The implicit integrators end a step with x = x_old + h v exactly (pinned particles excepted);
  // h is recovered by least squares and accepted only when the relation holds to rounding.
  const Index nv = tris_.num_vertices;
  Real dv = 0, vv = 0, big = 0;
  for (Index p = 0; p < nv; ++p) {
    if (pinned_[static_cast<size_t>(p)]) continue;
    const Vec3 dp = node3(x_pred, p) - node3(x_old, p);
    dv += dp.dot(node3(v, p));
    vv += node3(v, p).squaredNorm();
    big = std::max(big, dp.norm());
  }
  if (!(vv > 0) || !(dv > 0)) return -1;
  const Real h = dv / vv;
  for (Index p = 0; p < nv; ++p) {
    if (pinned_[static_cast<size_t>(p)]) continue;
    if (!((Vec3(node3(x_pred, p) - node3(x_old, p)) - h * Vec3(node3(v, p))).norm() <= 1e-6 * big + 1e-15)) return -1;
  }
  return h;
}

long SelfCollisionPass::resolveProximity(const std::vector<ProxPair>& pairs, Real thickness, const VecX& x_old,
                                         const VecX& x_pred, VecX& x, VecX& v, SelfCollisionStats& st) {
  // A projection of the step x_old -> x_pred onto the contact constraints, by Gauss-Seidel over the
  // pairs (sorted: deterministic) in the mass metric (position-based dynamics, Mueller et al. 2007,
  // with accumulated multipliers as in XPBD, Macklin et al. 2016):
  //  * contact (inequality): the relative normal displacement of the step,
  //    delta = n . sum_i w_i (x_i - x_old_i), must not fall below T - gap (gap >= T: approach up to
  //    the thickness) or s (T - gap) (gap < T: no approach, restore a fraction s of the deficit). A
  //    multiplier lambda moves particle i by w_i m_i^-1 lambda n: Bridson et al. 2002's
  //    momentum-conserving vertex-face / edge-edge impulse, in positions;
  //  * Coulomb friction: the relative tangential displacement is cancelled by a tangential
  //    multiplier limited to mu lambda_n (sticking inside the cone, sliding outside);
  //  * grid edges (propagate): every grid edge touched keeps its length after the step, so that a
  //    correction moves the patch the integrator moved with it instead of straining the stiff
  //    tension springs (Provot 1995's deformation constraints, as a projection).
  // With contact-force feedback (a ContactForceModel passes the contact forces of the last step to
  // the integrator) the step x_old -> x_pred already felt the multipliers of the previous step as
  // forces: they are the starting point and only the change is applied here; the total is stored
  // as accelerations for the next step. At rest the change vanishes: the rest state is a fixed point.
  const Real mu = options_.proximity_friction, sep = options_.proximity_separation;
  const Index nv = tris_.num_vertices;
  const Index ne = tris_.num_grid_edges;
  const bool propagate = options_.proximity_propagate;
  Real h = estimateStep(x_old, x_pred, v);
  // A step in which nothing moved (exact rest) says nothing about h: keep the last one, so that the
  // contact forces carry on.
  if (!(h > 0) && force_feedback_ && last_h_ > 0 && x_pred == x_old) h = last_h_;
  if (h > 0) last_h_ = h;
  // Corrections below this are not worth a sweep: 0.1 % of the thickness, and at most what moves a
  // particle at 0.1 mm/s (far below the rest threshold) over the step.
  const Real tol = h > 0 ? std::min(1e-3 * thickness, 1e-4 * h) : 1e-3 * thickness;
  const bool feedback = force_feedback_ && h > 0;
  std::vector<Real> ln(pairs.size(), 0.0), W(pairs.size(), 0.0);
  std::vector<Vec3> lt(pairs.size(), Vec3::Zero());
  for (size_t k = 0; k < pairs.size(); ++k) {
    Real w = 0;
    for (int j = 0; j < 4; ++j) w += pairs[k].w[j] * pairs[k].w[j] * inv_mass_[static_cast<size_t>(pairs[k].idx[j])];
    W[k] = w;
    if (!feedback) continue;
    const auto it = contact_memory_.find(pairKey(pairs[k]));
    if (it == contact_memory_.end()) continue;
    const Vec3 lam = (h * h) * it->second;  // the multiplier the last step's force amounts to
    ln[k] = std::max(0.0, lam.dot(pairs[k].n));
    lt[k] = lam - lam.dot(pairs[k].n) * pairs[k].n;
    const Real cap = mu * ln[k], ltn = lt[k].norm();
    if (ltn > cap) lt[k] *= ltn > 0 ? cap / ltn : 0.0;
  }
  std::vector<char> in_region(static_cast<size_t>(nv), 0);
  std::vector<Index> region;
  auto touch = [&](Index p) {
    if (!in_region[static_cast<size_t>(p)]) {
      in_region[static_cast<size_t>(p)] = 1;
      region.push_back(p);
    }
  };
  auto applyPair = [&](size_t k, const Vec3& d, VecX& s) {
    const ProxPair& pp = pairs[k];
    for (int j = 0; j < 4; ++j) {
      const Real im = inv_mass_[static_cast<size_t>(pp.idx[j])];
      if (im > 0 && pp.w[j] != 0) {
        node3(s, pp.idx[j]) += (pp.w[j] * im) * d;
        touch(pp.idx[j]);
      }
    }
  };
  std::vector<char> edge_listed(propagate ? static_cast<size_t>(ne) : 0, 0);
  std::vector<std::pair<Index, Real>> edges;  // grid edges and their target lengths (after the step)
  size_t region_scanned = 0;                  // region[0, region_scanned) has its edges listed
  for (int it = 0; it < options_.proximity_iterations; ++it) {
    Real change = 0;
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (!(W[k] > 0)) continue;
      const ProxPair& pp = pairs[k];
      Vec3 rel = Vec3::Zero();
      for (int j = 0; j < 4; ++j) rel += pp.w[j] * (node3(x, pp.idx[j]) - node3(x_old, pp.idx[j]));
      const Real delta = pp.n.dot(rel);
      const Real target = pp.gap >= thickness ? thickness - pp.gap : sep * (thickness - pp.gap);
      // A pair without multipliers that does not approach past its target stays so (n_new = 0
      // caps the friction at 0: nothing moves); most pairs of a sweep are such.
      if (ln[k] == 0 && lt[k].isZero(0) && !(target - delta > 0)) continue;
      const Real n_new = std::max(0.0, ln[k] + (target - delta) / W[k]);
      // Friction: cancel the relative tangential displacement within |lambda_t| <= mu lambda_n.
      Vec3 t_new = lt[k] - (rel - delta * pp.n) / W[k];
      t_new -= pp.n.dot(t_new) * pp.n;
      const Real cap = mu * n_new, tn = t_new.norm();
      if (tn > cap) t_new *= tn > 0 ? cap / tn : 0.0;
      const Real dn = n_new - ln[k];
      const Vec3 dt = t_new - lt[k];
      const Real moved = (std::abs(dn) + dt.norm()) * W[k];
      if (!(moved > tol)) continue;
      applyPair(k, dn * pp.n + dt, x);
      ln[k] = n_new;
      lt[k] = t_new;
      change = std::max(change, moved);
    }
    if (!propagate) {
      if (!(change > tol)) break;
      continue;
    }
    // Grid edges around every particle moved so far (kept sorted: deterministic). The region only
    // grows, so only its particles added since the last sweep can bring new edges.
    const size_t before = edges.size();
    for (; region_scanned < region.size(); ++region_scanned) {
      const Index p = region[region_scanned];
      for (Index q = vertex_edge_start_[static_cast<size_t>(p)]; q < vertex_edge_start_[static_cast<size_t>(p) + 1]; ++q) {
        const Index e = vertex_edge_list_[static_cast<size_t>(q)];
        if (e >= ne || edge_listed[static_cast<size_t>(e)]) continue;
        edge_listed[static_cast<size_t>(e)] = 1;
        const auto& ed = tris_.edges[static_cast<size_t>(e)];
        edges.emplace_back(e, (node3(x_pred, ed[0]) - node3(x_pred, ed[1])).norm());
      }
    }
    if (edges.size() != before) {  // sort the new ones and merge them in
      const auto mid = edges.begin() + static_cast<std::ptrdiff_t>(before);
      std::sort(mid, edges.end());
      std::inplace_merge(edges.begin(), mid, edges.end());
    }
    for (size_t k = 0; k < edges.size(); ++k) {
      const auto& ed = tris_.edges[static_cast<size_t>(edges[k].first)];
      const Index a = ed[0], b = ed[1];
      const Real wa = inv_mass_[static_cast<size_t>(a)], wb = inv_mass_[static_cast<size_t>(b)];
      if (!(wa + wb > 0)) continue;
      Vec3 u = node3(x, a) - node3(x, b);
      const Real len = u.norm();
      if (!(len > 0)) continue;
      const Real c = len - edges[k].second;
      if (!(std::abs(c) > tol)) continue;
      u *= c / ((wa + wb) * len);
      if (wa > 0) {
        node3(x, a) -= wa * u;
        touch(a);
      }
      if (wb > 0) {
        node3(x, b) += wb * u;
        touch(b);
      }
      change = std::max(change, std::abs(c));
      ++st.proximity_edge_projections;
    }
    if (!(change > tol)) break;
  }
  long contacts = 0;
  for (size_t k = 0; k < pairs.size(); ++k) contacts += ln[k] > 0 ? 1 : 0;
  // Contact forces for the next step (as accelerations of the particles, relative-mass weighted).
  contact_memory_.clear();
  if (feedback) {
    if (contact_accel_.size() != 3 * nv) contact_accel_ = VecX::Zero(3 * nv);
    contact_accel_.setZero();
    const Real ih2 = 1.0 / (h * h);
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (!(ln[k] > 0)) continue;
      const Vec3 a = ih2 * (ln[k] * pairs[k].n + lt[k]);
      contact_memory_.emplace(pairKey(pairs[k]), a);
      for (int j = 0; j < 4; ++j) {
        const Real im = inv_mass_[static_cast<size_t>(pairs[k].idx[j])];
        if (im > 0) node3(contact_accel_, pairs[k].idx[j]) += (pairs[k].w[j] * im) * a;
      }
    }
  } else {
    contact_accel_.resize(0);
  }
  // Velocities: with x = x_old + h v the end velocity follows the corrected displacement, which
  // keeps x and v consistent (the correction acts as an impulse). Otherwise (h unknown) an inelastic
  // impulse on the relative normal velocity of every contact, with friction.
  if (h > 0) {
    std::sort(region.begin(), region.end());
    for (Index p : region) node3(v, p) += (Vec3(node3(x, p)) - Vec3(node3(x_pred, p))) / h;
  } else {
    for (int it = 0; it < options_.proximity_iterations; ++it) {
      bool any = false;
      for (size_t k = 0; k < pairs.size(); ++k) {
        if (!(ln[k] > 0) || !(W[k] > 0)) continue;
        const ProxPair& pp = pairs[k];
        Vec3 rel = Vec3::Zero();
        for (int j = 0; j < 4; ++j) rel += pp.w[j] * node3(v, pp.idx[j]);
        const Real un = pp.n.dot(rel);
        if (!(un < 0)) continue;
        Vec3 d = -un * pp.n;
        const Vec3 ut = rel - un * pp.n;
        const Real utn = ut.norm();
        if (mu > 0 && utn > 0) d -= std::min(1.0, mu * -un / utn) * ut;
        applyPair(k, d / W[k], v);
        any = true;
      }
      if (!any) break;
    }
  }
  return contacts;
}

void SelfCollisionPass::setReference(MotionReference& ref, const VecX& y) const {
  ref.x = y;
  ref.valid = y.allFinite();
}

bool SelfCollisionPass::movedLessThan(const MotionReference& ref, const VecX& y, Real budget) const {
  // Any orthogonal map Q and translation c keep all distances: with z_i = Q p_i + c (p: the
  // reference) and u_i = y_i - z_i, a pair of features of y is closer than at the build by at most
  // max |u_i - u_j| over their particles i, j (the features' points are convex combinations of
  // their particles), which is at most the diameter of the box of all u. Q, c: the identity when
  // every particle moved less than budget / 2, else the least-squares rigid fit (Kabsch 1976) of
  // a subsample. Sequential: the same decisions for every thread count (they never change a
  // result anyway, only the cost).
  const Index n = y.size() / 3;
  if (!ref.valid || ref.x.size() != y.size() || !(budget >= 0)) return false;
  if (n == 0) return true;
  const Real* p = ref.x.data();
  const Real* q = y.data();
  {
    const Real lim2 = 0.25 * budget * budget;
    bool ok = true;
    for (Index k = 0; k < n && ok; ++k) {
      const Real dx = q[3 * k] - p[3 * k], dy = q[3 * k + 1] - p[3 * k + 1], dz = q[3 * k + 2] - p[3 * k + 2];
      ok = dx * dx + dy * dy + dz * dz <= lim2;
    }
    if (ok) return true;
  }
  // Fit on about 512 particles, relative to particle 0 (small numbers, little cancellation).
  const Index stride = std::max<Index>(1, n / 512);
  const Vec3 p0(p[0], p[1], p[2]), q0(q[0], q[1], q[2]);
  Vec3 sp = Vec3::Zero(), sq = Vec3::Zero();
  Mat3 spq = Mat3::Zero();
  Index m = 0;
  for (Index k = 0; k < n; k += stride, ++m) {
    const Vec3 pk = Vec3(p[3 * k], p[3 * k + 1], p[3 * k + 2]) - p0;
    const Vec3 qk = Vec3(q[3 * k], q[3 * k + 1], q[3 * k + 2]) - q0;
    sp += pk;
    sq += qk;
    spq.noalias() += pk * qk.transpose();
  }
  const Vec3 cp = sp / static_cast<Real>(m), cq = sq / static_cast<Real>(m);
  const Mat3 H = spq - static_cast<Real>(m) * cp * cq.transpose();  // sum of (p - cp)(q - cq)^T
  if (!H.allFinite()) return false;
  const Eigen::JacobiSVD<Mat3> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Mat3 Q = svd.matrixV() * svd.matrixU().transpose();
  if (!Q.allFinite()) return false;
  // z_k = Q (p_k - p0 - cp) + q0 + cq. Q is orthogonal to rounding (relative 1e-15), which changes
  // distances of up to a few metres by far less than the allowance taken off the budget.
  const Vec3 c = q0 + cq - Q * (p0 + cp);
  const Real lim = budget - 1e-12 * (1 + p0.norm() + q0.norm());
  if (!(lim >= 0)) return false;
  Vec3 lo = Vec3::Constant(std::numeric_limits<Real>::infinity()), hi = -lo;
  for (Index k = 0; k < n; ++k) {
    const Vec3 u = Vec3(q[3 * k], q[3 * k + 1], q[3 * k + 2]) - Q * Vec3(p[3 * k], p[3 * k + 1], p[3 * k + 2]) - c;
    lo = lo.cwiseMin(u);
    hi = hi.cwiseMax(u);
  }
  const Real D = (hi - lo).norm();
  return D <= lim;
}

long SelfCollisionPass::applyV3(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st) {
  const Index E = options_.include_diagonals ? tris_.numEdges() : tris_.num_grid_edges;
  const Index nv = tris_.num_vertices;
  auto t0 = Clock::now();
  // Broad phase (docs/collision.md, "Broad phase and cost"): two Verlet lists, kept from step to
  // step while they provably contain everything needed.
  //  * cand_: the triangle pairs whose swept boxes at the build (x_old, x and the step continued
  //    by kCandidateLookahead steps) were within Rc of each other (plus the topological
  //    neighbours, listed once). Two triangles that touch now were within Rc at the build as long
  //    as every particle stayed within Rc / 2 of its box then, or no two particles moved apart by
  //    more than Rc since, less a rigid motion (cand_ref_): rigid motions keep all distances.
  //  * prox_cache_*: the vertex-triangle and edge-edge pairs within Rp at the x_old of their build
  //    (prox_ref_), taken from cand_: a pair within the search radius R now was within Rp then
  //    while no two particles of x_old moved apart by more than Rp - R, less a rigid motion. The
  //    list is rebuilt from cand_ when cand_ still covers Rp at x_old (budget Rc - Rp), else cand_
  //    is rebuilt first.
  // Without the proximity stage (Rc = 0) cand_ is built every step. Which lists are reused never
  // changes a result: what is kept is always a superset of what is tested, and everything found
  // is sorted. Rollbacks only put particles back to x_old, which the list covers.
  const Real thickness = options_.thickness_factor * tris_.spacing;
  const bool prox = options_.proximity && thickness > 0;
  const Real R = proximitySearchRadius(thickness);
  const Real Rp = prox ? proximityListRadius(thickness) : 0.0;
  const Real Rc = prox ? candidateListRadius(thickness) : 0.0;
  auto outside = [&](const VecX& y) {  // largest distance of a particle outside its reference box
    Real d = 0;
    const Real* lo = list_lo_.data();
    const Real* hi = list_hi_.data();
    const Real* py = y.data();
    for (Index k = 0; k < 3 * nv; ++k) d = std::max({d, lo[k] - py[k], py[k] - hi[k]});
    return d;
  };
  auto buildCandidates = [&](const VecX& xn) {
    const Real ahead = prox ? kCandidateLookahead : 0.0;
    collectCandidates(x_old, xn, Rc, ahead);
    list_lo_.resize(static_cast<size_t>(3 * nv));
    list_hi_.resize(static_cast<size_t>(3 * nv));
    for (Index k = 0; k < 3 * nv; ++k) {
      const Real ext = xn[k] + ahead * (xn[k] - x_old[k]);
      list_lo_[static_cast<size_t>(k)] = std::min({x_old[k], xn[k], ext});
      list_hi_[static_cast<size_t>(k)] = std::max({x_old[k], xn[k], ext});
    }
    setReference(cand_ref_, xn);
    cand_valid_ = prox;
    cand_radius_ = Rc;
    ++st.candidate_list_builds;
  };
  // cand_ contains every triangle pair within `reach` of each other at y.
  auto candidatesCover = [&](const VecX& y, Real reach) {
    if (!prox || !cand_valid_ || cand_radius_ != Rc || list_lo_.size() != static_cast<size_t>(y.size())) return false;
    const Real budget = Rc - reach;
    if (!(budget >= 0)) return false;
    if (2 * outside(y) <= budget) return true;
    return movedLessThan(cand_ref_, y, budget);
  };
  hash_current_ = false;
  if (prox) {
    bool rebuild = !list_valid_ || list_radius_ != Rp || list_edges_ != options_.proximity_edges ||
                   prox_ref_.x.size() != x_old.size();
    if (!rebuild) rebuild = !movedLessThan(prox_ref_, x_old, Rp - R);
    if (rebuild) {
      if (!candidatesCover(x_old, Rp)) buildCandidates(x);
      buildProximityCache(x_old, Rp);
      setReference(prox_ref_, x_old);
      list_valid_ = true;
      list_radius_ = Rp;
      list_edges_ = options_.proximity_edges;
      ++st.proximity_list_builds;
    }
  }
  st.broad_ms += msSince(t0);
  if (prox) {
    t0 = Clock::now();
    std::vector<ProxPair> pairs;
    detectProximity(x_old, thickness, pairs);
    st.proximity_pairs = static_cast<long>(pairs.size());
    st.proximity_detect_ms += msSince(t0);
    if (pairs.empty()) {
      resetContactForces();
    } else {
      const VecX x_pred = x;
      st.proximity_contacts = resolveProximity(pairs, thickness, x_old, x_pred, x, v, st);
    }
    st.proximity_ms += msSince(t0);
  }
  t0 = Clock::now();
  // The triangle pairs that can touch at x (after the proximity stage's corrections): those of the
  // proximity build that were within Rp while no two particles have moved apart by more than Rp
  // since (a quarter of the candidate pairs on the towel), else the candidate pairs.
  const bool near_pairs_cover = prox && list_valid_ && movedLessThan(prox_ref_, x, Rp - 1e-6);
  if (!near_pairs_cover && !candidatesCover(x, 0.0)) buildCandidates(x);
  st.broad_ms += msSince(t0);
  t0 = Clock::now();
  computeSweptBoxes(x_old, x);  // the current swept boxes (the list's boxes contain them)
  st.broad_ms += msSince(t0);
  if (!orphan_edges_.empty() && !hash_current_) {  // orphan edges are queried against the hash
    buildHash(x_old, x, 0.0);
    hash_current_ = true;
  }
  t0 = Clock::now();
  std::vector<Hit> hits;
  detectFromCandidates(near_pairs_cover ? prox_tri_ : cand_, E, x, hits);
  if (near_pairs_cover) ++st.detections_from_proximity_build;
  st.detect_ms += msSince(t0);
  st.crossings = static_cast<long>(hits.size());
  long events = 0;
  std::vector<Index> moved;

  // Thesis step for one crossing (edge e cuts triangle t owned by p0): every endpoint q of e that
  // changed sides relative to a candidate triangle of p0 (with its crossing inside that triangle)
  // is rolled back together with the triangle's corners, and the velocities are reflected apart.
  auto thesisResolve = [&](const Hit& h) {
    bool handled = false;
    const auto ed = tris_.edges[static_cast<size_t>(h.a)];
    const Index p0 = tris_.owner[static_cast<size_t>(h.t)];
    for (Index q : ed) {
      for (Index k = tris_.candidate_start[static_cast<size_t>(p0)]; k < tris_.candidate_start[static_cast<size_t>(p0) + 1]; ++k) {
        const Index tc = tris_.candidate_list[static_cast<size_t>(k)];
        if (tris_.triangleHasVertex(tc, q)) continue;
        if (!sideChanged(q, tc, x_old, x)) continue;
        const auto& c = tris_.triangles[static_cast<size_t>(tc)];
        if (options_.point_in_triangle_check &&
            crossingMinBarycentric(q, c, x_old, x) < -options_.barycentric_tolerance) {
          ++st.point_test_rejections;
          continue;
        }
        bool ch = rollback(q, x_old, x, moved);
        for (Index cc : c) ch = rollback(cc, x_old, x, moved) || ch;
        if (!ch) continue;  // only pinned particles moved: nothing a rollback can do
        Vec3 nrm = triNormal(x_old, c).normalized();
        if (geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q)) < 0) nrm = -nrm;
        respond(&q, 1, c.data(), 3, nrm, v);
        ++events;
        ++st.thesis_events;
        handled = true;
      }
    }
    return handled;
  };
  // Fallback for a crossing no candidate side change explains: restore the edge and the crossed
  // triangle, whose old configuration was crossing-free.
  auto fallbackResolve = [&](const Hit& h) {
    const auto ed = tris_.edges[static_cast<size_t>(h.a)];
    const auto& c = tris_.triangles[static_cast<size_t>(h.t)];
    bool ch = false;
    for (Index q : ed) ch = rollback(q, x_old, x, moved) || ch;
    for (Index cc : c) ch = rollback(cc, x_old, x, moved) || ch;
    if (!ch) return false;
    // Normal toward the edge's old side (its first endpoint off the plane).
    Vec3 nrm = triNormal(x_old, c).normalized();
    int side = 0;
    for (Index q : ed)
      if (side == 0)
        side = geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q));
    if (side != 0) respond(ed.data(), 2, c.data(), 3, side > 0 ? nrm : Vec3(-nrm), v);
    ++events;
    ++st.fallback_events;
    return true;
  };

  for (int pass = 0;; ++pass) {
    if (hits.empty()) break;
    if (pass >= options_.max_passes) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
    ++st.passes;
    t0 = Clock::now();
    moved.clear();
    // Sequential resolution in (edge, triangle) order: thesis rollbacks first; the fallback only
    // in a pass where no thesis rollback applies any more (so a crossing seen from the other
    // side, by another edge, gets the thesis treatment first).
    bool any_change = false;
    for (const Hit& h : hits)
      if (edgeCrosses(h.a, h.t, x)) any_change = thesisResolve(h) || any_change;
    if (!any_change && options_.fallback_rollback)
      for (const Hit& h : hits)
        if (edgeCrosses(h.a, h.t, x)) any_change = fallbackResolve(h) || any_change;
    st.resolve_ms += msSince(t0);
    t0 = Clock::now();
    if (!any_change) {
      long left = 0;
      for (const Hit& h : hits) left += edgeCrosses(h.a, h.t, x) ? 1 : 0;
      st.unresolved = left;
      st.detect_ms += msSince(t0);
      break;
    }
    // Next pass: crossings left over from this pass plus those a moved particle may have created.
    std::vector<Hit> left;
    for (const Hit& h : hits)
      if (edgeCrosses(h.a, h.t, x)) left.push_back(h);
    if (!hash_current_) {  // the candidate list was reused: the queries need this step's boxes
      buildHash(x_old, x, 0.0);
      hash_current_ = true;
    }
    detectIncremental(moved, E, x, hits);
    hits.insert(hits.end(), left.begin(), left.end());
    std::sort(hits.begin(), hits.end());
    hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
    st.detect_ms += msSince(t0);
  }
  return events;
}

long SelfCollisionPass::applyV2(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st) {
  long events = 0;
  std::vector<Hit> hits;
  for (int pass = 0;; ++pass) {
    auto t0 = Clock::now();
    buildHash(x_old, x, options_.d_min);  // pushes leave the swept boxes: rebuild every pass
    computeEdgeBoxes(x_old, x);
    st.broad_ms += msSince(t0);
    t0 = Clock::now();
    detectEdges(tris_.num_grid_edges, x, hits);
    st.detect_ms += msSince(t0);
    if (pass == 0) st.crossings = static_cast<long>(hits.size());
    if (hits.empty()) break;
    if (pass >= options_.max_passes) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
    ++st.passes;
    t0 = Clock::now();
    bool any = false;
    for (const Hit& h : hits) {
      if (!edgeCrosses(h.a, h.t, x)) continue;
      const auto ed = tris_.edges[static_cast<size_t>(h.a)];
      const auto& c = tris_.triangles[static_cast<size_t>(h.t)];
      for (Index q : ed) {
        if (pinned_[static_cast<size_t>(q)] || !sideChanged(q, h.t, x_old, x)) continue;
        const int so = geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q));
        const Vec3 nn = triNormal(x, c);
        if (!(nn.norm() > 0)) continue;
        const Vec3 nh = (so > 0 ? 1.0 : -1.0) * nn.normalized();
        const Vec3 a = node3(x, ed[0]), b = node3(x, ed[1]);
        const Real da = nh.dot(a - node3(x, c[0])), db = nh.dot(b - node3(x, c[0]));
        if (da == db) continue;
        const Vec3 cut = a + (da / (da - db)) * (b - a);
        node3(x, q) = cut + options_.d_min * nh;
        reflect(q, nh, v);
        ++events;
        any = true;
      }
    }
    st.resolve_ms += msSince(t0);
    if (!any) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
  }
  return events;
}

long SelfCollisionPass::applyV1(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st) {
  const Index n = tris_.num_vertices;
  long events = 0;
  std::vector<Hit> hits;
  for (int pass = 0;; ++pass) {
    auto t0 = Clock::now();
    buildHash(x_old, x, options_.d_min);
    st.broad_ms += msSince(t0);
    t0 = Clock::now();
    std::vector<ThreadList<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (n >= kParallelMin)
    {
      auto& out = local[static_cast<size_t>(threadId())].items;
      geom::SpatialHash::Query query(hash_);
#pragma omp for schedule(dynamic, 256)
      for (Index p = 0; p < n; ++p) {
        if (pinned_[static_cast<size_t>(p)]) continue;
        const Vec3 a = node3(x_old, p), b = node3(x, p);
        if (a == b) continue;
        geom::Aabb box;
        box.extend(a);
        box.extend(b);
        query.forEachOverlap(box, [&](int t) {
          if (tris_.triangleHasVertex(t, p)) return;
          const auto& c = tris_.triangles[static_cast<size_t>(t)];
          if (geom::segmentTriangleIntersect(a, b, node3(x, c[0]), node3(x, c[1]), node3(x, c[2]))) out.push_back(Hit{p, t});
        });
      }
    }
    mergeSorted(local, hits);
    st.detect_ms += msSince(t0);
    if (pass == 0) st.crossings = static_cast<long>(hits.size());
    if (hits.empty()) break;
    if (pass >= options_.max_passes) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
    ++st.passes;
    t0 = Clock::now();
    bool any = false;
    for (size_t k = 0; k < hits.size();) {
      // All hits of particle p; take the first along its path.
      const Index p = hits[k].a;
      size_t end = k;
      while (end < hits.size() && hits[end].a == p) ++end;
      const Vec3 a = node3(x_old, p), b = node3(x, p);
      Real best_s = std::numeric_limits<Real>::infinity();
      Vec3 best_n = Vec3::Zero();
      for (size_t j = k; j < end; ++j) {
        const auto& c = tris_.triangles[static_cast<size_t>(hits[j].t)];
        if (!geom::segmentTriangleIntersect(a, b, node3(x, c[0]), node3(x, c[1]), node3(x, c[2]))) continue;
        const Vec3 nn = triNormal(x, c);
        if (!(nn.norm() > 0)) continue;
        Vec3 nh = nn.normalized();
        const Real da = nh.dot(a - node3(x, c[0])), db = nh.dot(b - node3(x, c[0]));
        const Real s = da != db ? std::clamp(da / (da - db), 0.0, 1.0) : 0.0;
        if (da < 0 || (da == 0 && db > 0)) nh = -nh;  // toward the old side
        if (s < best_s) {
          best_s = s;
          best_n = nh;
        }
      }
      k = end;
      if (!std::isfinite(best_s)) continue;
      node3(x, p) = a + best_s * (b - a) + options_.d_min * best_n;
      reflect(p, best_n, v);
      ++events;
      any = true;
    }
    st.resolve_ms += msSince(t0);
    if (!any) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
  }
  return events;
}

}  // namespace textile_handling

namespace textile_handling {

// ---- contact-force feedback ------------------------------------------------------------------------

ContactForceModel::ContactForceModel(std::unique_ptr<ClothModel> base, SelfCollisionPass& pass)
    : owned_(std::move(base)), base_(*owned_), pass_(pass) {
  if (base_.numNodes() != pass_.triangles().num_vertices || base_.dofsPerNode() != 3)
    throw std::invalid_argument("ContactForceModel: the model does not match the self-collision pass");
  pass_.force_feedback_ = true;
}

ContactForceModel::ContactForceModel(ClothModel& base, SelfCollisionPass& pass) : base_(base), pass_(pass) {
  if (base_.numNodes() != pass_.triangles().num_vertices || base_.dofsPerNode() != 3)
    throw std::invalid_argument("ContactForceModel: the model does not match the self-collision pass");
  pass_.force_feedback_ = true;
}

std::unique_ptr<ClothModel> withContactForces(std::unique_ptr<ClothModel> model, SelfCollisionPass& pass) {
  const SelfCollisionOptions& o = pass.options();
  if (!model || o.version != SelfCollisionVersion::kRollback || !o.proximity || !o.contact_forces) return model;
  if (model->dofsPerNode() != 3 || model->numNodes() != pass.triangles().num_vertices) return model;
  if (const auto* c = dynamic_cast<const ContactForceModel*>(model.get()))
    if (&c->pass() == &pass) return model;  // already wrapped for this pass
  return std::make_unique<ContactForceModel>(std::move(model), pass);
}

ForceReport ContactForceModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const ForceReport r = base_.computeForces(x, v, f, jac);
  const VecX& a = pass_.contactAccelerations();
  if (a.size() == f.size()) f += base_.massPerDof().cwiseProduct(a);
  return r;
}

// Layout: base state, contact accelerations (A values), pairs (5 values each: key high 31 bits, key
// low 32 bits, acceleration x, y, z), then A, the number of pairs and the base state's size.
std::vector<Real> ContactForceModel::internalState() const {
  std::vector<Real> s = base_.internalState();
  const size_t base_size = s.size();
  const VecX& a = pass_.contact_accel_;
  s.insert(s.end(), a.data(), a.data() + a.size());
  std::vector<std::pair<std::uint64_t, Vec3>> mem(pass_.contact_memory_.begin(), pass_.contact_memory_.end());
  std::sort(mem.begin(), mem.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
  for (const auto& m : mem) {
    s.push_back(static_cast<Real>(m.first >> 32));
    s.push_back(static_cast<Real>(m.first & 0xffffffffULL));
    s.push_back(m.second.x());
    s.push_back(m.second.y());
    s.push_back(m.second.z());
  }
  s.push_back(static_cast<Real>(a.size()));
  s.push_back(static_cast<Real>(mem.size()));
  s.push_back(static_cast<Real>(base_size));
  return s;
}

bool ContactForceModel::setInternalState(const std::vector<Real>& state) {
  if (state.empty()) {  // a state written without contact forces (e.g. by the bare model)
    if (!base_.setInternalState(state)) return false;
    pass_.resetContactForces();
    return true;
  }
  if (state.size() < 3) return false;
  const Real na = state[state.size() - 3], nm = state[state.size() - 2], nb = state[state.size() - 1];
  const size_t n3 = static_cast<size_t>(3 * base_.numNodes());
  if (!(na == 0 || na == static_cast<Real>(n3)) || !(nm >= 0) || !(nb >= 0) || nm != std::floor(nm) || nb != std::floor(nb))
    return false;
  const size_t A = static_cast<size_t>(na), M = static_cast<size_t>(nm), B = static_cast<size_t>(nb);
  if (B + A + 5 * M + 3 != state.size()) return false;
  std::unordered_map<std::uint64_t, Vec3> mem;
  for (size_t k = 0; k < M; ++k) {
    const Real* e = state.data() + B + A + 5 * k;
    if (!(e[0] >= 0 && e[0] < 2147483648.0 && e[1] >= 0 && e[1] < 4294967296.0) || e[0] != std::floor(e[0]) ||
        e[1] != std::floor(e[1]) || !std::isfinite(e[2]) || !std::isfinite(e[3]) || !std::isfinite(e[4]))
      return false;
    const std::uint64_t key = (static_cast<std::uint64_t>(e[0]) << 32) | static_cast<std::uint64_t>(e[1]);
    mem.emplace(key, Vec3(e[2], e[3], e[4]));
  }
  VecX a(static_cast<Index>(A));
  for (size_t k = 0; k < A; ++k) {
    if (!std::isfinite(state[B + k])) return false;
    a[static_cast<Index>(k)] = state[B + k];
  }
  if (!base_.setInternalState(std::vector<Real>(state.begin(), state.begin() + static_cast<std::ptrdiff_t>(B))))
    return false;
  pass_.contact_memory_ = std::move(mem);
  pass_.contact_accel_ = std::move(a);
  return true;
}

}  // namespace textile_handling
