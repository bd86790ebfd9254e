// The thesis triangulation of the particle grid and the pinned-particle mask.
#include "textile_handling/sim/cloth_triangles.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>
#include <unordered_map>

#include "collision_primitives.h"

namespace textile_handling {

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

}  // namespace textile_handling
