// Tests for textile outlines, polygon validation, rasterisation and hold points.
#include "textile_handling/sim/textile_geometry.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

namespace textile_handling {
namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TextileOutline plainOutline(const std::string& name, const std::vector<Vec2>& vertices) {
  TextileOutline t;
  t.name = name;
  t.outline = vertices;
  return t;
}

// L shape 0.2 x 0.2 m with the 0.1 x 0.1 m upper-right quadrant cut away.
TextileOutline lShape() {
  return plainOutline("L", {Vec2(0, 0), Vec2(0.2, 0), Vec2(0.2, 0.1), Vec2(0.1, 0.1), Vec2(0.1, 0.2), Vec2(0, 0.2)});
}

// ---------------------------------------------------------------- validation

TEST(ValidatePolygon, AcceptsSimplePolygonsOfEitherOrientation) {
  std::string error = "stale";
  EXPECT_TRUE(validatePolygon({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1)}, &error));
  EXPECT_TRUE(error.empty());
  EXPECT_TRUE(validatePolygon({Vec2(0, 0), Vec2(0, 1), Vec2(1, 0)}, &error));  // clockwise
  EXPECT_TRUE(validatePolygon(lShape().outline, &error)) << error;
  const Polygon2 towel{presetTextile("towel").outline};
  EXPECT_TRUE(validatePolygon(towel.vertices, nullptr));
}

TEST(ValidatePolygon, RejectsTwoVertices) {
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 0)}, &error));
  EXPECT_TRUE(contains(error, "2 vertices")) << error;
  EXPECT_TRUE(contains(error, "at least 3")) << error;
  EXPECT_FALSE(validatePolygon({}, nullptr));  // a null error pointer is allowed
}

TEST(ValidatePolygon, RejectsNonFiniteVertex) {
  const Real nan = std::numeric_limits<Real>::quiet_NaN();
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(nan, 0), Vec2(1, 1)}, &error));
  EXPECT_TRUE(contains(error, "vertex 1 is not finite")) << error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 0), Vec2(1, std::numeric_limits<Real>::infinity())}, &error));
  EXPECT_TRUE(contains(error, "vertex 2 is not finite")) << error;
}

TEST(ValidatePolygon, RejectsRepeatedConsecutiveVertices) {
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 0), Vec2(1, 0), Vec2(0, 1)}, &error));
  EXPECT_TRUE(contains(error, "vertices 1 and 2 coincide")) << error;
  // Explicitly closed loops repeat the first vertex at the end.
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 0), Vec2(0, 1), Vec2(0, 0)}, &error));
  EXPECT_TRUE(contains(error, "vertices 3 and 0 coincide")) << error;
}

TEST(ValidatePolygon, RejectsCollinearDegeneratePolygon) {
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 0), Vec2(2, 0)}, &error));
  EXPECT_TRUE(contains(error, "collinear")) << error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 1), Vec2(3, 3), Vec2(2, 2)}, &error));
  EXPECT_TRUE(contains(error, "collinear")) << error;
}

TEST(ValidatePolygon, RejectsSelfIntersectingBowTie) {
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)}, &error));
  EXPECT_TRUE(contains(error, "polygon edge 0-1 crosses edge 2-3")) << error;
}

TEST(ValidatePolygon, RejectsTouchingAndOverlappingEdges) {
  std::string error;
  // Vertex 3 touches edge 0-1 from above: a pinched outline.
  EXPECT_FALSE(
      validatePolygon({Vec2(0, 0), Vec2(2, 0), Vec2(2, 1), Vec2(1, 0), Vec2(0, 1)}, &error));
  EXPECT_TRUE(contains(error, "crosses")) << error;
  // Non-adjacent edges 0-1 and 4-5 overlap collinearly along y = 0.
  EXPECT_FALSE(validatePolygon(
      {Vec2(0, 0), Vec2(3, 0), Vec2(3, 1), Vec2(2, 1), Vec2(2, 0), Vec2(1, 0), Vec2(1, 2), Vec2(0, 2)}, &error));
  EXPECT_TRUE(contains(error, "crosses")) << error;
  // Adjacent edges that double back (a spike).
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(2, 0), Vec2(1, 0), Vec2(1, 1)}, &error));
  EXPECT_TRUE(contains(error, "overlap")) << error;
}

TEST(ValidatePolygon, RejectsTinyArea) {
  std::string error;
  EXPECT_FALSE(validatePolygon({Vec2(0, 0), Vec2(1e-6, 0), Vec2(0, 1e-6)}, &error));
  EXPECT_TRUE(contains(error, "area")) << error;
}

// ------------------------------------------------------------- full outline

TEST(FullOutline, UnmirroredIsTheOutlineItself) {
  const TextileOutline towel = presetTextile("towel");
  const std::vector<Vec2> full = fullOutline(towel);
  ASSERT_EQ(full.size(), towel.outline.size());
  for (std::size_t i = 0; i < full.size(); ++i) EXPECT_EQ(full[i], towel.outline[i]);
}

TEST(FullOutline, MirroredTshirtIsSymmetricAndDoublesTheArea) {
  const TextileOutline shirt = presetTextile("tshirt");
  const std::vector<Vec2> full = fullOutline(shirt);
  ASSERT_EQ(full.size(), 2 * shirt.outline.size() - 2);
  EXPECT_NEAR(polygonSignedArea(full), 2 * polygonSignedArea(shirt.outline), 1e-12);
  EXPECT_GT(polygonSignedArea(full), 0);  // orientation of the half is kept
  for (const Vec2& v : full) {
    const Vec2 reflected(2 * shirt.mirror_x - v.x(), v.y());
    bool found = false;
    for (const Vec2& w : full) found = found || (w - reflected).norm() < 1e-12;
    EXPECT_TRUE(found) << "no mirror image of (" << v.x() << ", " << v.y() << ")";
  }
  std::string error;
  EXPECT_TRUE(validatePolygon(full, &error)) << error;
}

TEST(FullOutline, MirroredHalfWithOffsetAxis) {
  TextileOutline half = plainOutline("half", {Vec2(0.3, 0), Vec2(0.5, 0), Vec2(0.5, 0.2), Vec2(0.3, 0.2)});
  half.mirrored = true;
  half.mirror_x = 0.3;
  const std::vector<Vec2> full = fullOutline(half);
  ASSERT_EQ(full.size(), 6u);  // axis vertices stay (collinear, but harmless)
  EXPECT_NEAR(std::abs(polygonSignedArea(full)), 0.4 * 0.2, 1e-12);
  EXPECT_NEAR(full[4].x(), 0.1, 1e-12);
}

TEST(FullOutline, MirroredErrorsAreClear) {
  TextileOutline shirt = presetTextile("tshirt");
  shirt.outline.front().x() = 0.01;  // first vertex off the axis
  try {
    fullOutline(shirt);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_TRUE(contains(e.what(), "must start and end on the mirror axis")) << e.what();
    EXPECT_TRUE(contains(e.what(), "tshirt")) << e.what();
  }

  TextileOutline wrong_side = plainOutline("w", {Vec2(0, 0), Vec2(-0.1, 0.1), Vec2(0, 0.2)});
  wrong_side.mirrored = true;
  std::string error;
  EXPECT_FALSE(buildFullOutline(wrong_side, nullptr, &error));
  EXPECT_TRUE(contains(error, "wrong side of the mirror axis")) << error;

  TextileOutline interior_on_axis =
      plainOutline("a", {Vec2(0, 0), Vec2(0.1, 0), Vec2(0, 0.1), Vec2(0.1, 0.2), Vec2(0, 0.2)});
  interior_on_axis.mirrored = true;
  EXPECT_FALSE(buildFullOutline(interior_on_axis, nullptr, &error));
  EXPECT_TRUE(contains(error, "vertex 2")) << error;
  EXPECT_TRUE(contains(error, "only the first and last")) << error;

  TextileOutline bad_plain = plainOutline("bow", {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)});
  EXPECT_THROW(fullOutline(bad_plain), std::invalid_argument);
}

// ------------------------------------------------------------------ presets

TEST(Presets, NamesAreKnownAndValid) {
  const std::vector<std::string> names = presetTextileNames();
  EXPECT_EQ(names, (std::vector<std::string>{"towel", "square", "tablecloth", "tshirt"}));
  for (const std::string& name : names) {
    const TextileOutline t = presetTextile(name);
    EXPECT_EQ(t.name, name);
    std::string error;
    EXPECT_TRUE(validateTextileOutline(t, &error)) << name << ": " << error;
    EXPECT_FALSE(t.named_points.empty());
  }
}

TEST(Presets, UnknownNameListsKnownNames) {
  try {
    presetTextile("sock");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_TRUE(contains(what, "sock")) << what;
    for (const std::string& name : presetTextileNames()) EXPECT_TRUE(contains(what, name)) << what;
  }
}

TEST(Presets, TowelGeometry) {
  const TextileOutline towel = presetTextile("towel");
  EXPECT_FALSE(towel.mirrored);
  EXPECT_NEAR(polygonSignedArea(towel.outline), 0.64 * 0.46, 1e-12);
  std::set<std::string> names;
  for (const NamedPoint& p : towel.named_points) names.insert(p.name);
  for (const char* expected : {"corner_ll", "corner_lr", "corner_ul", "corner_ur", "short_side_left_mid",
                               "short_side_right_mid", "long_side_bottom_mid", "long_side_top_mid"}) {
    EXPECT_EQ(names.count(expected), 1u) << expected;
  }
  for (const NamedPoint& p : towel.named_points) {
    if (p.name == "corner_ur") {
      EXPECT_TRUE(p.position.isApprox(Vec2(0.64, 0.46)));
    }
    if (p.name == "short_side_right_mid") {
      EXPECT_TRUE(p.position.isApprox(Vec2(0.64, 0.23)));
    }
  }
}

TEST(Presets, ValidateTextileOutlineCatchesBadNamedPoints) {
  TextileOutline towel = presetTextile("towel");
  towel.named_points.push_back({"outside", "grasp", Vec2(0.7, 0.1)});
  std::string error;
  EXPECT_FALSE(validateTextileOutline(towel, &error));
  EXPECT_TRUE(contains(error, "'outside'")) << error;

  towel = presetTextile("towel");
  towel.named_points.push_back({"corner_ll", "corner", Vec2(0, 0)});
  EXPECT_FALSE(validateTextileOutline(towel, &error));
  EXPECT_TRUE(contains(error, "twice")) << error;
}

// ------------------------------------------------------------ rasterisation

TEST(ParticleGrid, TowelAtOneCentimetre) {
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(presetTextile("towel"), 0.01, &error);
  ASSERT_TRUE(error.empty()) << error;
  EXPECT_EQ(grid.rows(), 47);
  EXPECT_EQ(grid.cols(), 65);
  EXPECT_EQ(grid.numActive(), 3055);
  EXPECT_DOUBLE_EQ(grid.spacing(), 0.01);
  EXPECT_TRUE(grid.origin().isZero());
  EXPECT_NEAR((grid.node(46, 64) - Vec2(0.64, 0.46)).norm(), 0, 1e-12);
  EXPECT_NEAR((grid.node(2, 3) - Vec2(0.03, 0.02)).norm(), 0, 1e-15);
  // Row-major compact numbering and consistent inverse maps.
  EXPECT_EQ(grid.activeIndex(1, 0), 65);
  EXPECT_EQ(grid.activeIndex(-1, 0), -1);
  EXPECT_EQ(grid.activeIndex(0, 65), -1);
  ASSERT_EQ(grid.compactRows().size(), 3055u);
  ASSERT_EQ(grid.compactCols().size(), 3055u);
  for (Index c = 0; c < grid.numActive(); ++c) {
    ASSERT_EQ(grid.activeIndex(grid.compactRows()[c], grid.compactCols()[c]), c);
  }
  const std::vector<Vec2> positions = grid.activePositions2D();
  ASSERT_EQ(positions.size(), 3055u);
  EXPECT_EQ(positions[100], grid.node(grid.compactRows()[100], grid.compactCols()[100]));
  EXPECT_EQ(positions[100], grid.activePosition(100));
}

TEST(ParticleGrid, TowelAtHalfCentimetre) {
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(presetTextile("towel"), 0.005, &error);
  ASSERT_TRUE(error.empty()) << error;
  EXPECT_EQ(grid.rows(), 93);
  EXPECT_EQ(grid.cols(), 129);
  EXPECT_EQ(grid.numActive(), 93 * 129);
}

TEST(ParticleGrid, SpacingThatDoesNotDivideTheSize) {
  // 0.64 / 0.03 = 21.33 -> 22 columns; 0.46 / 0.03 = 15.33 -> 16 rows; all inside.
  const ParticleGrid grid = ParticleGrid::rasterize(presetTextile("towel"), 0.03, nullptr);
  EXPECT_EQ(grid.cols(), 22);
  EXPECT_EQ(grid.rows(), 16);
  EXPECT_EQ(grid.numActive(), 22 * 16);
}

TEST(ParticleGrid, MirroredTshirtIsExactlySymmetric) {
  const TextileOutline shirt = presetTextile("tshirt");
  const Real area = polygonSignedArea(fullOutline(shirt));
  bool saw_odd_cols = false;
  bool saw_even_cols = false;
  for (Real d : {0.005, 0.007, 0.01, 0.015, 0.02, 0.03}) {
    std::string error;
    const ParticleGrid grid = ParticleGrid::rasterize(shirt, d, &error);
    ASSERT_TRUE(error.empty()) << "d=" << d << ": " << error;
    (grid.cols() % 2 == 1 ? saw_odd_cols : saw_even_cols) = true;
    Index inactive = 0;
    for (Index i = 0; i < grid.rows(); ++i) {
      for (Index j = 0; j < grid.cols(); ++j) {
        ASSERT_EQ(grid.active(i, j), grid.active(i, grid.cols() - 1 - j)) << "d=" << d << " i=" << i << " j=" << j;
        const Real mirror_sum = grid.node(i, j).x() + grid.node(i, grid.cols() - 1 - j).x();
        ASSERT_NEAR(mirror_sum, 2 * shirt.mirror_x, 1e-12);
        if (!grid.active(i, j)) ++inactive;
      }
    }
    EXPECT_GT(inactive, 0) << "the neck and the space under the sleeves must be empty";
    // Node count approximates area / d^2 (boundary effects are O(perimeter / d)).
    EXPECT_NEAR(grid.numActive() * d * d, area, 0.1 * area) << "d=" << d;
  }
  EXPECT_TRUE(saw_odd_cols);
  EXPECT_TRUE(saw_even_cols);
}

TEST(ParticleGrid, TshirtNeckAndUnderSleeveAreEmpty) {
  const ParticleGrid grid = ParticleGrid::rasterize(presetTextile("tshirt"), 0.01, nullptr);
  ASSERT_EQ(grid.cols(), 77);  // 0.76 m span including sleeves, axis on column 38
  EXPECT_NEAR(grid.node(0, 38).x(), 0.0, 1e-12);
  EXPECT_TRUE(grid.active(0, 38));     // hem middle
  EXPECT_TRUE(grid.active(62, 38));    // front neck middle (on the outline)
  EXPECT_FALSE(grid.active(65, 38));   // inside the neck opening
  EXPECT_FALSE(grid.active(10, 38 + 30));  // x = 0.30, y = 0.10: beside the body, below the sleeve
  EXPECT_TRUE(grid.active(50, 38 + 30));   // x = 0.30, y = 0.50: in the sleeve
}

TEST(ParticleGrid, MirroredOffsetAxisBetweenColumns) {
  // Full shape 0.1 <= x <= 0.5 with axis x = 0.3; d = 0.03 gives 14 columns,
  // so the axis lies midway between columns 6 and 7.
  TextileOutline half = plainOutline("half", {Vec2(0.3, 0), Vec2(0.5, 0), Vec2(0.5, 0.2), Vec2(0.3, 0.2)});
  half.mirrored = true;
  half.mirror_x = 0.3;
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(half, 0.03, &error);
  ASSERT_TRUE(error.empty()) << error;
  ASSERT_EQ(grid.cols(), 14);
  EXPECT_NEAR(0.5 * (grid.node(0, 6).x() + grid.node(0, 7).x()), 0.3, 1e-12);
  EXPECT_EQ(grid.numActive(), 14 * grid.rows());
}

TEST(ParticleGrid, NeighboursAtCornersAndInside) {
  const ParticleGrid grid = ParticleGrid::rasterize(presetTextile("towel"), 0.01, nullptr);
  const Index lower_left = grid.activeIndex(0, 0);
  EXPECT_EQ(grid.neighbour(lower_left, ParticleGrid::kLeft), -1);
  EXPECT_EQ(grid.neighbour(lower_left, ParticleGrid::kDown), -1);
  EXPECT_EQ(grid.neighbour(lower_left, ParticleGrid::kRight), grid.activeIndex(0, 1));
  EXPECT_EQ(grid.neighbour(lower_left, ParticleGrid::kUp), grid.activeIndex(1, 0));
  const Index upper_right = grid.activeIndex(46, 64);
  EXPECT_EQ(grid.neighbour(upper_right, 0), -1);
  EXPECT_EQ(grid.neighbour(upper_right, 1), -1);
  EXPECT_EQ(grid.neighbour(upper_right, 2), grid.activeIndex(46, 63));
  EXPECT_EQ(grid.neighbour(upper_right, 3), grid.activeIndex(45, 64));
  const Index inner = grid.activeIndex(10, 20);
  for (int dir = 0; dir < 4; ++dir) {
    const Index n = grid.neighbour(inner, dir);
    ASSERT_GE(n, 0);
    EXPECT_EQ(grid.neighbour(n, (dir + 2) % 4), inner);  // opposite direction leads back
  }
  EXPECT_EQ(grid.neighbour(inner, 4), -1);
  EXPECT_EQ(grid.neighbour(-1, 0), -1);
  EXPECT_EQ(grid.neighbour(grid.numActive(), 0), -1);
}

TEST(ParticleGrid, NeighbourSkipsInactiveNotch) {
  const ParticleGrid grid = ParticleGrid::rasterize(lShape(), 0.01, nullptr);
  // Node (10, 15) is on the notch's lower edge y = 0.1; above it is the notch.
  const Index on_edge = grid.activeIndex(10, 15);
  ASSERT_GE(on_edge, 0);
  EXPECT_EQ(grid.neighbour(on_edge, ParticleGrid::kUp), -1);
  EXPECT_GE(grid.neighbour(on_edge, ParticleGrid::kDown), 0);
}

TEST(ParticleGrid, NearestActiveOfNamedPoints) {
  const Real d = 0.01;
  for (const std::string& name : presetTextileNames()) {
    const TextileOutline t = presetTextile(name);
    std::string error;
    const ParticleGrid grid = ParticleGrid::rasterize(t, d, &error);
    ASSERT_TRUE(error.empty()) << error;
    for (const NamedPoint& p : t.named_points) {
      const Index c = grid.nearestActive(p.position);
      ASSERT_GE(c, 0);
      EXPECT_LE((grid.activePosition(c) - p.position).norm(), d * std::sqrt(2.0) / 2 + 1e-9)
          << name << "/" << p.name;
    }
  }
  EXPECT_EQ(ParticleGrid().nearestActive(Vec2(0, 0)), -1);
}

TEST(ParticleGrid, LShapeNotchIsInactive) {
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(lShape(), 0.01, &error);
  ASSERT_TRUE(error.empty()) << error;
  EXPECT_EQ(grid.rows(), 21);
  EXPECT_EQ(grid.cols(), 21);
  // Notch: 0.1 < x, y <= 0.2 -> columns and rows 11..20 (10 x 10 nodes) inactive;
  // the notch edges at x = 0.1 and y = 0.1 stay active.
  EXPECT_EQ(grid.numActive(), 21 * 21 - 10 * 10);
  EXPECT_FALSE(grid.active(15, 15));
  EXPECT_FALSE(grid.active(20, 20));
  EXPECT_TRUE(grid.active(10, 20));
  EXPECT_TRUE(grid.active(20, 10));
  EXPECT_TRUE(grid.active(15, 5));
  EXPECT_TRUE(grid.active(5, 15));
}

TEST(ParticleGrid, InvalidSpacingIsAnError) {
  const TextileOutline towel = presetTextile("towel");
  for (Real d : {0.0, -1.0, std::numeric_limits<Real>::quiet_NaN(), std::numeric_limits<Real>::infinity()}) {
    std::string error;
    const ParticleGrid grid = ParticleGrid::rasterize(towel, d, &error);
    EXPECT_TRUE(grid.empty());
    EXPECT_EQ(grid.numActive(), 0);
    EXPECT_TRUE(contains(error, "spacing")) << error;
  }
  std::string error;
  EXPECT_TRUE(ParticleGrid::rasterize(towel, 1e-6, &error).empty());  // 640k x 460k nodes
  EXPECT_TRUE(contains(error, "limit")) << error;
}

TEST(ParticleGrid, InvalidPolygonIsAnError) {
  std::string error;
  const ParticleGrid grid =
      ParticleGrid::rasterize(plainOutline("bow", {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)}), 0.1, &error);
  EXPECT_TRUE(grid.empty());
  EXPECT_TRUE(contains(error, "'bow'")) << error;
  EXPECT_TRUE(contains(error, "crosses")) << error;
}

TEST(ParticleGrid, TooFewActiveParticlesIsAnError) {
  std::string error;
  // 0.1 m towel-corner triangle at d = 0.1: nodes (0,0), (0.1,0), (0,0.1) only.
  const ParticleGrid grid =
      ParticleGrid::rasterize(plainOutline("tri", {Vec2(0, 0), Vec2(0.1, 0), Vec2(0, 0.1)}), 0.1, &error);
  EXPECT_TRUE(grid.empty());
  EXPECT_TRUE(contains(error, "only 3 active")) << error;
  EXPECT_TRUE(contains(error, "at least 4")) << error;
}

// -------------------------------------------------------------- hold points

void expectSortedInsideAndSpread(const TextileOutline& t, const std::vector<Vec2>& points, Real s) {
  const std::vector<Vec2> polygon = fullOutline(t);
  for (std::size_t k = 0; k < points.size(); ++k) {
    EXPECT_TRUE(pointInPolygon(polygon, points[k], 1e-9)) << "point " << k << " outside";
    if (k > 0) {
      const bool ordered = points[k - 1].y() < points[k].y() - 1e-9 ||
                           (std::abs(points[k - 1].y() - points[k].y()) <= 1e-9 && points[k - 1].x() < points[k].x());
      EXPECT_TRUE(ordered) << "points " << k - 1 << " and " << k << " are not sorted by (y, x)";
    }
    for (std::size_t m = 0; m < k; ++m) {
      ASSERT_GE((points[k] - points[m]).norm(), 0.25 * s) << "points " << m << " and " << k;
    }
  }
}

TEST(HoldPointLattice, TowelExactCounts) {
  const TextileOutline towel = presetTextile("towel");
  // s = 0.08: x lines 0..0.64 (9, exact fit); y lines 0..0.40 plus the far edge
  // 0.46 because the 0.06 remainder exceeds 0.25*s = 0.02 (7 lines): 63 points.
  const std::vector<Vec2> p08 = holdPointLattice(towel, 0.08);
  EXPECT_EQ(p08.size(), 63u);
  expectSortedInsideAndSpread(towel, p08, 0.08);
  EXPECT_EQ(p08.front(), Vec2(0, 0));
  EXPECT_EQ(p08.back(), Vec2(0.64, 0.46));
  EXPECT_NEAR(p08[9].y(), 0.08, 1e-12);  // second row starts after 9 points

  // s = 0.15: x lines 0..0.60 plus 0.64 (remainder 0.04 > 0.0375): 6;
  // y lines 0, 0.15, 0.30, and 0.45 moved onto 0.46 (remainder 0.01 <= 0.0375): 4.
  const std::vector<Vec2> p15 = holdPointLattice(towel, 0.15);
  EXPECT_EQ(p15.size(), 24u);
  expectSortedInsideAndSpread(towel, p15, 0.15);
  EXPECT_NEAR(p15.back().y(), 0.46, 1e-12);

  // s = 0.01 matches the particle grid: 65 x 47.
  EXPECT_EQ(holdPointLattice(towel, 0.01).size(), 3055u);
}

TEST(HoldPointLattice, TshirtIncludesVerticesAndStaysInside) {
  const TextileOutline shirt = presetTextile("tshirt");
  const Real s = 0.05;
  const std::vector<Vec2> points = holdPointLattice(shirt, s);
  expectSortedInsideAndSpread(shirt, points, s);
  for (const Vec2& v : fullOutline(shirt)) {
    bool found = false;
    for (const Vec2& p : points) found = found || (p - v).norm() < 1e-12;
    EXPECT_TRUE(found) << "vertex (" << v.x() << ", " << v.y() << ") missing";
  }
  // More than the bare interior lattice: boundary samples were added.
  const std::vector<Vec2> polygon = fullOutline(shirt);
  std::size_t lattice_inside = 0;
  for (int i = 0; i * s <= 0.70 + 1e-12; ++i) {
    for (int j = 0; j * s <= 0.76 + 1e-12; ++j) {
      if (pointInPolygon(polygon, Vec2(-0.38 + j * s, i * s), 1e-9)) ++lattice_inside;
    }
  }
  EXPECT_GT(points.size(), lattice_inside);
}

TEST(HoldPointLattice, InvalidInputsThrow) {
  const TextileOutline towel = presetTextile("towel");
  EXPECT_THROW(holdPointLattice(towel, 0.0), std::invalid_argument);
  EXPECT_THROW(holdPointLattice(towel, -0.1), std::invalid_argument);
  EXPECT_THROW(holdPointLattice(towel, std::numeric_limits<Real>::quiet_NaN()), std::invalid_argument);
  EXPECT_THROW(holdPointLattice(plainOutline("bow", {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)}), 0.1),
               std::invalid_argument);
}

}  // namespace
}  // namespace textile_handling
