// Tests for the collision module (docs/collision.md): triangulation, exact predicates, the
// independent intersection checker, the three self-collision versions of the thesis on hand-made
// failure scenes, obstacles, pinned particles, thread independence and two drape scenes.
#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/collision.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <string>
#include <map>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "textile_handling/sim/drape_scene.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {
namespace {

using geom::orient2d;
using geom::orient3d;
using geom::segmentTriangleIntersect;
using geom::triangleTriangleIntersect;
using geom::triangleTriangleIntersectByEdges;

// ---- helpers --------------------------------------------------------------------------------------

// Topology of the given grid cells (row i, column j); neighbours are the 4-connected cells present.
ParticleTopology topologyFromCells(const std::vector<std::array<int, 2>>& cells, Real spacing = 0.1) {
  std::map<std::pair<int, int>, Index> id;
  for (size_t k = 0; k < cells.size(); ++k) id[{cells[k][0], cells[k][1]}] = static_cast<Index>(k);
  ParticleTopology t;
  t.spacing = spacing;
  for (const auto& c : cells) {
    auto look = [&](int i, int j) {
      const auto it = id.find({i, j});
      return it == id.end() ? Index(-1) : it->second;
    };
    t.neighbour.push_back({look(c[0], c[1] + 1), look(c[0] + 1, c[1]), look(c[0], c[1] - 1), look(c[0] - 1, c[1])});
    t.grid.push_back({c[0], c[1]});
    t.area.push_back(spacing * spacing);
  }
  return t;
}

std::vector<std::array<int, 2>> block(int i0, int j0, int rows, int cols) {
  std::vector<std::array<int, 2>> c;
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) c.push_back({i0 + i, j0 + j});
  return c;
}

// A flat grid state (rows x cols, spacing d, height z).
VecX flatGrid(int rows, int cols, Real d, Real z = 0) {
  VecX x(3 * rows * cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) x.segment<3>(3 * (i * cols + j)) = Vec3(j * d, i * d, z);
  return x;
}

void setThreads(int n) {
#ifdef _OPENMP
  omp_set_num_threads(n);
#else
  (void)n;
#endif
}

int maxThreads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

struct ThreadGuard {
  int saved = maxThreads();
  ~ThreadGuard() { setThreads(saved); }
};

// ---- the two failure scenes of the thesis -----------------------------------------------------------

// Thesis 7.1 (version-1 failure): a point moves parallel to a surface while the surface moves so that
// the old and the new position of the point end up on different sides, without the point's path (or
// any vertex path of the surface) crossing a triangle. Patch A: a large 2x2 sheet rising from z = 0
// to z = 0.2. Patch B: a 3x3 "cone" whose tip q (centre, z = 0.1) slides sideways while its other
// particles stay at z = 0.3. After the step the sheet cuts through the cone.
struct Scene {
  ClothTriangles tris;
  VecX x_old, x, v;
  Index q = -1;  // the penetrating point
  std::vector<Index> patch_a;
};

Scene pointPathFailureScene() {
  auto cells = block(0, 0, 2, 2);      // patch A, particles 0..3
  const auto b = block(10, 0, 3, 3);   // patch B, particles 4..12
  cells.insert(cells.end(), b.begin(), b.end());
  Scene s;
  s.tris = ClothTriangles::fromTopology(topologyFromCells(cells));
  const Index n = static_cast<Index>(cells.size());
  s.x_old.resize(3 * n);
  s.x.resize(3 * n);
  for (Index k = 0; k < 4; ++k) {
    const auto& c = cells[static_cast<size_t>(k)];
    const Vec3 p(-1.0 + 2.0 * c[1], -1.0 + 2.0 * c[0], 0.0);
    s.x_old.segment<3>(3 * k) = p;
    s.x.segment<3>(3 * k) = p + Vec3(0, 0, 0.2);
    s.patch_a.push_back(k);
  }
  for (Index k = 4; k < n; ++k) {
    const auto& c = cells[static_cast<size_t>(k)];
    const bool tip = c[0] == 11 && c[1] == 1;
    const Vec3 p(0.05 + 0.1 * (c[1] - 1), 0.03 + 0.1 * (c[0] - 11), tip ? 0.1 : 0.3);
    s.x_old.segment<3>(3 * k) = p;
    s.x.segment<3>(3 * k) = tip ? Vec3(p + Vec3(0.02, 0.01, 0)) : p;
    if (tip) s.q = k;
  }
  s.v = (s.x - s.x_old) / 1e-2;  // as if the step took 10 ms
  return s;
}

// Thesis 7.2, failure case 1 (version-2 failure): the point q crosses triangle T' (left, flat half of
// a creased sheet) while its edges cut the neighbouring triangle T (right half, sloping down), and
// relative to T's plane q does not change sides. Patch A: 2 rows x 3 columns, crease along the
// middle column; patch B: the triangle (q, right, up) with q moving down through T'.
Scene creaseFailureScene() {
  auto cells = block(0, 0, 2, 3);  // patch A, particles 0..5
  cells.push_back({10, 0});        // q
  cells.push_back({10, 1});        // its right neighbour
  cells.push_back({11, 0});        // its up neighbour
  Scene s;
  s.tris = ClothTriangles::fromTopology(topologyFromCells(cells));
  const Index n = static_cast<Index>(cells.size());
  s.x_old.resize(3 * n);
  for (Index k = 0; k < 6; ++k) {
    const auto& c = cells[static_cast<size_t>(k)];
    s.x_old.segment<3>(3 * k) = Vec3(-0.2 + 0.2 * c[1], 0.2 * c[0], c[1] == 2 ? -0.2 : 0.0);
    s.patch_a.push_back(k);
  }
  s.q = 6;
  s.x_old.segment<3>(3 * 6) = Vec3(-0.05, 0.15, 0.03);
  s.x_old.segment<3>(3 * 7) = Vec3(0.15, 0.10, 0.05);
  s.x_old.segment<3>(3 * 8) = Vec3(0.15, 0.18, 0.05);
  s.x = s.x_old;
  s.x.segment<3>(3 * 6) = Vec3(-0.05, 0.15, -0.03);
  s.v = (s.x - s.x_old) / 1e-2;
  return s;
}

// The failure-case tests exercise the thesis's mechanisms, so v3 runs without the proximity stage
// (this module's addition in front of the rollback; tested on its own below).
SelfCollisionOptions versionOptions(SelfCollisionVersion v) {
  SelfCollisionOptions o;
  o.version = v;
  o.d_min = 1e-3;
  o.proximity = false;
  return o;
}

// Applies a pass to a copy of the scene; returns the final state.
struct Applied {
  VecX x, v;
  long events = 0;
  SelfCollisionStats stats;
};
Applied applyPass(const Scene& s, const SelfCollisionOptions& o, std::vector<char> pinned = {}) {
  SelfCollisionPass pass(s.tris, std::move(pinned), o);
  Applied a{s.x, s.v, 0, {}};
  a.events = pass.apply(s.x_old, a.x, a.v);
  a.stats = pass.lastStats();
  return a;
}

// ---- triangulation -----------------------------------------------------------------------------------

TEST(ClothTriangles, ThesisTriangulationOfAFullGrid) {
  const auto topo = topologyFromCells(block(0, 0, 3, 3));
  const ClothTriangles t = ClothTriangles::fromTopology(topo);
  // 4 cells, 2 triangles each: every cell exactly once.
  ASSERT_EQ(t.numTriangles(), 8);
  EXPECT_EQ(t.num_vertices, 9);
  // 12 grid edges and 4 diagonals (right-up of each cell).
  EXPECT_EQ(t.num_grid_edges, 12);
  EXPECT_EQ(t.numEdges(), 16);
  // Particle 0 (corner) owns only (0, right, up); particle 8 (opposite corner) only (8, left, down).
  EXPECT_GE(t.owned[0][0], 0);
  EXPECT_EQ(t.owned[0][1], -1);
  EXPECT_EQ(t.owned[8][0], -1);
  EXPECT_GE(t.owned[8][1], 0);
  EXPECT_EQ(t.triangles[static_cast<size_t>(t.owned[0][0])], (std::array<Index, 3>{0, 1, 3}));
  EXPECT_EQ(t.triangles[static_cast<size_t>(t.owned[8][1])], (std::array<Index, 3>{8, 7, 5}));
  // The centre owns both triangles.
  EXPECT_EQ(t.triangles[static_cast<size_t>(t.owned[4][0])], (std::array<Index, 3>{4, 5, 7}));
  EXPECT_EQ(t.triangles[static_cast<size_t>(t.owned[4][1])], (std::array<Index, 3>{4, 3, 1}));
  // Every cell is split once along its right-up diagonal: each cell's two triangles share it.
  std::map<std::pair<Index, Index>, int> diag_use;
  for (Index k = 0; k < t.numTriangles(); ++k) {
    const auto& c = t.triangles[static_cast<size_t>(k)];
    diag_use[{std::min(c[1], c[2]), std::max(c[1], c[2])}]++;
  }
  EXPECT_EQ(diag_use.size(), 4u);
  for (const auto& d : diag_use) EXPECT_EQ(d.second, 2);
  // Consistent orientation: all normals +z on a flat grid.
  const VecX x = flatGrid(3, 3, 0.1);
  for (const auto& c : t.triangles) {
    const Vec3 n = (node3(x, c[1]) - node3(x, c[0])).cross(node3(x, c[2]) - node3(x, c[0]));
    EXPECT_GT(n.z(), 0);
  }
  // Vertex adjacency: the centre lies in 6 triangles, a corner of the split in 2 or 1.
  EXPECT_EQ(t.vertex_triangle_start[5] - t.vertex_triangle_start[4], 6);
  EXPECT_EQ(t.vertex_triangle_start[1] - t.vertex_triangle_start[0], 1);
  EXPECT_EQ(t.vertex_triangle_start[3] - t.vertex_triangle_start[2], 2);
  // Candidate set of the centre: every triangle touching 4, 5, 7, 3, 1 = all 8.
  EXPECT_EQ(t.candidate_start[5] - t.candidate_start[4], 8);
}

TEST(ClothTriangles, MaskedGridKeepsOnlyCompleteTriangles) {
  // L shape: 3x3 minus the upper-right particle (2, 2).
  auto cells = block(0, 0, 3, 3);
  cells.erase(std::remove(cells.begin(), cells.end(), std::array<int, 2>{2, 2}), cells.end());
  const ClothTriangles t = ClothTriangles::fromTopology(topologyFromCells(cells));
  // The upper-right cell keeps its (p0, right, up) triangle (corners (1,1), (1,2), (2,1) exist) and
  // loses the (p0, left, down) one, whose owner is missing: 7 triangles.
  EXPECT_EQ(t.numTriangles(), 7);
  for (const auto& c : t.triangles)
    for (Index v : c) EXPECT_LT(v, 8);
  // A one-particle-wide strip has no triangles at all; its edges are still grid edges.
  const ClothTriangles strip = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, 1, 4)));
  EXPECT_EQ(strip.numTriangles(), 0);
  EXPECT_EQ(strip.num_grid_edges, 3);
}

TEST(ClothTriangles, FromARasterisedTextile) {
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("square"), 0.03, nullptr);
  const ClothTriangles t = ClothTriangles::fromTopology(ParticleTopology::fromGrid(g));
  EXPECT_EQ(t.num_vertices, 121);
  EXPECT_EQ(t.numTriangles(), 2 * 10 * 10);
  EXPECT_EQ(t.numEdges(), 2 * 11 * 10 + 10 * 10);
  EXPECT_EQ(countIntersectingTrianglePairs(t, flatGrid(11, 11, 0.03)), 0);
}

// ---- exact predicates -----------------------------------------------------------------------------

long long det3(const std::array<long long, 3>& a, const std::array<long long, 3>& b, const std::array<long long, 3>& c,
               const std::array<long long, 3>& d) {
  // ((b-a) x (c-a)) . (d-a) with __int128 (exact for |coordinates| < 2^20).
  __int128 u[3], v[3], w[3];
  for (int k = 0; k < 3; ++k) {
    u[k] = b[k] - a[k];
    v[k] = c[k] - a[k];
    w[k] = d[k] - a[k];
  }
  const __int128 r = (u[1] * v[2] - u[2] * v[1]) * w[0] + (u[2] * v[0] - u[0] * v[2]) * w[1] + (u[0] * v[1] - u[1] * v[0]) * w[2];
  return r > 0 ? 1 : (r < 0 ? -1 : 0);
}

TEST(ExactPredicates, Orient3dMatchesIntegerArithmetic) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> small(-3, 3), large(-(1 << 19), 1 << 19);
  int zeros = 0;
  for (int it = 0; it < 20000; ++it) {
    std::array<std::array<long long, 3>, 4> p;
    for (auto& q : p)
      for (auto& c : q) c = it % 2 ? small(rng) : large(rng);
    if (it % 3 == 0)  // force exact coplanarity: d = a + (b - a) + (c - a)
      for (int k = 0; k < 3; ++k) p[3][static_cast<size_t>(k)] = p[1][k] + p[2][k] - p[0][k];
    // An exact power-of-two scaling keeps the sign; test in [0, 1e-6) too.
    const Real scale = it % 5 == 0 ? std::ldexp(1.0, -40) : 1.0;
    Vec3 v[4];
    for (int k = 0; k < 4; ++k) v[k] = Vec3(p[k][0], p[k][1], p[k][2]) * scale;
    const int expect = static_cast<int>(det3(p[0], p[1], p[2], p[3]));
    zeros += expect == 0;
    ASSERT_EQ(orient3d(v[0], v[1], v[2], v[3]), expect) << "iteration " << it;
  }
  EXPECT_GT(zeros, 5000);  // the degenerate cases were exercised
}

TEST(ExactPredicates, Orient2dNearDegenerateWhereNaiveArithmeticFails) {
  // Points p = (0.5 + i u, 0.5 + j u), u = 2^-53, against the line through (12, 12) and (24, 24):
  // the naive double formula gets many of these signs wrong (Kettner et al. 2008).
  const Real u = std::ldexp(1.0, -53);
  const Vec2 q(12, 12), r(24, 24);
  int naive_wrong = 0;
  for (int i = 0; i < 64; ++i)
    for (int j = 0; j < 64; ++j) {
      const Vec2 p(0.5 + i * u, 0.5 + j * u);
      // Exact reference: scale by 2^53 to integers (p = 2^52 + i, ...), products fit in __int128.
      const __int128 px = (static_cast<__int128>(1) << 52) + i, py = (static_cast<__int128>(1) << 52) + j;
      const __int128 qx = static_cast<__int128>(12) << 53, rx = static_cast<__int128>(24) << 53;
      const __int128 det = (qx - px) * (rx - py) - (qx - py) * (rx - px);
      const int expect = det > 0 ? 1 : (det < 0 ? -1 : 0);
      EXPECT_EQ(orient2d(p, q, r), expect) << i << "," << j;
      const Real naive = (q.x() - p.x()) * (r.y() - p.y()) - (q.y() - p.y()) * (r.x() - p.x());
      naive_wrong += (naive > 0 ? 1 : (naive < 0 ? -1 : 0)) != expect;
    }
  EXPECT_GT(naive_wrong, 0);  // the example really is hard for plain doubles
}

TEST(ExactPredicates, SegmentTriangleCases) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), a, b, c));   // crossing
  EXPECT_FALSE(segmentTriangleIntersect(Vec3(0.8, 0.8, -1), Vec3(0.8, 0.8, 1), a, b, c));  // misses
  EXPECT_FALSE(segmentTriangleIntersect(Vec3(0.2, 0.2, 0.1), Vec3(0.2, 0.2, 1), a, b, c)); // above
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 1), a, b, c));    // endpoint on face
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1), a, b, c));   // through an edge
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(0, 0, -1), Vec3(0, 0, 1), a, b, c));           // through a vertex
  // Coplanar: overlapping and disjoint.
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(-1, 0.2, 0), Vec3(2, 0.2, 0), a, b, c));
  EXPECT_FALSE(segmentTriangleIntersect(Vec3(-1, 2, 0), Vec3(2, 2, 0), a, b, c));
  EXPECT_TRUE(segmentTriangleIntersect(Vec3(0.1, 0.1, 0), Vec3(0.2, 0.1, 0), a, b, c));  // inside
}

// ---- triangle-triangle test (the checker's narrow phase) ------------------------------------------------

TEST(TriangleTriangle, HandMadePairs) {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Crossing: a vertical triangle piercing the face.
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.2, 0.2, -0.5), Vec3(0.3, 0.2, 0.5), Vec3(0.2, 0.3, 0.5)));
  // Touching along an edge: the other triangle stands on the face, its lower edge lying in it.
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.1, 0.1, 0), Vec3(0.4, 0.1, 0), Vec3(0.2, 0.1, 1)));
  // Touching in one point: a vertex on the face.
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.2, 0.2, 0), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)));
  // Edge against edge (the two boundaries cross in one point).
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.5, -0.5, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 1)));
  // Parallel planes, separated.
  EXPECT_FALSE(triangleTriangleIntersect(a, b, c, Vec3(0, 0, 1e-9), Vec3(1, 0, 1e-9), Vec3(0, 1, 1e-9)));
  // Non-parallel but apart (the planes cut outside both triangles).
  EXPECT_FALSE(triangleTriangleIntersect(a, b, c, Vec3(2, 2, -1), Vec3(3, 2, 1), Vec3(2, 3, 1)));
  // Coplanar overlap counts as intersecting (decision, docs/collision.md).
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.2, 0.2, 0), Vec3(1.2, 0.2, 0), Vec3(0.2, 1.2, 0)));
  // Coplanar, one inside the other.
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(0.1, 0.1, 0), Vec3(0.2, 0.1, 0), Vec3(0.1, 0.2, 0)));
  // Coplanar, disjoint; and coplanar, touching at a vertex.
  EXPECT_FALSE(triangleTriangleIntersect(a, b, c, Vec3(1, 1, 0), Vec3(2, 1, 0), Vec3(1, 2, 0)));
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, Vec3(1, 0, 0), Vec3(2, 0, 0), Vec3(2, 1, 0)));
  // Neighbouring grid triangles that share an edge do intersect (the checker skips such pairs).
  EXPECT_TRUE(triangleTriangleIntersect(a, b, c, b, Vec3(1, 1, 0), c));
}

TEST(TriangleTriangle, DevillersGuigueAgreesWithEdgeTestsOnRandomAndDegenerateInput) {
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> coord(-2, 2);  // a tiny lattice: many touching/coplanar cases
  std::uniform_real_distribution<Real> real(-1, 1);
  long hits = 0;
  for (int it = 0; it < 40000; ++it) {
    Vec3 p[6];
    for (auto& v : p) v = it % 2 ? Vec3(coord(rng), coord(rng), coord(rng)) : Vec3(real(rng), real(rng), real(rng));
    if (it % 7 == 0)
      for (int k = 3; k < 6; ++k) p[k].z() = p[0].z();  // coplanar-ish sets
    const bool dg = triangleTriangleIntersect(p[0], p[1], p[2], p[3], p[4], p[5]);
    const bool edges = triangleTriangleIntersectByEdges(p[0], p[1], p[2], p[3], p[4], p[5]);
    ASSERT_EQ(dg, edges) << "iteration " << it;
    // Symmetric in the two triangles and in the vertex order.
    ASSERT_EQ(dg, triangleTriangleIntersect(p[3], p[4], p[5], p[0], p[1], p[2]));
    ASSERT_EQ(dg, triangleTriangleIntersect(p[1], p[0], p[2], p[5], p[3], p[4]));
    hits += dg;
  }
  EXPECT_GT(hits, 1000);
  EXPECT_LT(hits, 39000);
}

// ---- the independent checker -------------------------------------------------------------------------

TEST(IntersectionChecker, FlatAndFoldedGridsAreClean) {
  const int R = 12, C = 12;
  const ClothTriangles t = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, R, C), 0.01));
  VecX x = flatGrid(R, C, 0.01);
  EXPECT_EQ(countIntersectingTrianglePairs(t, x), 0);
  // Fold the right half over the left half, 2 mm above it: close but apart.
  for (int i = 0; i < R; ++i)
    for (int j = 7; j < C; ++j) x.segment<3>(3 * (i * C + j)) = Vec3((12 - j) * 0.01, i * 0.01, 0.002 + (j - 6) * 1e-4);
  EXPECT_EQ(countIntersectingTrianglePairs(t, x), 0);
  // Push one particle of the upper layer through the lower one.
  x[3 * (5 * C + 9) + 2] = -0.003;
  EXPECT_GT(countIntersectingTrianglePairs(t, x), 0);
}

TEST(IntersectionChecker, BroadPhaseMatchesBruteForce) {
  std::mt19937 rng(3);
  std::normal_distribution<Real> noise(0, 0.012);
  const int R = 14, C = 14;
  const ClothTriangles t = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, R, C), 0.01));
  long total = 0;
  for (int trial = 0; trial < 5; ++trial) {
    VecX x = flatGrid(R, C, 0.01);
    for (Index k = 0; k < x.size(); ++k) x[k] += noise(rng);  // crumpled: many intersections
    const long fast = countIntersectingTrianglePairs(t, x);
    EXPECT_EQ(fast, countIntersectingTrianglePairsBruteForce(t, x));
    total += fast;
    // The pair list is sorted and contains no pair sharing a vertex.
    const auto pairs = findIntersectingTrianglePairs(t, x);
    EXPECT_TRUE(std::is_sorted(pairs.begin(), pairs.end()));
    for (const auto& p : pairs) EXPECT_FALSE(t.trianglesShareVertex(p.first, p.second));
  }
  EXPECT_GT(total, 50);
}

TEST(SpatialHash, QueriesReturnEveryOverlappingBoxOnce) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<Real> pos(-0.2, 0.2), size(0.0, 0.04);
  std::vector<geom::Aabb> boxes(600);
  for (size_t k = 0; k < boxes.size(); ++k) {
    const Vec3 lo(pos(rng), pos(rng), pos(rng));
    boxes[k].lo = lo;
    boxes[k].hi = lo + Vec3(size(rng), size(rng), k % 50 == 0 ? 1.0 : size(rng));  // a few oversized
  }
  geom::SpatialHash hash;
  hash.build(boxes, 0.02);
  geom::SpatialHash::Query query(hash);
  for (int it = 0; it < 300; ++it) {
    geom::Aabb q;
    q.lo = Vec3(pos(rng), pos(rng), pos(rng));
    q.hi = q.lo + Vec3(size(rng), size(rng), size(rng)) * 2;
    std::vector<int> got, want;
    query.forEachOverlap(q, [&](int id) { got.push_back(id); });
    for (int k = 0; k < hash.size(); ++k)
      if (boxes[static_cast<size_t>(k)].overlaps(q)) want.push_back(k);
    std::sort(got.begin(), got.end());
    EXPECT_TRUE(std::adjacent_find(got.begin(), got.end()) == got.end()) << "duplicate report";
    // Conservative: every overlapping box is reported; extra ones only within float rounding.
    EXPECT_TRUE(std::includes(got.begin(), got.end(), want.begin(), want.end()));
    EXPECT_LE(got.size(), want.size() + 2);
  }
}

TEST(SpatialHash, QueryingAboveTheOwnIdFindsEveryOverlappingPairOnce) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<Real> pos(-0.1, 0.1), size(0.0, 0.03);
  std::vector<geom::Aabb> boxes(400);
  for (size_t k = 0; k < boxes.size(); ++k) {
    const Vec3 lo(pos(rng), pos(rng), pos(rng));
    boxes[k].lo = lo;
    boxes[k].hi = lo + Vec3(size(rng), k % 40 == 0 ? 1.0 : size(rng), size(rng));  // a few oversized
  }
  geom::SpatialHash hash;
  hash.build(boxes, 0.02);
  geom::SpatialHash::Query query(hash);
  std::vector<std::pair<int, int>> got, want;
  for (int i = 0; i < hash.size(); ++i) {
    query.forEachOverlapAbove(boxes[static_cast<size_t>(i)], i, [&](int j) {
      EXPECT_GT(j, i);
      got.emplace_back(i, j);
    });
    for (int j = i + 1; j < hash.size(); ++j)
      if (boxes[static_cast<size_t>(i)].overlaps(boxes[static_cast<size_t>(j)])) want.emplace_back(i, j);
  }
  std::sort(got.begin(), got.end());
  EXPECT_TRUE(std::adjacent_find(got.begin(), got.end()) == got.end()) << "duplicate pair";
  EXPECT_TRUE(std::includes(got.begin(), got.end(), want.begin(), want.end()));
  EXPECT_LE(got.size(), want.size() + 4);
}

// ---- thesis failure cases ------------------------------------------------------------------------------

TEST(SelfCollisionFailureCases, PointPathVersionMissesTheMovingSurface) {
  const Scene s = pointPathFailureScene();
  ASSERT_EQ(countIntersectingTrianglePairs(s.tris, s.x_old), 0);  // x_old is collision-free
  ASSERT_GT(countIntersectingTrianglePairs(s.tris, s.x), 0);      // the step penetrated
  // v1: neither the tip's path nor any vertex path crosses a triangle -> nothing is detected.
  const Applied v1 = applyPass(s, versionOptions(SelfCollisionVersion::kPointPath));
  EXPECT_EQ(v1.events, 0);
  EXPECT_EQ(v1.stats.crossings, 0);
  EXPECT_GT(countIntersectingTrianglePairs(s.tris, v1.x), 0);
  // v3 resolves it through the thesis mechanism alone (no fallback needed).
  SelfCollisionOptions o3 = versionOptions(SelfCollisionVersion::kRollback);
  o3.fallback_rollback = false;
  const Applied v3 = applyPass(s, o3);
  EXPECT_GT(v3.events, 0);
  EXPECT_GT(v3.stats.thesis_events, 0);
  EXPECT_EQ(v3.stats.fallback_events, 0);
  EXPECT_EQ(v3.stats.unresolved, 0);
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, v3.x), 0);
  // The tip was rolled back to its old position.
  EXPECT_EQ(Vec3(node3(v3.x, s.q)), Vec3(node3(s.x_old, s.q)));
  // With the default options and with the literal thesis options as well.
  const Applied v3d = applyPass(s, versionOptions(SelfCollisionVersion::kRollback));
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, v3d.x), 0);
  EXPECT_EQ(v3d.stats.unresolved, 0);
  const Applied v3t = applyPass(s, SelfCollisionOptions::thesisLiteral());
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, v3t.x), 0);
}

TEST(SelfCollisionFailureCases, EdgeVersionMissesTheCrossedNeighbourTriangle) {
  const Scene s = creaseFailureScene();
  ASSERT_EQ(countIntersectingTrianglePairs(s.tris, s.x_old), 0);
  ASSERT_GT(countIntersectingTrianglePairs(s.tris, s.x), 0);
  // v2: the edges of q cut triangle T of the sloped half, but relative to T's plane neither endpoint
  // changed sides; the triangle q actually crossed (flat half) is never looked at.
  const Applied v2 = applyPass(s, versionOptions(SelfCollisionVersion::kEdge));
  EXPECT_GT(v2.stats.crossings, 0);  // the edge-triangle crossings were found ...
  EXPECT_EQ(v2.events, 0);           // ... but not resolved
  EXPECT_GT(countIntersectingTrianglePairs(s.tris, v2.x), 0);
  // v3: the candidate set of the crossed triangle's owner contains the flat neighbour, relative to
  // which q changed sides: q is rolled back.
  SelfCollisionOptions o3 = versionOptions(SelfCollisionVersion::kRollback);
  o3.fallback_rollback = false;
  const Applied v3 = applyPass(s, o3);
  EXPECT_GT(v3.stats.thesis_events, 0);
  EXPECT_EQ(v3.stats.unresolved, 0);
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, v3.x), 0);
  EXPECT_EQ(Vec3(node3(v3.x, s.q)), Vec3(node3(s.x_old, s.q)));
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, applyPass(s, SelfCollisionOptions::thesisLiteral()).x), 0);
  // With the proximity stage (default options) q is stopped at the thickness above the flat half
  // before it crosses (q starts 3 cm above it, within the search radius): nothing to roll back.
  const Applied vp = applyPass(s, SelfCollisionOptions{});
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, vp.x), 0);
  EXPECT_EQ(vp.stats.thesis_events + vp.stats.fallback_events, 0);
  EXPECT_GT(vp.stats.proximity_contacts, 0);
  EXPECT_GT(node3(vp.x, s.q).z(), node3(vp.x, 0).z());
  // v1 handles this one (the path of q crosses the flat triangle): the two versions fail differently.
  const Applied v1 = applyPass(s, versionOptions(SelfCollisionVersion::kPointPath));
  EXPECT_GT(v1.events, 0);
  EXPECT_EQ(countIntersectingTrianglePairs(s.tris, v1.x), 0);
  EXPECT_GT(node3(v1.x, s.q).z(), 0);  // pushed back above the flat half by d_min
}

TEST(SelfCollisionFailureCases, PushVersionsPushByDminAndReflect) {
  const Scene s = creaseFailureScene();
  SelfCollisionOptions o = versionOptions(SelfCollisionVersion::kPointPath);
  o.d_min = 2e-3;
  const Applied v1 = applyPass(s, o);
  // The hit point on the flat triangle is (x, y, 0); the push puts q at d_min above it.
  EXPECT_NEAR(node3(v1.x, s.q).z(), 2e-3, 1e-12);
  EXPECT_NEAR(node3(v1.x, s.q).x(), -0.05, 1e-12);
  // Velocity reflected: the downward normal velocity now points up with the same magnitude.
  EXPECT_NEAR(node3(v1.v, s.q).z(), -node3(s.v, s.q).z(), 1e-12);
}

TEST(SelfCollisionFailureCases, VelocityResponses) {
  const Scene s = pointPathFailureScene();
  for (auto resp : {CollisionResponse::kStop, CollisionResponse::kThesis, CollisionResponse::kRelative}) {
    SelfCollisionOptions o = versionOptions(SelfCollisionVersion::kRollback);
    o.response = resp;
    const Applied a = applyPass(s, o);
    EXPECT_EQ(countIntersectingTrianglePairs(s.tris, a.x), 0);
    const Vec3 vq = node3(a.v, s.q);
    if (resp == CollisionResponse::kStop) {
      EXPECT_EQ(vq, Vec3::Zero());
    } else if (resp == CollisionResponse::kThesis) {
      // The tip moved sideways only: v_n = 0, so the reflection keeps its velocity.
      EXPECT_NEAR((vq - Vec3(node3(s.v, s.q))).norm(), 0.0, 1e-12);
    } else {
      // The sheet approached the tip from below at 20 m/s: the relative normal velocity is reversed.
      EXPECT_GT(vq.z(), 0);
    }
  }
}

// ---- v3 on random crumpling: always intersection-free, thread-independent ------------------------------

struct RandomCrumple {
  ClothTriangles tris;
  VecX x_old, x, v;
};

RandomCrumple randomCrumple(int R, int C, Real amplitude, unsigned seed) {
  RandomCrumple r;
  r.tris = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, R, C), 0.01));
  r.x_old = flatGrid(R, C, 0.01);
  std::mt19937 rng(seed);
  std::normal_distribution<Real> noise(0, amplitude);
  r.x = r.x_old;
  for (Index k = 0; k < r.x.size(); ++k) r.x[k] += noise(rng);
  r.v = (r.x - r.x_old) / 1e-3;
  return r;
}

TEST(SelfCollisionRollback, RandomStepsEndIntersectionFree) {
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const RandomCrumple r = randomCrumple(16, 16, 0.008, seed);
    ASSERT_GT(countIntersectingTrianglePairs(r.tris, r.x), 0);
    SelfCollisionPass pass(r.tris, {}, SelfCollisionOptions{});
    VecX x = r.x, v = r.v;
    pass.apply(r.x_old, x, v);
    EXPECT_EQ(pass.lastStats().unresolved, 0);
    EXPECT_EQ(countIntersectingTrianglePairs(r.tris, x), 0) << "seed " << seed;
    // Every particle is at its old or its new position (rollback never invents positions).
    for (Index p = 0; p < r.tris.num_vertices; ++p) {
      const Vec3 xp = node3(x, p);
      EXPECT_TRUE(xp == Vec3(node3(r.x_old, p)) || xp == Vec3(node3(r.x, p)));
    }
  }
}

TEST(SelfCollisionRollback, FirstDetectionFindsEveryCrossingOfABruteForceSearch) {
  // The broad phase (cells in a hash, neighbouring cells' triangle pairs listed by topology, the
  // triangles that share a vertex, edges of no triangle) must hand every crossing edge-triangle
  // pair to the exact test: the crossings of the first detection equal those of a search over all
  // pairs. A hole, a one-particle-wide strip and more than 2048 cells put the irregular and the
  // parallel paths to work.
  std::vector<std::array<int, 2>> pts;
  for (const auto& p : block(0, 0, 48, 48))
    if (!(p[0] >= 20 && p[0] < 30 && p[1] >= 15 && p[1] < 25)) pts.push_back(p);
  for (int i = 48; i < 56; ++i) pts.push_back({i, 5});  // a one-particle-wide strip: edges of no triangle
  const ClothTriangles tris = ClothTriangles::fromTopology(topologyFromCells(pts, 0.01));
  ASSERT_GT(tris.numTriangles() / 2, 2048);
  {
    std::vector<char> in_triangle(tris.edges.size(), 0);
    for (const auto& te : tris.triangle_edges)
      for (Index e : te) in_triangle[static_cast<size_t>(e)] = 1;
    ASSERT_GT(std::count(in_triangle.begin(), in_triangle.end(), 0), 0) << "no edge outside the triangles";
  }
  VecX x_old(3 * static_cast<Index>(pts.size()));
  for (size_t k = 0; k < pts.size(); ++k) {
    x_old.segment<3>(3 * static_cast<Index>(k)) = Vec3(pts[k][1] * 0.01, pts[k][0] * 0.01, 0);
    // The strip lies 3 mm above the sheet (and its first edge reaches across it), so that the
    // step makes its edges cross the sheet.
    if (pts[k][0] >= 48) x_old.segment<3>(3 * static_cast<Index>(k)) = Vec3(0.05 + 0.01 * (pts[k][0] - 48), 0.10, 0.003);
  }
  for (unsigned seed : {3u, 4u}) {
    std::mt19937 rng(seed);
    std::normal_distribution<Real> noise(0, 0.007);
    VecX x = x_old;
    for (Index k = 0; k < x.size(); ++k) x[k] += noise(rng);
    long brute = 0;
    for (Index e = 0; e < tris.numEdges(); ++e) {
      const auto& ed = tris.edges[static_cast<size_t>(e)];
      const Vec3 p = node3(x, ed[0]), q = node3(x, ed[1]);
      for (Index t = 0; t < tris.numTriangles(); ++t) {
        if (tris.triangleHasVertex(t, ed[0]) || tris.triangleHasVertex(t, ed[1])) continue;
        const auto& c = tris.triangles[static_cast<size_t>(t)];
        const Vec3 a = node3(x, c[0]), b = node3(x, c[1]), d = node3(x, c[2]);
        const Vec3 lo = a.cwiseMin(b).cwiseMin(d), hi = a.cwiseMax(b).cwiseMax(d);
        if ((p.cwiseMax(q).array() < lo.array()).any() || (p.cwiseMin(q).array() > hi.array()).any()) continue;
        if (segmentTriangleIntersect(p, q, a, b, d)) ++brute;
      }
    }
    ASSERT_GT(brute, 0) << "seed " << seed << ": the step crosses nothing, the test tests nothing";
    SelfCollisionOptions o;
    o.proximity = false;  // the detection sees the step as given
    SelfCollisionPass pass(tris, {}, o);
    VecX xs = x, vs = (x - x_old) / 1e-3;
    pass.apply(x_old, xs, vs);
    EXPECT_EQ(pass.lastStats().crossings, brute) << "seed " << seed;
    EXPECT_EQ(countIntersectingTrianglePairs(tris, xs), 0) << "seed " << seed;
  }
}

TEST(SelfCollisionRollback, DetectionFromTheProximityBuildFindsEveryCrossing) {
  // With the proximity stage on, the first detection tests only the triangle pairs the proximity
  // build kept (within Rp = 2 T at x_old) while no two particles moved apart by more than Rp since;
  // else all candidate pairs. A sheet hangs 4.5 mm over another (beyond the search radius R = 1.5 T
  // = 3.75 mm, within Rp = 5 mm: no proximity pair acts on it). Some of its particles then drop
  // through the lower sheet: by 4.8 mm (less than Rp: the short list) or by 7 mm (more: the
  // candidate pairs). Both must find every crossing of a search over all pairs.
  const Real d = 0.01;
  std::vector<std::array<int, 2>> pts = block(0, 0, 24, 24);
  const auto upper = block(0, 40, 24, 24);
  pts.insert(pts.end(), upper.begin(), upper.end());
  const ClothTriangles tris = ClothTriangles::fromTopology(topologyFromCells(pts, d));
  VecX x_old(3 * static_cast<Index>(pts.size()));
  for (size_t k = 0; k < pts.size(); ++k) {
    const bool up = pts[k][1] >= 40;
    // The upper sheet is shifted in the plane so that its particles lie over triangle interiors.
    x_old.segment<3>(3 * static_cast<Index>(k)) =
        up ? Vec3((pts[k][1] - 40 + 0.3) * d, (pts[k][0] + 0.4) * d, 0.0045) : Vec3(pts[k][1] * d, pts[k][0] * d, 0.0);
  }
  for (const Real drop : {0.0048, 0.007}) {
    VecX x = x_old;
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> pick(2, 21);
    for (int n = 0; n < 12; ++n) {  // interior particles of the upper sheet
      const Index k = static_cast<Index>(24 * 24 + 24 * pick(rng) + pick(rng));
      x[3 * k + 2] = 0.0045 - drop;
    }
    long brute = 0;
    for (Index e = 0; e < tris.numEdges(); ++e) {
      const auto& ed = tris.edges[static_cast<size_t>(e)];
      for (Index t = 0; t < tris.numTriangles(); ++t) {
        if (tris.triangleHasVertex(t, ed[0]) || tris.triangleHasVertex(t, ed[1])) continue;
        const auto& c = tris.triangles[static_cast<size_t>(t)];
        const Vec3 p = node3(x, ed[0]), q = node3(x, ed[1]), a = node3(x, c[0]), b = node3(x, c[1]), f = node3(x, c[2]);
        const Vec3 lo = a.cwiseMin(b).cwiseMin(f), hi = a.cwiseMax(b).cwiseMax(f);
        if ((p.cwiseMax(q).array() < lo.array()).any() || (p.cwiseMin(q).array() > hi.array()).any()) continue;
        if (segmentTriangleIntersect(p, q, a, b, f)) ++brute;
      }
    }
    ASSERT_GT(brute, 0) << "drop " << drop << ": nothing crosses, the test tests nothing";
    SelfCollisionOptions o;
    ASSERT_TRUE(o.proximity);
    SelfCollisionPass pass(tris, {}, o);
    VecX xs = x, vs = (x - x_old) / 1e-3;
    pass.apply(x_old, xs, vs);
    EXPECT_EQ(pass.lastStats().proximity_pairs, 0) << "drop " << drop;
    EXPECT_EQ(pass.lastStats().crossings, brute) << "drop " << drop;
    EXPECT_EQ(pass.lastStats().detections_from_proximity_build, drop < 0.005 ? 1 : 0) << "drop " << drop;
    EXPECT_EQ(countIntersectingTrianglePairs(tris, xs), 0) << "drop " << drop;
  }
}

TEST(SelfCollisionRollback, PassCapIsRespectedAndReported) {
  const RandomCrumple r = randomCrumple(16, 16, 0.01, 9);
  SelfCollisionOptions o;
  o.max_passes = 1;
  SelfCollisionPass pass(r.tris, {}, o);
  VecX x = r.x, v = r.v;
  pass.apply(r.x_old, x, v);
  EXPECT_EQ(pass.lastStats().passes, 1);
  EXPECT_GT(pass.lastStats().unresolved, 0);  // one pass is not enough for this much crumpling
}

TEST(SelfCollisionRollback, ResultsDoNotDependOnTheThreadCount) {
  ThreadGuard guard;
  for (auto version : {SelfCollisionVersion::kPointPath, SelfCollisionVersion::kEdge, SelfCollisionVersion::kRollback}) {
    // Large enough (> 2048 triangles) for the parallel code paths to run.
    const RandomCrumple r = randomCrumple(50, 50, 0.006, 21);
    std::vector<VecX> xs, vs;
    std::vector<long> events;
    for (int threads : {1, 2, 4}) {
      setThreads(threads);
      SelfCollisionOptions o;
      o.version = version;
      SelfCollisionPass pass(r.tris, {}, o);
      VecX x = r.x, v = r.v;
      events.push_back(pass.apply(r.x_old, x, v));
      xs.push_back(x);
      vs.push_back(v);
      EXPECT_EQ(countIntersectingTrianglePairs(r.tris, x), countIntersectingTrianglePairs(r.tris, xs.front()));
    }
    for (size_t k = 1; k < xs.size(); ++k) {
      EXPECT_EQ(events[k], events[0]) << toString(version);
      EXPECT_TRUE(xs[k] == xs[0]) << toString(version);  // bitwise
      EXPECT_TRUE(vs[k] == vs[0]) << toString(version);
    }
  }
}

// ---- pinned particles -------------------------------------------------------------------------------

TEST(PinnedParticles, NeverMovedBySelfCollision) {
  // Pin the rising sheet of the point-path scene: it moves by prescription, so the pass may not
  // roll it back; the crossing then cannot be resolved and must be reported as unresolved.
  const Scene s = pointPathFailureScene();
  std::vector<char> pinned(static_cast<size_t>(s.tris.num_vertices), 0);
  for (Index p : s.patch_a) pinned[static_cast<size_t>(p)] = 1;
  for (auto version : {SelfCollisionVersion::kPointPath, SelfCollisionVersion::kEdge, SelfCollisionVersion::kRollback}) {
    for (auto resp : {CollisionResponse::kStop, CollisionResponse::kThesis, CollisionResponse::kRelative}) {
      SelfCollisionOptions o = versionOptions(version);
      o.response = resp;
      const Applied a = applyPass(s, o, pinned);
      for (Index p : s.patch_a) {
        EXPECT_EQ(Vec3(node3(a.x, p)), Vec3(node3(s.x, p))) << toString(version);
        EXPECT_EQ(Vec3(node3(a.v, p)), Vec3(node3(s.v, p))) << toString(version);
      }
      if (version == SelfCollisionVersion::kRollback) {
        EXPECT_GT(a.stats.unresolved, 0);
        EXPECT_GT(countIntersectingTrianglePairs(s.tris, a.x), 0);
      }
    }
  }
  // Pinning the penetrating point of the crease scene instead: it stays where it was put.
  const Scene c = creaseFailureScene();
  std::vector<char> pin_q(static_cast<size_t>(c.tris.num_vertices), 0);
  pin_q[static_cast<size_t>(c.q)] = 1;
  for (auto version : {SelfCollisionVersion::kPointPath, SelfCollisionVersion::kEdge, SelfCollisionVersion::kRollback}) {
    const Applied a = applyPass(c, versionOptions(version), pin_q);
    EXPECT_EQ(Vec3(node3(a.x, c.q)), Vec3(node3(c.x, c.q)));
    EXPECT_EQ(Vec3(node3(a.v, c.q)), Vec3(node3(c.v, c.q)));
  }
}

TEST(PinnedParticles, MaskFromPinnedNodesAndSizeChecks) {
  PinnedNodes pins;
  pins.nodes = {1, 3};
  pins.anchors = {Vec3::Zero(), Vec3::Zero()};
  const auto m = pinnedMask(5, pins);
  EXPECT_EQ(m, (std::vector<char>{0, 1, 0, 1, 0}));
  const ClothTriangles t = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, 2, 2)));
  EXPECT_THROW(SelfCollisionPass(t, std::vector<char>(3, 0)), std::invalid_argument);
  SelfCollisionPass pass(t, {});
  VecX x = VecX::Zero(6), v = VecX::Zero(6);
  EXPECT_THROW(pass.apply(VecX::Zero(6), x, v), std::invalid_argument);
  EXPECT_EQ(selfCollisionVersionFromString("v2"), SelfCollisionVersion::kEdge);
  EXPECT_THROW(selfCollisionVersionFromString("v4"), std::invalid_argument);
}

TEST(SelfCollisionOptionsCheck, EachBadFieldIsNamedWithItsRange) {
  const ClothTriangles t = ClothTriangles::fromTopology(topologyFromCells(block(0, 0, 2, 2)));
  SelfCollisionOptions bad;
  bad.restitution = 1.5;
  bad.thickness_factor = 0.4;
  bad.proximity_iterations = 0;
  std::string message;
  try {
    SelfCollisionPass pass(t, {}, bad);
  } catch (const std::invalid_argument& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("SelfCollisionPass"), std::string::npos) << message;
  EXPECT_NE(message.find("restitution = 1.5, accepted: [0, 1]"), std::string::npos) << message;
  EXPECT_NE(message.find("thickness_factor = 0.4, accepted: (0, 0.35)"), std::string::npos) << message;
  EXPECT_NE(message.find("proximity_iterations = 0, accepted: >= 1"), std::string::npos) << message;
  // Only the bad fields are named.
  EXPECT_EQ(message.find("d_min"), std::string::npos) << message;
  EXPECT_EQ(message.find("proximity_friction"), std::string::npos) << message;
  // NaN fails the range checks as before.
  SelfCollisionOptions nan_friction;
  nan_friction.proximity_friction = std::numeric_limits<Real>::quiet_NaN();
  EXPECT_THROW(validateSelfCollisionOptions(nan_friction), std::invalid_argument);
  EXPECT_NO_THROW(validateSelfCollisionOptions(SelfCollisionOptions{}));
  EXPECT_NO_THROW(validateSelfCollisionOptions(SelfCollisionOptions::thesisLiteral()));
}

// ---- obstacles ---------------------------------------------------------------------------------------

TEST(Obstacles, FloorProjectsRemovesNormalVelocityAndAppliesFriction) {
  ObstacleOptions o;
  o.contact_distance = 1e-3;
  o.friction = 0.5;
  ObstaclePass pass(std::vector<char>(3, 0), o);
  pass.addPlane(PlaneObstacle{Vec3::Zero(), Vec3(0, 0, 2), Vec3::Zero()});  // normal normalised
  VecX x_old(9), x(9), v(9);
  x_old << 0, 0, 0.1, 1, 0, 0.1, 2, 0, 0.1;
  x << 0, 0, -0.01, 1, 0, 0.0005, 2, 0, 0.05;  // below, within contact distance, free
  v << 2, 0, -2, 0.3, 0, -1, 0, 0, -1;
  const VecX v_in = v;
  EXPECT_EQ(pass.apply(x_old, x, v), 2);
  EXPECT_NEAR(x[2], 1e-3, 1e-15);
  EXPECT_NEAR(x[5], 1e-3, 1e-15);
  EXPECT_EQ(x[8], 0.05);
  EXPECT_EQ(v[2], 0);  // inward normal velocity removed
  EXPECT_NEAR(v[0], 2 - 0.5 * 2, 1e-15);  // Coulomb: |v_t| reduced by mu |v_n|
  EXPECT_NEAR(v[3], 0.0, 1e-15);          // ... but never reversed (0.3 - 0.5 < 0 -> 0)
  EXPECT_EQ(v.segment<3>(6), v_in.segment<3>(6));
  EXPECT_EQ(pass.countInside(x), 0);
}

TEST(Obstacles, TableBoxLeavesThroughTheEntryFace) {
  ObstaclePass pass(std::vector<char>(2, 0), ObstacleOptions{1e-3, 0.0});
  pass.addBox(BoxObstacle::axisAligned(Vec3(-0.25, -0.25, 0), Vec3(0.25, 0.25, 0.75)));
  VecX x_old(6), x(6), v(6);
  // Particle 0 fell into the table near its edge: nearer to the side face, but it entered from the
  // top, so it goes back onto the top. Particle 1 was inside already: nearest face (the side).
  x_old << 0.245, 0, 0.76, 0.24, 0.1, 0.5;
  x << 0.249, 0, 0.70, 0.24, 0.1, 0.5;
  v << 0.4, 0, -3, 0, 0, 0;
  EXPECT_EQ(pass.apply(x_old, x, v), 2);
  EXPECT_NEAR(x[2], 0.751, 1e-12);
  EXPECT_NEAR(x[0], 0.249, 1e-12);
  EXPECT_EQ(v[2], 0);
  EXPECT_EQ(v[0], 0.4);  // frictionless
  EXPECT_NEAR(x[3], 0.251, 1e-12);
  EXPECT_EQ(pass.countInside(x), 0);
}

TEST(Obstacles, SphereAndRotatedJaw) {
  ObstaclePass pass(std::vector<char>(2, 0), ObstacleOptions{0.0, 0.0});
  pass.addSphere(SphereObstacle{Vec3(0, 0, 0), 0.1, Vec3::Zero()});
  BoxObstacle jaw;
  jaw.centre = Vec3(1, 0, 0);
  jaw.half_extents = Vec3(0.1, 0.02, 0.05);
  jaw.rotation = Eigen::AngleAxis<Real>(kPi / 4, Vec3::UnitZ()).toRotationMatrix();
  jaw.velocity = Vec3(0, 0.5, 0);  // a closing jaw
  pass.addBox(jaw);
  VecX x_old(6), x(6), v(6);
  x_old << 0.3, 0, 0, 1, 0, 0.2;
  x << 0.05, 0, 0, 1.01, 0.005, 0;  // inside the sphere; inside the jaw
  v << -1, 0, 0, 0, 0, 0;
  EXPECT_EQ(pass.apply(x_old, x, v), 2);
  EXPECT_NEAR(node3(x, 0).norm(), 0.1, 1e-12);
  EXPECT_NEAR(v[0], 0, 1e-15);
  EXPECT_FALSE(jaw.contains(node3(x, 1), -1e-12));
  EXPECT_EQ(pass.countInside(x, 1e-12), 0);
  // The jaw entered from above (x_old above it): projected onto its top face.
  EXPECT_NEAR(x[5], 0.05, 1e-12);
  EXPECT_THROW(pass.addSphere(SphereObstacle{Vec3::Zero(), -1, Vec3::Zero()}), std::invalid_argument);
}

TEST(Obstacles, PinnedParticlesAreNeverMovedAndChainsSumEvents) {
  std::vector<char> pinned = {1, 0};
  ObstaclePass floor(pinned, ObstacleOptions{});
  floor.addPlane(PlaneObstacle{});
  VecX x_old(6), x(6), v(6);
  x_old << 0, 0, 0.1, 1, 0, 0.1;
  x << 0, 0, -0.1, 1, 0, -0.1;
  v << 0, 0, -1, 0, 0, -1;
  const VecX x_in = x, v_in = v;
  SelfCollisionPass self(ClothTriangles::fromTopology(topologyFromCells({{0, 0}, {0, 1}})), pinned);
  PostStepPassChain chain({&floor, &self});
  EXPECT_EQ(chain.apply(x_old, x, v), 1);
  EXPECT_EQ(x.head<3>(), x_in.head<3>());
  EXPECT_EQ(v.head<3>(), v_in.head<3>());
  EXPECT_GT(x[5], 0);
}

// ---- drape scenes -------------------------------------------------------------------------------------

// The thesis self-collision experiment (section 5.4.3): the 30x30 cm cotton square held at its centre.
DrapeSceneSpec squareSpec(Real spacing) {
  DrapeSceneSpec s;
  s.textile = presetTextile("square");
  s.spacing = spacing;
  s.hold = {HoldPoint{"centre", Vec2::Zero()}};
  s.hold_position = Vec3(0, 0, 1.0);
  s.model.set("settle_damping_per_s", 4.0);
  s.model.set("jacobian", "definite_fix");
  s.settings.integrator = IntegratorType::kSemiImplicitEuler;
  s.settings.policy = StepPolicy::kFixed;
  s.settings.dt = 1e-3;
  s.settings.max_time = 8.0;
  return s;
}

struct DrapeOutcome {
  RunResult result;
  VecX x;
  long pairs = 0;
  double seconds = 0;
};

DrapeOutcome runSquare(bool collisions, SelfCollisionStats* stats = nullptr) {
  // One thread: on these small meshes parallel regions cost more than they save (a lot more on a
  // busy machine); the results do not depend on the thread count (tested separately).
  ThreadGuard guard;
  setThreads(1);
  const DrapeSceneSpec spec = squareSpec(0.025);
  DrapeScene scene = buildDrapeScene(spec);
  const auto* pm = dynamic_cast<const ParticleClothModel*>(scene.model.get());
  const ClothTriangles tris = ClothTriangles::fromTopology(pm->topology());
  SelfCollisionPass pass(tris, pinnedMask(pm->numNodes(), scene.pins));
  // As a scene does (withContactForces): the contact forces of the proximity stage enter the solve.
  ContactForceModel model(*scene.model, pass);
  DrapeSimulation sim(collisions ? static_cast<ClothModel&>(model) : *scene.model, scene.pins, spec.settings, scene.x0,
                      scene.v0);
  if (collisions) sim.setPostStepPass(&pass);
  const auto t0 = std::chrono::steady_clock::now();
  DrapeOutcome out;
  out.result = sim.run();
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.x = sim.positions();
  out.pairs = countIntersectingTrianglePairs(tris, out.x);
  if (stats) *stats = pass.totalStats();
  std::printf("[ square 25 mm, %s ] %s t=%.2f s, %ld steps, %.2f s wall, %ld intersecting pairs, %ld events, "
              "%ld proximity contacts, collision %.0f ms of %.0f ms stepping\n",
              collisions ? "v3" : "no collision handling", out.result.rest_reached ? "rest" : "no rest",
              out.result.sim_time, out.result.steps, out.seconds, out.pairs, out.result.post_step_events,
              pass.totalStats().proximity_contacts, out.result.post_step_ms, out.result.step_ms);
  return out;
}

TEST(DrapeScenes, SquareHeldAtCentreSelfIntersectsWithoutHandling) {
  const DrapeOutcome off = runSquare(false);
  ASSERT_FALSE(off.result.diverged) << off.result.divergence_reason;
  EXPECT_TRUE(off.result.rest_reached);
  EXPECT_GT(off.pairs, 0);  // the thesis's observation: penetration without collision handling
}

TEST(DrapeScenes, SquareHeldAtCentreHangsToRestWithoutIntersectionsUnderV3) {
  SelfCollisionStats stats;
  const DrapeOutcome on = runSquare(true, &stats);
  ASSERT_FALSE(on.result.diverged) << on.result.divergence_reason;
  EXPECT_TRUE(on.result.rest_reached);
  EXPECT_EQ(on.pairs, 0);
  EXPECT_GT(on.result.post_step_events + stats.proximity_contacts, 0);  // the handling was at work
  EXPECT_EQ(stats.unresolved, 0);
  std::printf("[ square 25 mm, v3 ] thesis rollbacks %ld, fallback rollbacks %ld, passes %d, proximity contacts %ld\n",
              stats.thesis_events, stats.fallback_events, stats.passes, stats.proximity_contacts);
}

TEST(DrapeScenes, SquareRunIsIndependentOfTheThreadCount) {
  ThreadGuard guard;
  const DrapeSceneSpec base = squareSpec(0.03);
  std::vector<VecX> finals;
  for (int threads : {1, 3}) {
    setThreads(threads);
    DrapeSceneSpec spec = base;
    spec.settings.max_time = 0.8;
    spec.settings.dt = 2e-3;
    DrapeScene scene = buildDrapeScene(spec);
    const auto* pm = dynamic_cast<const ParticleClothModel*>(scene.model.get());
    SelfCollisionPass pass(ClothTriangles::fromTopology(pm->topology()), pinnedMask(pm->numNodes(), scene.pins));
    ContactForceModel model(*scene.model, pass);
    DrapeSimulation sim(model, scene.pins, spec.settings, scene.x0, scene.v0);
    sim.setPostStepPass(&pass);
    sim.run();
    finals.push_back(sim.positions());
  }
  EXPECT_TRUE(finals[0] == finals[1]);
}

// The thesis validation scene (section 5.4.1): the 100x100 cm tablecloth fixed on a 50x50 cm area, here
// with the table as a box obstacle just below the pinned region, plus v3.
TEST(DrapeScenes, TableclothOnATableStaysOutOfTheTable) {
  ThreadGuard guard;
  setThreads(1);  // see runSquare()
  DrapeSceneSpec spec;
  spec.textile = presetTextile("tablecloth");
  spec.spacing = 0.04;
  spec.pinned_regions = {Eigen::Matrix<Real, 4, 1>(0.25, 0.25, 0.75, 0.75)};
  spec.hold_position = Vec3(0, 0, 1.0);  // the region's centre
  spec.model.set("settle_damping_per_s", 4.0);
  spec.model.set("jacobian", "definite_fix");
  spec.settings.integrator = IntegratorType::kSemiImplicitEuler;
  spec.settings.policy = StepPolicy::kFixed;
  spec.settings.dt = 2e-3;
  spec.settings.max_time = 3.0;
  DrapeScene scene = buildDrapeScene(spec);
  const auto* pm = dynamic_cast<const ParticleClothModel*>(scene.model.get());
  const Index n = pm->numNodes();

  ObstaclePass table(n, scene.pins, ObstacleOptions{1e-3, 0.3});
  // Table top 2 mm below the pinned cloth; the table is as large as the pinned region.
  const BoxObstacle box = BoxObstacle::axisAligned(Vec3(-0.25, -0.25, 0.0), Vec3(0.25, 0.25, 0.998));
  table.addBox(box);
  SelfCollisionPass self(pm->topology(), scene.pins);
  PostStepPassChain chain({&table, &self});
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(&chain);
  const auto t0 = std::chrono::steady_clock::now();
  const RunResult r = sim.run();
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_FALSE(r.diverged) << r.divergence_reason;
  const VecX& x = sim.positions();
  long inside = 0;
  for (Index p = 0; p < n; ++p) inside += box.contains(node3(x, p), -1e-9) ? 1 : 0;
  EXPECT_EQ(inside, 0);
  EXPECT_EQ(table.countInside(x), 0);
  // The cloth does hang down over the table edges.
  Real lowest = 1.0;
  for (Index p = 0; p < n; ++p) lowest = std::min(lowest, x[3 * p + 2]);
  EXPECT_LT(lowest, 0.85);
  // Pinned particles never moved.
  for (size_t k = 0; k < scene.pins.nodes.size(); ++k)
    EXPECT_EQ(Vec3(node3(x, scene.pins.nodes[k])), scene.pins.anchors[k]);
  EXPECT_EQ(countIntersectingTrianglePairs(self.triangles(), x), 0);
  std::printf("[ tablecloth 40 mm on a table ] %s t=%.2f s, %ld steps, %.2f s wall, %ld events, lowest z %.3f m\n",
              r.rest_reached ? "rest" : "no rest", r.sim_time, r.steps, secs, r.post_step_events, lowest);
}


// ---- persistent contact: the proximity stage and the contact forces ---------------------------------

bool bitwiseEqual(const VecX& a, const VecX& b) {
  return a.size() == b.size() && std::equal(a.data(), a.data() + a.size(), b.data(), [](Real p, Real q) {
           return std::memcmp(&p, &q, sizeof(Real)) == 0;
         });
}

// A free 8x8 patch released 8 mm above a 12x12 sheet pinned along its border (d = 2 cm, so the
// thickness is 5 mm): the patch lands on the sheet and must stay there, on it, at rest.
struct PatchOnSheet {
  ParticleTopology topo;
  PinnedNodes pins;
  VecX x0;
  std::vector<Index> upper;  // the free patch
  Index lower_count = 0;
};

PatchOnSheet patchOnSheet() {
  constexpr int L = 12, U = 8;
  constexpr Real d = 0.02;
  auto cells = block(0, 0, L, L);
  const auto up = block(100, 0, U, U);
  cells.insert(cells.end(), up.begin(), up.end());
  PatchOnSheet s;
  s.topo = topologyFromCells(cells, d);
  s.lower_count = L * L;
  s.x0.resize(3 * static_cast<Index>(cells.size()));
  for (size_t k = 0; k < cells.size(); ++k) {
    const Index p = static_cast<Index>(k);
    const int i = cells[k][0], j = cells[k][1];
    if (p < s.lower_count) {
      node3(s.x0, p) = Vec3(j * d, i * d, 0.0);
      if (i == 0 || j == 0 || i == L - 1 || j == L - 1) {
        s.pins.nodes.push_back(p);
        s.pins.anchors.push_back(Vec3(j * d, i * d, 0.0));
      }
    } else {
      node3(s.x0, p) = Vec3((j + 2.5) * d, (i - 100 + 2.5) * d, 0.008);
      s.upper.push_back(p);
    }
  }
  return s;
}

SimulationSettings restSettings(Real max_time) {
  SimulationSettings st;
  st.integrator = IntegratorType::kSemiImplicitEuler;
  st.policy = StepPolicy::kErrorControlled;
  st.dt = 1e-3;
  st.dt_max = 0.0125;
  st.error_tolerance = 1e-3;
  st.max_time = max_time;
  return st;
}

ParticleModelOptions settleOptions() {
  ParticleModelOptions mo;
  mo.settle_damping = 4.0;
  mo.jacobian = JacobianMode::kDefiniteFix;
  return mo;
}

Real kinetic(const ClothModel& m, const VecX& v) { return 0.5 * v.cwiseProduct(v).dot(m.massPerDof()); }

TEST(PersistentContact, PatchRestsOnAPinnedSheetAsAFixedPoint) {
  ThreadGuard guard;
  setThreads(1);
  const PatchOnSheet s = patchOnSheet();
  ParticleClothModel base(s.topo, Material::cotton(), settleOptions());
  SelfCollisionPass pass(s.topo, s.pins);
  ContactForceModel model(base, pass);
  const SimulationSettings st = restSettings(6.0);
  DrapeSimulation sim(model, s.pins, st, s.x0, VecX::Zero(s.x0.size()));
  sim.setPostStepPass(&pass);
  // Energy is bounded: kinetic + potential energy never exceeds the initial total by more than
  // rounding (the contact handling is dissipative), checked along the way.
  const Real e0 = base.potentialEnergy(s.x0);
  Real e_max = e0, ke_max = 0;
  while (!sim.result().rest_reached && !sim.result().diverged && sim.time() < st.max_time - 1e-9) {
    sim.run(sim.time() + 0.05);
    const Real ke = kinetic(base, sim.velocities());
    ke_max = std::max(ke_max, ke);
    e_max = std::max(e_max, ke + base.potentialEnergy(sim.positions()));
  }
  const RunResult r = sim.result();
  ASSERT_FALSE(r.diverged) << r.divergence_reason;
  EXPECT_TRUE(r.rest_reached);
  EXPECT_LE(e_max, e0 + 1e-6 * std::abs(e0) + 1e-9);
  const VecX x_rest = sim.positions();
  EXPECT_EQ(countIntersectingTrianglePairs(pass.triangles(), x_rest), 0);
  // The patch lies on the sheet (it did not fall through): above the sheet's lowest point.
  Real sheet_low = 0;
  for (Index p = 0; p < s.lower_count; ++p) sheet_low = std::min(sheet_low, x_rest[3 * p + 2]);
  for (Index p : s.upper) EXPECT_GT(x_rest[3 * p + 2], sheet_low);
  const SelfCollisionStats at_rest = pass.totalStats();
  EXPECT_GT(at_rest.proximity_contacts, 0);
  // The rest state is a fixed point: 0.5 s more change nothing (no rollback, no movement), while the
  // contacts keep carrying the patch.
  DrapeSimulation more(model, s.pins, restSettings(sim.time() + 0.5), x_rest, sim.velocities());
  more.setPostStepPass(&pass);
  const RunResult r2 = more.run();
  EXPECT_FALSE(r2.diverged);
  EXPECT_EQ(r2.post_step_events, 0);
  EXPECT_GT(pass.totalStats().proximity_contacts, at_rest.proximity_contacts);
  EXPECT_LT((more.positions() - x_rest).cwiseAbs().maxCoeff(), 1e-4);
  EXPECT_EQ(countIntersectingTrianglePairs(pass.triangles(), more.positions()), 0);
  std::printf("[ patch on a pinned sheet ] rest t=%.2f s, %ld steps, %ld rollbacks, %ld proximity contacts, max "
              "kinetic energy %.2e J; 0.5 s more: max displacement %.1e m\n",
              r.sim_time, r.steps, r.post_step_events, at_rest.proximity_contacts, ke_max,
              (more.positions() - x_rest).cwiseAbs().maxCoeff());
}

TEST(PersistentContact, ContactForcesSurviveSaveAndResume) {
  ThreadGuard guard;
  setThreads(1);
  const PatchOnSheet s = patchOnSheet();
  const std::string path = ::testing::TempDir() + "collision_contact_resume.txt";
  const SimulationSettings st = restSettings(10.0);
  ParticleClothModel base_a(s.topo, Material::cotton(), settleOptions());
  SelfCollisionPass pass_a(s.topo, s.pins);
  ContactForceModel model_a(base_a, pass_a);
  DrapeSimulation a(model_a, s.pins, st, s.x0, VecX::Zero(s.x0.size()));
  a.setPostStepPass(&pass_a);
  a.run(0.3);
  ASSERT_GT(pass_a.contactAccelerations().size(), 0);  // contacts carry the patch at the save
  a.save(path);
  a.run(0.6);
  ParticleClothModel base_b(s.topo, Material::cotton(), settleOptions());
  SelfCollisionPass pass_b(s.topo, s.pins);
  ContactForceModel model_b(base_b, pass_b);
  DrapeSimulation b(model_b, s.pins, st, s.x0, VecX::Zero(s.x0.size()));
  b.setPostStepPass(&pass_b);
  b.load(path);
  b.run(0.6);
  std::remove(path.c_str());
  EXPECT_TRUE(bitwiseEqual(a.positions(), b.positions()))
      << "max difference " << (a.positions() - b.positions()).cwiseAbs().maxCoeff();
  EXPECT_TRUE(bitwiseEqual(a.velocities(), b.velocities()));
  EXPECT_EQ(a.result().steps, b.result().steps);
  // A malformed contact state is rejected.
  std::vector<Real> bad = model_b.internalState();
  bad.back() += 1;
  EXPECT_FALSE(model_b.setInternalState(bad));
}

// The README's demo scene at half the resolution: the towel held at a corner reaches rest without
// intersections under v3 (it used to be pumped by rollbacks in persistent contact and never rested).
TEST(PersistentContact, TowelHeldAtACornerRestsWithoutIntersectionsAtTwoCentimetres) {
  ThreadGuard guard;
  setThreads(1);
  const DrapeSceneSpec spec = parseDrapeSceneYaml(R"(
textile: towel
material: cotton
spacing_m: 0.02
hold:
  points: [corner_ul]
  position: [0.0, 0.0, 1.0]
model:
  name: particle_kes
  jacobian: definite_fix
  settle_damping_per_s: 4.0
simulation:
  integrator: semi_implicit
  policy: error
  dt_s: 0.001
  dt_max_s: 0.0125
  error_tolerance_m: 0.001
  max_time_s: 10.0
  linear_solver: cg
  preconditioner: two_level
  cg_tolerance: 0.03
  cg_warm_start: true
collision:
  self: v3
)");
  DrapeScene scene = buildDrapeScene(spec);
  ASSERT_TRUE(scene.self_collision_pass);
  SelfCollisionPass& pass = *scene.self_collision_pass;
  scene.model = withContactForces(std::move(scene.model), pass);  // idempotent
  ASSERT_TRUE(dynamic_cast<ContactForceModel*>(scene.model.get()));
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  const RunResult r = sim.run();
  ASSERT_FALSE(r.diverged) << r.divergence_reason;
  EXPECT_TRUE(r.rest_reached);
  EXPECT_EQ(countIntersectingTrianglePairs(scene.triangles(), sim.positions()), 0);
  const SelfCollisionStats& t = pass.totalStats();
  EXPECT_EQ(t.unresolved, 0);
  EXPECT_GT(t.proximity_contacts, 0);
  std::printf("[ towel 20 mm, corner, v3 ] %s t=%.2f s, %ld steps (%ld rejected), %ld rollbacks, %ld proximity "
              "contacts, collision %.2f ms/step, assembly %.2f ms/step\n",
              r.rest_reached ? "rest" : "no rest", r.sim_time, r.steps, r.rejected_steps, r.post_step_events,
              t.proximity_contacts, r.post_step_ms / std::max<long>(r.steps, 1),
              r.assembly_ms / std::max<long>(r.steps, 1));
}

// Two 40x40 sheets 3 mm apart (d = 1 cm, thickness 2.5 mm), one step that brings them together:
// more than 2048 triangles, so that the parallel loops run. The result does not depend on the
// thread count, nothing crosses, and pinned particles are neither moved nor slowed.
struct TwoSheets {
  ParticleTopology topo;
  std::vector<char> pinned;
  PinnedNodes pins;
  VecX x_old, x, v;
};

TwoSheets twoSheets() {
  constexpr int N = 40;
  constexpr Real d = 0.01, h = 0.01;
  auto cells = block(0, 0, N, N);
  const auto b = block(100, 0, N, N);
  cells.insert(cells.end(), b.begin(), b.end());
  TwoSheets s;
  s.topo = topologyFromCells(cells, d);
  const Index n = static_cast<Index>(cells.size());
  s.pinned.assign(static_cast<size_t>(n), 0);
  s.x_old.resize(3 * n);
  std::mt19937 rng(5);
  std::normal_distribution<Real> noise(0, 4e-4);
  s.x = s.x_old;
  for (Index p = 0; p < n; ++p) {
    const int i = cells[static_cast<size_t>(p)][0], j = cells[static_cast<size_t>(p)][1];
    const bool top = i >= 100;
    node3(s.x_old, p) = top ? Vec3((j + 0.5) * d, (i - 100 + 0.5) * d, 0.003) : Vec3(j * d, i * d, 0.0);
    Vec3 step(noise(rng), noise(rng), noise(rng));
    if (top) step.z() -= 0.002;
    if (!top && p % 7 == 0) {  // pinned: moves by prescription
      s.pinned[static_cast<size_t>(p)] = 1;
      s.pins.nodes.push_back(p);
      s.pins.anchors.push_back(node3(s.x_old, p));
    }
    node3(s.x, p) = node3(s.x_old, p) + step;
  }
  s.v = (s.x - s.x_old) / h;
  return s;
}

TEST(PersistentContact, ProximityStageIsThreadIndependentAndLeavesPinnedParticles) {
  ThreadGuard guard;
  const TwoSheets s = twoSheets();
  ASSERT_GT(ClothTriangles::fromTopology(s.topo).numTriangles(), 2 * 2048);
  std::vector<VecX> xs, vs, as;
  for (int threads : {1, 2, 4}) {
    setThreads(threads);
    ParticleClothModel base(s.topo, Material::cotton(), settleOptions());
    SelfCollisionPass pass(s.topo, s.pins);
    ContactForceModel model(base, pass);  // contact forces on: their memory is part of the result
    VecX x = s.x, v = s.v;
    pass.apply(s.x_old, x, v);
    const SelfCollisionStats& st = pass.lastStats();
    EXPECT_GT(st.proximity_contacts, 100);
    EXPECT_EQ(st.unresolved, 0);
    EXPECT_EQ(countIntersectingTrianglePairs(pass.triangles(), x), 0);
    for (Index p = 0; p < static_cast<Index>(s.pinned.size()); ++p)
      if (s.pinned[static_cast<size_t>(p)]) {
        EXPECT_EQ(Vec3(node3(x, p)), Vec3(node3(s.x, p)));
        EXPECT_EQ(Vec3(node3(v, p)), Vec3(node3(s.v, p)));
      }
    // Pinned particles take no contact force.
    const VecX& a = pass.contactAccelerations();
    ASSERT_EQ(a.size(), s.x.size());
    for (Index p = 0; p < base.numNodes(); ++p) {
      if (s.pinned[static_cast<size_t>(p)]) {
        EXPECT_EQ(Vec3(node3(a, p)), Vec3::Zero());
      }
    }
    xs.push_back(x);
    vs.push_back(v);
    as.push_back(a);
  }
  for (size_t k = 1; k < xs.size(); ++k) {
    EXPECT_TRUE(bitwiseEqual(xs[k], xs[0]));
    EXPECT_TRUE(bitwiseEqual(vs[k], vs[0]));
    EXPECT_TRUE(bitwiseEqual(as[k], as[0]));
  }
  // Without pins the corrections and the contact forces conserve momentum.
  setThreads(1);
  ParticleClothModel base(s.topo, Material::cotton(), settleOptions());
  SelfCollisionPass pass(s.topo, PinnedNodes{});
  ContactForceModel model(base, pass);
  VecX x = s.x, v = s.v;
  pass.apply(s.x_old, x, v);
  const VecX& m = base.massPerDof();
  const VecX& a = pass.contactAccelerations();
  ASSERT_EQ(a.size(), s.x.size());
  Vec3 p_force = Vec3::Zero(), p_move = Vec3::Zero(), p_vel = Vec3::Zero();
  Real scale = 0;
  for (Index p = 0; p < base.numNodes(); ++p) {
    p_force += m[3 * p] * Vec3(node3(a, p));
    p_move += m[3 * p] * Vec3(node3(x, p) - node3(s.x, p));
    p_vel += m[3 * p] * Vec3(node3(v, p) - node3(s.v, p));
    scale += m[3 * p] * Vec3(node3(a, p)).norm();
  }
  EXPECT_GT(scale, 0);
  EXPECT_LT(p_force.norm(), 1e-12 * scale);
  EXPECT_LT(p_move.norm(), 1e-15);
  EXPECT_LT(p_vel.norm(), 1e-13);
}

TEST(PersistentContact, OptionsAndTheContactForceModel) {
  EXPECT_FALSE(SelfCollisionOptions::thesisLiteral().proximity);
  const PatchOnSheet s = patchOnSheet();
  SelfCollisionOptions bad;
  bad.thickness_factor = 0.4;  // the candidate lists would reach non-adjacent neighbours of a flat sheet
  EXPECT_THROW(SelfCollisionPass(s.topo, s.pins, bad), std::invalid_argument);
  bad = SelfCollisionOptions{};
  bad.proximity_iterations = 0;
  EXPECT_THROW(SelfCollisionPass(s.topo, s.pins, bad), std::invalid_argument);
  // withContactForces wraps only for v3 with the proximity stage and contact forces, and once.
  SelfCollisionOptions off;
  off.contact_forces = false;
  SelfCollisionPass pass_off(s.topo, s.pins, off);
  auto m0 = withContactForces(std::make_unique<ParticleClothModel>(s.topo, Material::cotton()), pass_off);
  EXPECT_FALSE(dynamic_cast<ContactForceModel*>(m0.get()));
  SelfCollisionPass pass(s.topo, s.pins);
  auto m1 = withContactForces(std::make_unique<ParticleClothModel>(s.topo, Material::cotton()), pass);
  ASSERT_TRUE(dynamic_cast<ContactForceModel*>(m1.get()));
  ClothModel* before = m1.get();
  m1 = withContactForces(std::move(m1), pass);
  EXPECT_EQ(m1.get(), before);
  // Without contacts the wrapper is transparent: same forces, energy and state as the bare model.
  ParticleClothModel bare(s.topo, Material::cotton());
  VecX f_bare(s.x0.size()), f_wrap(s.x0.size());
  const VecX v0 = VecX::Zero(s.x0.size());
  bare.computeForces(s.x0, v0, f_bare, nullptr);
  m1->computeForces(s.x0, v0, f_wrap, nullptr);
  EXPECT_TRUE(bitwiseEqual(f_bare, f_wrap));
  EXPECT_EQ(m1->potentialEnergy(s.x0), bare.potentialEnergy(s.x0));
  EXPECT_EQ(m1->name(), bare.name());
  EXPECT_TRUE(m1->setInternalState(m1->internalState()));
}

// ---- broad phase: Verlet lists kept under rigid motion ----------------------------------------------

// A lower 20x20 sheet at z = 0, an upper 20x20 sheet 4 mm above it (offset by half a cell) and a
// small 6x6 sheet 30 mm above (d = 1 cm, thickness T = 2.5 mm). Every step moves the whole scene by
// a large rigid motion (0.25 rad about a tilted axis, 4 cm), the upper sheet approaches the lower by
// 0.25 mm (contacts after a few steps) and every particle gets 0.02 mm of noise; in the last step
// half of the small sheet drops by 45 mm, so that its edges cut through both sheets (a crossing far
// faster than any list margin).
// The pass that keeps its lists (rigid-motion compensated validity) must give bitwise the results of
// a pass that rebuilds them every step, while building them far less often.
TEST(BroadPhase, ListsKeptUnderRigidMotionGiveTheResultsOfRebuildingEveryStep) {
  ThreadGuard guard;
  setThreads(2);
  constexpr Real d = 0.01, h = 0.01;
  auto cells = block(0, 0, 20, 20);
  const auto upper = block(100, 0, 20, 20), small = block(200, 0, 6, 6);
  cells.insert(cells.end(), upper.begin(), upper.end());
  cells.insert(cells.end(), small.begin(), small.end());
  const ParticleTopology topo = topologyFromCells(cells, d);
  const Index n = static_cast<Index>(cells.size());
  std::vector<int> layer(static_cast<size_t>(n));
  VecX x0(3 * n);
  for (Index p = 0; p < n; ++p) {
    const int i = cells[static_cast<size_t>(p)][0], j = cells[static_cast<size_t>(p)][1];
    layer[static_cast<size_t>(p)] = i >= 200 ? 2 : (i >= 100 ? 1 : 0);
    if (i >= 200) node3(x0, p) = Vec3((j + 7) * d, (i - 200 + 7) * d, 0.03);
    else if (i >= 100) node3(x0, p) = Vec3((j + 0.5) * d, (i - 100 + 0.5) * d, 0.004);
    else node3(x0, p) = Vec3(j * d, i * d, 0.0);
  }
  SelfCollisionPass kept(topo, PinnedNodes{}), fresh(topo, PinnedNodes{});
  ASSERT_EQ(countIntersectingTrianglePairs(kept.triangles(), x0), 0);
  VecX xa = x0, va = VecX::Zero(3 * n), xb = x0, vb = va;
  std::mt19937 rng(11);
  std::normal_distribution<Real> noise(0, 2e-5);
  const Mat3 rot = Eigen::AngleAxis<Real>(0.25, Vec3(1, 2, 3).normalized()).toRotationMatrix();
  const Vec3 shift(0.04, -0.01, 0.02);
  Mat3 frame = Mat3::Identity();  // orientation of the scene: its sheets' normal is frame * e_z
  constexpr int kSteps = 14;
  long events = 0, contacts = 0;
  for (int k = 0; k < kSteps; ++k) {
    const bool drop = k == kSteps - 1;
    frame = rot * frame;
    Vec3 c = Vec3::Zero();
    for (Index p = 0; p < n; ++p) c += Vec3(node3(xa, p));
    c /= static_cast<Real>(n);
    VecX x_pred(3 * n);
    for (Index p = 0; p < n; ++p) {
      const int l = layer[static_cast<size_t>(p)];
      const bool falls = l == 2 && drop && cells[static_cast<size_t>(p)][0] >= 203;  // half of the small sheet
      const Real dz = l == 1 ? -2.5e-4 : (falls ? -0.045 : 0.0);
      node3(x_pred, p) = c + rot * (Vec3(node3(xa, p)) - c) + shift + frame * Vec3(0, 0, dz) +
                         Vec3(noise(rng), noise(rng), noise(rng));
    }
    const VecX x_old_a = xa, x_old_b = xb;
    xa = x_pred;
    va = (x_pred - x_old_a) / h;
    xb = x_pred;
    vb = (x_pred - x_old_b) / h;
    kept.apply(x_old_a, xa, va);
    fresh.setOptions(fresh.options());  // forgets the lists: rebuilt in this step
    fresh.apply(x_old_b, xb, vb);
    ASSERT_TRUE(bitwiseEqual(xa, xb)) << "step " << k;
    ASSERT_TRUE(bitwiseEqual(va, vb)) << "step " << k;
    EXPECT_EQ(kept.lastStats().unresolved, 0);
    EXPECT_EQ(countIntersectingTrianglePairs(kept.triangles(), xa), 0) << "step " << k;
    EXPECT_EQ(fresh.lastStats().candidate_list_builds, 1);
    EXPECT_EQ(fresh.lastStats().proximity_list_builds, 1);
    contacts += kept.lastStats().proximity_contacts;
    if (!drop) events += kept.lastStats().events;
    if (drop) {
      // The fast crossing: the lists had to be rebuilt, and the rollback caught it.
      EXPECT_EQ(kept.lastStats().candidate_list_builds, 1);
      EXPECT_GT(kept.lastStats().events, 0);
    }
  }
  EXPECT_GT(contacts, 0);  // the sheets did touch
  EXPECT_EQ(events, 0);    // and the proximity stage kept them apart
  // Kept lists: built only a few times, although every particle moved by several centimetres per
  // step.
  EXPECT_LE(kept.totalStats().candidate_list_builds, kSteps / 2);
  EXPECT_LE(kept.totalStats().proximity_list_builds, kSteps / 2);
  EXPECT_EQ(fresh.totalStats().candidate_list_builds, kSteps);
  std::printf("[ kept lists ] %ld candidate and %ld proximity list builds in %d steps, %ld contacts\n",
              kept.totalStats().candidate_list_builds, kept.totalStats().proximity_list_builds, kSteps, contacts);
}

}  // namespace
}  // namespace textile_handling
