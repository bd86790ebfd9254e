// Tests for the size limits of textile outlines, the name rule, and the sweep-line crossing check
// against the brute-force reference.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {
namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

// A star-shaped (hence simple) polygon: n vertices at increasing angles with random radii.
std::vector<Vec2> randomStarPolygon(std::mt19937& rng, int n) {
  std::uniform_real_distribution<Real> radius(0.3, 1.0);
  std::vector<Vec2> v;
  for (int i = 0; i < n; ++i) {
    const Real a = 2 * M_PI * i / n;
    const Real r = radius(rng);
    v.emplace_back(r * std::cos(a), r * std::sin(a));
  }
  return v;
}

// Random vertices: mostly self-intersecting for n >= 5.
std::vector<Vec2> randomLoop(std::mt19937& rng, int n) {
  std::uniform_int_distribution<int> coordinate(0, 6);  // a coarse lattice: touching and overlaps are common
  std::vector<Vec2> v;
  for (int i = 0; i < n; ++i) v.emplace_back(0.1 * coordinate(rng), 0.1 * coordinate(rng));
  return v;
}

// The circle polygon of n vertices and radius r.
std::vector<Vec2> circle(int n, Real r) {
  std::vector<Vec2> v;
  for (int i = 0; i < n; ++i) v.emplace_back(r * std::cos(2 * M_PI * i / n), r * std::sin(2 * M_PI * i / n));
  return v;
}

TEST(EdgeCrossing, SweepAgreesWithBruteForceOnRandomPolygons) {
  std::mt19937 rng(12345);
  int simple = 0, crossing = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    const int n = 3 + trial % 40;
    const std::vector<Vec2> v = trial % 3 == 0 ? randomStarPolygon(rng, n) : randomLoop(rng, n);
    std::size_t a1 = 0, a2 = 0, b1 = 0, b2 = 0;
    const bool sweep = findEdgeCrossing(v, &a1, &a2);
    const bool brute = findEdgeCrossingBruteForce(v, &b1, &b2);
    ASSERT_EQ(sweep, brute) << "trial " << trial;
    if (brute) {
      // The same (lowest) pair, so the error message does not depend on the algorithm.
      EXPECT_EQ(a1, b1) << "trial " << trial;
      EXPECT_EQ(a2, b2) << "trial " << trial;
      ++crossing;
    } else {
      ++simple;
    }
  }
  // Both kinds were exercised.
  EXPECT_GT(simple, 500);
  EXPECT_GT(crossing, 500);
}

TEST(EdgeCrossing, FindsTheCrossingOfALargeOutline) {
  std::vector<Vec2> v = circle(static_cast<int>(kMaxOutlineVertices), 0.5);
  std::size_t i = 0, k = 0;
  EXPECT_FALSE(findEdgeCrossing(v, &i, &k));
  // Pull one vertex across the circle: its two edges cross many others.
  v[100] = Vec2(-0.6, 0.01);
  ASSERT_TRUE(findEdgeCrossing(v, &i, &k));
  std::size_t bi = 0, bk = 0;
  ASSERT_TRUE(findEdgeCrossingBruteForce(v, &bi, &bk));
  EXPECT_EQ(i, bi);
  EXPECT_EQ(k, bk);
}

TEST(Rasterisation, RowWiseClassificationMatchesPointInPolygonExactly) {
  // Rasterisation tests only the edges near each row; every node must still get pointInPolygon()'s
  // answer, including nodes on the boundary (axis-aligned outlines put whole rows on edges).
  std::mt19937 rng(777);
  std::vector<TextileOutline> shapes;
  for (int trial = 0; trial < 40; ++trial) {
    TextileOutline t;
    t.name = "star";
    for (const Vec2& v : randomStarPolygon(rng, 5 + trial * 7)) t.outline.push_back(Vec2(0.5, 0.5) + 0.4 * v);
    shapes.push_back(t);
  }
  for (const std::string& name : presetTextileNames()) shapes.push_back(presetTextile(name));
  for (const TextileOutline& t : shapes) {
    for (const Real d : {0.05, 0.02, 0.0123}) {
      std::string error;
      const ParticleGrid grid = ParticleGrid::rasterize(t, d, &error);
      ASSERT_FALSE(grid.empty()) << error;
      const int first = t.mirrored ? static_cast<int>(grid.cols() / 2) : 0;  // mirrored: the other half is copied
      for (Index i = 0; i < grid.rows(); ++i)
        for (Index j = first; j < grid.cols(); ++j)
          ASSERT_EQ(grid.active(i, j), pointInPolygon(grid.polygon(), grid.node(i, j), 1e-9 * d))
              << t.name << " d=" << d << " node " << i << "," << j;
    }
  }
}

TEST(OutlineLimits, AnOutlineAtTheLimitIsValid) {
  TextileOutline t;
  t.name = "round_cloth";
  t.outline = circle(static_cast<int>(kMaxOutlineVertices), 0.5);
  std::string error;
  EXPECT_TRUE(validateTextileOutline(t, &error)) << error;
  std::vector<Vec2> full;
  EXPECT_TRUE(buildFullOutline(t, &full, &error)) << error;
}

TEST(OutlineLimits, HundredThousandVerticesAreRefusedNamingTheLimit) {
  TextileOutline t;
  t.name = "huge";
  t.outline = circle(100000, 0.5);
  std::string error;
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "100000 vertices")) << error;
  EXPECT_TRUE(contains(error, "limit of " + std::to_string(kMaxOutlineVertices))) << error;
  EXPECT_FALSE(buildFullOutline(t, nullptr, &error));
  EXPECT_TRUE(contains(error, "limit of " + std::to_string(kMaxOutlineVertices))) << error;
  EXPECT_FALSE(validatePolygon(t.outline, &error));
  EXPECT_TRUE(contains(error, "limit of " + std::to_string(kMaxPolygonVertices))) << error;
  EXPECT_TRUE(ParticleGrid::rasterize(t, 0.01, &error).empty());
  EXPECT_TRUE(contains(error, "limit of")) << error;
}

TEST(OutlineLimits, OneVertexOverTheLimitIsRefused) {
  TextileOutline t;
  t.name = "over";
  t.outline = circle(static_cast<int>(kMaxOutlineVertices) + 1, 0.5);
  std::string error;
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "limit of")) << error;
}

TEST(OutlineLimits, HundredThousandNamedPointsAreRefusedNamingTheLimit) {
  TextileOutline t = presetTextile("square");
  t.named_points.clear();
  for (int i = 0; i < 100000; ++i) {
    NamedPoint p;
    p.name = "p" + std::to_string(i);
    p.kind = "grasp";
    p.position = Vec2(0.15, 0.15);
    t.named_points.push_back(p);
  }
  std::string error;
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "100000 named points")) << error;
  EXPECT_TRUE(contains(error, "limit of " + std::to_string(kMaxNamedPoints))) << error;
  t.named_points.resize(kMaxNamedPoints);
  EXPECT_TRUE(validateTextileOutline(t, &error)) << error;
}

TEST(TextileName, FollowsTheRule) {
  std::string error = "stale";
  for (const std::string& ok : std::vector<std::string>{"towel", "T-shirt_2.v1", "a", std::string(kMaxTextileNameLength, 'x')}) {
    EXPECT_TRUE(validateTextileName(ok, &error)) << ok << ": " << error;
    EXPECT_TRUE(error.empty());
  }
  EXPECT_FALSE(validateTextileName("", &error));
  EXPECT_TRUE(contains(error, "empty")) << error;
  EXPECT_FALSE(validateTextileName(std::string(kMaxTextileNameLength + 1, 'x'), &error));
  EXPECT_TRUE(contains(error, "limit of 64")) << error;
  for (const std::string bad : {"x'); DROP TABLE grasp_points;--", "two words", "a/b", "tab\tname", "ü", "../x"}) {
    EXPECT_FALSE(validateTextileName(bad, &error)) << bad;
    EXPECT_TRUE(contains(error, "letters, digits")) << error;
  }
  // A hostile name is quoted only up to the limit.
  EXPECT_FALSE(validateTextileName(std::string(100000, '\''), &error));
  EXPECT_LT(error.size(), 300u);
}

TEST(TextileName, OutlineValidationChecksTextileAndPointNames) {
  TextileOutline t = presetTextile("square");
  std::string error;
  t.name = "bad name";
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "bad name")) << error;
  t.name = "";  // an unnamed outline is allowed (e.g. a preview)
  EXPECT_TRUE(validateTextileOutline(t, &error)) << error;
  t.name = "square";
  t.named_points[0].name = "x'); DROP TABLE grasp_points;--";
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "named point 0")) << error;
  EXPECT_TRUE(contains(error, "letters, digits")) << error;
  t.named_points[0].name = t.named_points[1].name;
  EXPECT_FALSE(validateTextileOutline(t, &error));
  EXPECT_TRUE(contains(error, "defined twice")) << error;
}

TEST(TextileName, EveryPresetStillValidates) {
  for (const std::string& name : presetTextileNames()) {
    std::string error;
    EXPECT_TRUE(validateTextileOutline(presetTextile(name), &error)) << name << ": " << error;
  }
}

}  // namespace
}  // namespace textile_handling
