// Broad phase of the self-collision pass: swept boxes, the spatial hash, the candidate triangle-pair
// list and the proximity list (Verlet lists) with their validity test. See docs/collision.md,
// "Broad phase and cost".
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/SVD>

#include "collision_primitives.h"
#include "self_collision_parallel.h"

namespace textile_handling {

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

void SelfCollisionPass::computeEdgeBoxes(const VecX& x_old, const VecX& x) {
  const Index E = tris_.numEdges();
  edge_boxes_.resize(static_cast<size_t>(E));
#pragma omp parallel for if (E >= kParallelMin) schedule(static)
  for (Index e = 0; e < E; ++e) edge_boxes_[static_cast<size_t>(e)] = edgeBox(e, x_old, x);
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

}  // namespace textile_handling
