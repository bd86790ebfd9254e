// Construction of the self-collision pass (adjacency, masses, broad-phase cells) and apply(), which
// runs the configured version. See docs/collision.md.
#include "textile_handling/sim/self_collision_pass.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "collision_primitives.h"

namespace textile_handling {

SelfCollisionPass::SelfCollisionPass(ClothTriangles tris, std::vector<char> pinned_mask, SelfCollisionOptions options)
    : tris_(std::move(tris)), pinned_(std::move(pinned_mask)), options_(options) {
  if (pinned_.empty()) pinned_.assign(static_cast<size_t>(tris_.num_vertices), 0);
  if (static_cast<Index>(pinned_.size()) != tris_.num_vertices)
    throw SimError("SelfCollisionPass: pinned mask size differs from the particle count");
  validateSelfCollisionOptions(options_);
  if (!tris_.vertex_mass.empty() && static_cast<Index>(tris_.vertex_mass.size()) != tris_.num_vertices)
    throw SimError("SelfCollisionPass: vertex_mass size differs from the particle count");
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
    throw SimError("SelfCollisionPass: state size does not match the triangulation");
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

}  // namespace textile_handling
