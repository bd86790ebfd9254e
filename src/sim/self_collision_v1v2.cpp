// Versions 1 (point path) and 2 (grid-edge test with a push by d_min) of the thesis.
// See docs/collision.md.
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "textile_handling/sim/timing.h"
#include "collision_primitives.h"
#include "self_collision_parallel.h"

namespace textile_handling {

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
