// Triangulation and the self-collision pass (versions 1-3 of the thesis). See docs/collision.md.
#include "textile_handling/sim/collision.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {

namespace {

using Clock = std::chrono::steady_clock;
// Below this many work items a loop runs on one thread: the parallel region would cost more than it
// saves (and far more on an oversubscribed machine).
constexpr Index kParallelMin = 2048;

double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

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
}

// ---- self-collision pass --------------------------------------------------------------------------

SelfCollisionPass::SelfCollisionPass(ClothTriangles tris, std::vector<char> pinned_mask, SelfCollisionOptions options)
    : tris_(std::move(tris)), pinned_(std::move(pinned_mask)), options_(options) {
  if (pinned_.empty()) pinned_.assign(static_cast<size_t>(tris_.num_vertices), 0);
  if (static_cast<Index>(pinned_.size()) != tris_.num_vertices)
    throw std::invalid_argument("SelfCollisionPass: pinned mask size differs from the particle count");
  if (!(options_.d_min >= 0) || options_.max_passes < 1 || !(options_.cell_size_factor > 0) ||
      !(options_.barycentric_tolerance >= 0) || !(options_.restitution >= 0 && options_.restitution <= 1) ||
      !(options_.tangential_damping >= 0 && options_.tangential_damping <= 1))
    throw std::invalid_argument("SelfCollisionPass: invalid options");
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

void SelfCollisionPass::buildHash(const VecX& x_old, const VecX& x, Real inflate) {
  const Index T = tris_.numTriangles();
  boxes_.resize(static_cast<size_t>(T));
#pragma omp parallel for if (T >= kParallelMin) schedule(static)
  for (Index t = 0; t < T; ++t) {
    geom::Aabb b;
    for (Index c : tris_.triangles[static_cast<size_t>(t)]) {
      b.extend(node3(x_old, c));
      b.extend(node3(x, c));
    }
    if (inflate > 0) b.inflate(inflate);
    boxes_[static_cast<size_t>(t)] = b;
  }
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
// Merges per-thread hit lists into one sorted, duplicate-free list (independent of thread count).
template <class HitT>
void mergeSorted(std::vector<std::vector<HitT>>& local, std::vector<HitT>& out) {
  out.clear();
  for (auto& l : local) out.insert(out.end(), l.begin(), l.end());
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
  std::vector<std::vector<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())];
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
  std::vector<std::vector<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())];
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

long SelfCollisionPass::applyV3(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st) {
  const Index E = options_.include_diagonals ? tris_.numEdges() : tris_.num_grid_edges;
  auto t0 = Clock::now();
  // Rollbacks only ever put particles back to x_old, so the swept boxes (old U new) stay valid
  // for all passes and the hash is built once.
  buildHash(x_old, x, 0.0);
  computeEdgeBoxes(x_old, x);
  st.broad_ms += msSince(t0);
  t0 = Clock::now();
  std::vector<Hit> hits;
  detectEdges(E, x, hits);
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
    std::vector<std::vector<Hit>> local(static_cast<size_t>(threadCount()));
#pragma omp parallel if (n >= kParallelMin)
    {
      auto& out = local[static_cast<size_t>(threadId())];
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
