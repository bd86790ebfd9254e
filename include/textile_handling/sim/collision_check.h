// Independent intersection checker of a triangulated cloth: exact triangle-triangle tests
// (Devillers-Guigue) with a uniform AABB grid as broad phase. Shares no code with the self-collision
// pass except the exact predicates, so tests and scenes can check the pass with it. ROS-free.
#pragma once

#include <utility>
#include <vector>

#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// All pairs (s, t), s < t, of triangles that share no vertex and intersect (closed triangles, exact
/// predicates, see geom::triangleTriangleIntersect), sorted. Broad phase: a uniform AABB grid.
std::vector<std::pair<Index, Index>> findIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x);
/// Size of findIntersectingTrianglePairs().
long countIntersectingTrianglePairs(const ClothTriangles& tris, const VecX& x);
/// Same, by testing all pairs (O(T^2)); for checking the broad phase in tests.
long countIntersectingTrianglePairsBruteForce(const ClothTriangles& tris, const VecX& x);

}  // namespace textile_handling
