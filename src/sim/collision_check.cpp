// Independent intersection checker: exact triangle-triangle tests (Devillers-Guigue) over all pairs of
// triangles that share no vertex, with a uniform AABB grid as broad phase. Deliberately shares no
// code with the self-collision pass except the exact predicates.
#include "textile_handling/sim/collision_check.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "textile_handling/sim/collision_geometry.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {

namespace {

struct Box {
  Vec3 lo, hi;
};

Box triangleBox(const ClothTriangles& tris, const VecX& x, Index t) {
  const auto& c = tris.triangles[static_cast<size_t>(t)];
  Box b{node3(x, c[0]), node3(x, c[0])};
  for (int k = 1; k < 3; ++k) {
    b.lo = b.lo.cwiseMin(node3(x, c[static_cast<size_t>(k)]));
    b.hi = b.hi.cwiseMax(node3(x, c[static_cast<size_t>(k)]));
  }
  return b;
}

bool overlap(const Box& a, const Box& b) {
  return (a.lo.array() <= b.hi.array()).all() && (b.lo.array() <= a.hi.array()).all();
}

bool intersects(const ClothTriangles& tris, const VecX& x, Index s, Index t) {
  const auto& a = tris.triangles[static_cast<size_t>(s)];
  const auto& b = tris.triangles[static_cast<size_t>(t)];
  return geom::triangleTriangleIntersect(node3(x, a[0]), node3(x, a[1]), node3(x, a[2]), node3(x, b[0]), node3(x, b[1]),
                                         node3(x, b[2]));
}

}  // namespace

std::vector<std::pair<Index, Index>> findIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x) {
  std::vector<std::pair<Index, Index>> result;
  const Index T = tris.numTriangles();
  if (T < 2) return result;
  std::vector<Box> boxes(static_cast<size_t>(T));
  Vec3 lo = Vec3::Constant(std::numeric_limits<Real>::infinity()), hi = -lo;
  for (Index t = 0; t < T; ++t) {
    boxes[static_cast<size_t>(t)] = triangleBox(tris, x, t);
    lo = lo.cwiseMin(boxes[static_cast<size_t>(t)].lo);
    hi = hi.cwiseMax(boxes[static_cast<size_t>(t)].hi);
  }
  if (!lo.allFinite() || !hi.allFinite()) return result;
  // Grid of cubic cells of the rest spacing, coarsened if the extent would need too many cells.
  Real cell = tris.spacing > 0 ? tris.spacing : 0.01;
  const Real extent = (hi - lo).maxCoeff();
  cell = std::max(cell, extent / 1e5);
  const Real inv = 1.0 / cell;
  auto cellOf = [&](const Vec3& p, int k) { return static_cast<std::int64_t>(std::floor((p[k] - lo[k]) * inv)); };
  // (cell key, triangle) entries; triangles covering too many cells are tested against everything.
  struct Entry {
    std::uint64_t key;
    Index t;
    bool operator<(const Entry& o) const { return key != o.key ? key < o.key : t < o.t; }
  };
  std::vector<Entry> entries;
  std::vector<Index> big;
  std::vector<std::array<std::int64_t, 3>> first(static_cast<size_t>(T));
  for (Index t = 0; t < T; ++t) {
    const Box& b = boxes[static_cast<size_t>(t)];
    std::int64_t c0[3], c1[3];
    long count = 1;
    for (int k = 0; k < 3; ++k) {
      c0[k] = cellOf(b.lo, k);
      c1[k] = cellOf(b.hi, k);
      count *= static_cast<long>(c1[k] - c0[k] + 1);
    }
    first[static_cast<size_t>(t)] = {c0[0], c0[1], c0[2]};
    if (count > 64) {
      big.push_back(t);
      continue;
    }
    for (std::int64_t i = c0[0]; i <= c1[0]; ++i)
      for (std::int64_t j = c0[1]; j <= c1[1]; ++j)
        for (std::int64_t k = c0[2]; k <= c1[2]; ++k)
          entries.push_back(Entry{(static_cast<std::uint64_t>(i) << 42) | (static_cast<std::uint64_t>(j) << 21) |
                                      static_cast<std::uint64_t>(k),
                                  t});
  }
  std::sort(entries.begin(), entries.end());
  std::vector<std::pair<Index, Index>> candidates;
  for (size_t a = 0; a < entries.size();) {
    size_t b = a;
    while (b < entries.size() && entries[b].key == entries[a].key) ++b;
    const std::uint64_t key = entries[a].key;
    const std::int64_t ci = static_cast<std::int64_t>(key >> 42), cj = static_cast<std::int64_t>((key >> 21) & 0x1FFFFF),
                       ck = static_cast<std::int64_t>(key & 0x1FFFFF);
    for (size_t u = a; u < b; ++u)
      for (size_t w = u + 1; w < b; ++w) {
        const Index s = entries[u].t, t = entries[w].t;
        const auto& fs = first[static_cast<size_t>(s)];
        const auto& ft = first[static_cast<size_t>(t)];
        // Count each pair in the first cell the two boxes share.
        if (std::max(fs[0], ft[0]) != ci || std::max(fs[1], ft[1]) != cj || std::max(fs[2], ft[2]) != ck) continue;
        if (!overlap(boxes[static_cast<size_t>(s)], boxes[static_cast<size_t>(t)])) continue;
        if (tris.trianglesShareVertex(s, t)) continue;
        candidates.emplace_back(std::min(s, t), std::max(s, t));
      }
    a = b;
  }
  for (Index s : big)
    for (Index t = 0; t < T; ++t) {
      if (t == s || !overlap(boxes[static_cast<size_t>(s)], boxes[static_cast<size_t>(t)]) || tris.trianglesShareVertex(s, t))
        continue;
      candidates.emplace_back(std::min(s, t), std::max(s, t));
    }
  std::sort(candidates.begin(), candidates.end());
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  std::vector<char> hit(candidates.size(), 0);
  const long m = static_cast<long>(candidates.size());
#pragma omp parallel for schedule(dynamic, 1024) if (m >= 4096)
  for (long k = 0; k < m; ++k)
    hit[static_cast<size_t>(k)] = intersects(tris, x, candidates[static_cast<size_t>(k)].first,
                                             candidates[static_cast<size_t>(k)].second);
  for (size_t k = 0; k < candidates.size(); ++k)
    if (hit[k]) result.push_back(candidates[k]);
  return result;
}

long countIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x) {
  return static_cast<long>(findIntersectingTrianglePairs(tris, x).size());
}

long countIntersectingTrianglePairsBruteForce(const ClothTriangles& tris, const VecX& x) {
  const Index T = tris.numTriangles();
  long count = 0;
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : count)
  for (Index s = 0; s < T; ++s)
    for (Index t = s + 1; t < T; ++t)
      if (!tris.trianglesShareVertex(s, t) && intersects(tris, x, s, t)) ++count;
  return count;
}

}  // namespace textile_handling
