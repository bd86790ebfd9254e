// The thesis triangulation of the particle grid (thesis section 7) with the edges and adjacency the
// collision passes need, and the pinned-particle mask they take. ROS-free.
#pragma once

#include <array>
#include <vector>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

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
  /// Mass of each particle, relative (the area it represents: the cloth is uniform). Weights the
  /// momentum-conserving impulses of the proximity stage; empty = equal masses.
  std::vector<Real> vertex_mass;

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

}  // namespace textile_handling
