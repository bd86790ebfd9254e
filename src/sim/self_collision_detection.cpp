// Crossing detection of the self-collision pass: edge-triangle crossings at the end of the step, from
// the hash, from the candidate pairs, or incrementally around the particles a pass moved.
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "collision_primitives.h"
#include "self_collision_parallel.h"

namespace textile_handling {

bool SelfCollisionPass::edgeCrosses(Index e, Index t, const VecX& x) const {
  const auto& ed = tris_.edges[static_cast<size_t>(e)];
  const auto& c = tris_.triangles[static_cast<size_t>(t)];
  return geom::segmentTriangleIntersect(node3(x, ed[0]), node3(x, ed[1]), node3(x, c[0]), node3(x, c[1]),
                                        node3(x, c[2]));
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

}  // namespace textile_handling
