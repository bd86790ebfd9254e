// Mirror symmetry of textiles, fundamental-domain hold points, the build plan and particle mirroring.
#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "textile_handling/db/textile_symmetry.h"
#include "textile_handling/sim/drape_scene.h"

using namespace textile_handling;
using namespace textile_handling::db;

TEST(TextileSymmetry, PresetsHaveTheExpectedMirrors) {
  const TextileSymmetry towel = detectSymmetry(presetTextile("towel"));
  EXPECT_TRUE(towel.mirror_x);
  EXPECT_TRUE(towel.mirror_y);
  EXPECT_NEAR(towel.cx, 0.32, 1e-12);
  EXPECT_NEAR(towel.cy, 0.23, 1e-12);
  EXPECT_EQ(towel.name(), "xy");
  const TextileSymmetry shirt = detectSymmetry(presetTextile("tshirt"));
  EXPECT_TRUE(shirt.mirror_x);
  EXPECT_FALSE(shirt.mirror_y);
  EXPECT_NEAR(shirt.cx, 0.0, 1e-12);

  TextileOutline l;
  l.name = "L";
  l.outline = {Vec2(0, 0), Vec2(0.4, 0), Vec2(0.4, 0.1), Vec2(0.1, 0.1), Vec2(0.1, 0.3), Vec2(0, 0.3)};
  EXPECT_FALSE(detectSymmetry(l).any());
}

TEST(TextileSymmetry, MirrorsAndCanonicalImages) {
  const TextileSymmetry s = detectSymmetry(presetTextile("towel"));
  const Vec2 p(0.5, 0.4);
  EXPECT_TRUE(s.apply(MirrorKind::kMirrorX, p).isApprox(Vec2(0.14, 0.4)));
  EXPECT_TRUE(s.apply(MirrorKind::kMirrorY, p).isApprox(Vec2(0.5, 0.06)));
  EXPECT_TRUE(s.apply(MirrorKind::kMirrorXY, p).isApprox(Vec2(0.14, 0.06)));
  EXPECT_TRUE(s.canonical(p).isApprox(Vec2(0.14, 0.06)));
  EXPECT_TRUE(s.inFundamentalDomain(Vec2(0.32, 0.23), 1e-12));
  EXPECT_FALSE(s.inFundamentalDomain(Vec2(0.33, 0.1), 1e-12));
  for (MirrorKind m : {MirrorKind::kIdentity, MirrorKind::kMirrorX, MirrorKind::kMirrorY, MirrorKind::kMirrorXY})
    EXPECT_EQ(mirrorKindFromString(toString(m)), m);
  EXPECT_THROW(mirrorKindFromString("rotate"), std::invalid_argument);
}

TEST(TextileSymmetry, TowelQuadrantLatticeIncludesEdgesAndAxes) {
  const TextileOutline towel = presetTextile("towel");
  const TextileSymmetry s = detectSymmetry(towel);
  const auto q = fundamentalDomainLattice(towel, s, 0.08);
  // x: 0, .08, .16, .24, .32; y: 0, .08, .16 and the axis .23 (remainder .07 > s/4).
  ASSERT_EQ(q.size(), 20u);
  std::set<long> xs, ys;
  for (const Vec2& p : q) {
    xs.insert(std::lround(p.x() * 1e4));
    ys.insert(std::lround(p.y() * 1e4));
    EXPECT_TRUE(s.inFundamentalDomain(p, 1e-12));
  }
  EXPECT_EQ(xs, (std::set<long>{0, 800, 1600, 2400, 3200}));
  EXPECT_EQ(ys, (std::set<long>{0, 800, 1600, 2300}));
  const auto plan = planHoldPoints(q, s);
  // Full set: 9 columns (x axis shared) x 7 rows (y axis shared) = 63.
  EXPECT_EQ(plan.size(), 63u);
  int simulated = 0, max_i = 0, max_j = 0;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    const auto& h = plan[k];
    if (h.mirror == MirrorKind::kIdentity) {
      ++simulated;
      EXPECT_EQ(h.source, static_cast<int>(k));
    } else {
      EXPECT_TRUE(s.apply(h.mirror, plan[static_cast<std::size_t>(h.source)].position).isApprox(h.position));
    }
    max_i = std::max(max_i, h.lattice_i);
    max_j = std::max(max_j, h.lattice_j);
  }
  EXPECT_EQ(simulated, 20);
  EXPECT_EQ(max_i, 6);
  EXPECT_EQ(max_j, 8);
}

TEST(TextileSymmetry, ThesisGridHas36PointsInOneQuadrant) {
  const TextileOutline towel = presetTextile("towel");
  const TextileSymmetry s = detectSymmetry(towel);
  const auto q = fundamentalDomainGrid(towel, s, 6, 6);
  ASSERT_EQ(q.size(), 36u);
  bool has_short_side_middle = false;
  for (const Vec2& p : q) has_short_side_middle |= (p - Vec2(0, 0.23)).norm() < 1e-12;
  EXPECT_TRUE(has_short_side_middle);
  EXPECT_EQ(planHoldPoints(q, s).size(), 121u);  // 11 x 11
  EXPECT_THROW(fundamentalDomainGrid(towel, s, 0, 3), std::invalid_argument);
}

TEST(TextileSymmetry, ShirtHalfIsItsGivenHalfOutline) {
  const TextileOutline shirt = presetTextile("tshirt");
  const TextileSymmetry s = detectSymmetry(shirt);
  const auto dom = fundamentalDomainPolygon(shirt, s);
  ASSERT_FALSE(dom.empty());
  for (const Vec2& v : dom) EXPECT_LE(v.x(), 1e-12);
  EXPECT_NEAR(std::abs(polygonSignedArea(dom)), 0.5 * std::abs(polygonSignedArea(fullOutline(shirt))), 1e-9);
  const auto q = fundamentalDomainLattice(shirt, s, 0.1);
  EXPECT_FALSE(q.empty());
  for (const Vec2& p : q) EXPECT_LE(p.x(), 1e-9);
}

TEST(TextileSymmetry, ParticleMirrorPermutationNeedsASymmetricGrid) {
  const TextileOutline towel = presetTextile("towel");
  const TextileSymmetry s = detectSymmetry(towel);
  std::string err;
  const ParticleGrid g2 = ParticleGrid::rasterize(towel, 0.02, &err);  // 33 x 24: symmetric
  for (MirrorKind m : s.mirrors()) {
    const auto perm = mirrorPermutation(g2, s, m);
    ASSERT_EQ(perm.size(), static_cast<std::size_t>(g2.numActive()));
    std::set<Index> image(perm.begin(), perm.end());
    EXPECT_EQ(image.size(), perm.size());  // a bijection
    for (Index k = 0; k < g2.numActive(); ++k)
      EXPECT_TRUE(g2.activePosition(perm[static_cast<std::size_t>(k)]).isApprox(s.apply(m, g2.activePosition(k))));
  }
  const ParticleGrid g4 = ParticleGrid::rasterize(towel, 0.04, &err);  // rows at 0..0.44: not symmetric in y
  EXPECT_FALSE(mirrorPermutation(g4, s, MirrorKind::kMirrorX).empty());
  EXPECT_TRUE(mirrorPermutation(g4, s, MirrorKind::kMirrorY).empty());
}

TEST(TextileSymmetry, MirroredPositionsAreAnInvolutionThatKeepsTheHoldPoint) {
  const TextileOutline towel = presetTextile("towel");
  const TextileSymmetry s = detectSymmetry(towel);
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(towel, 0.04 * 0.5, &err);
  const Index n = g.numActive();
  VecX x(3 * n);
  for (Index k = 0; k < 3 * n; ++k) x[k] = std::cos(0.1 * k) + (k % 3 == 2 ? 1.0 : 0.0);
  const Vec3 hold = x.segment<3>(3 * 17);
  for (MirrorKind m : s.mirrors()) {
    const auto perm = mirrorPermutation(g, s, m);
    const VecX y = mirrorPositions(x, perm, m, hold);
    EXPECT_TRUE(y.segment<3>(3 * perm[17]).isApprox(hold));
    EXPECT_TRUE(mirrorPositions(y, perm, m, hold).isApprox(x));
    // Heights are unchanged; pairwise distances too.
    EXPECT_NEAR(y[3 * perm[5] + 2], x[3 * 5 + 2], 1e-15);
    EXPECT_NEAR((y.segment<3>(3 * perm[3]) - y.segment<3>(3 * perm[40])).norm(),
                (x.segment<3>(3 * 3) - x.segment<3>(3 * 40)).norm(), 1e-12);
  }
  EXPECT_THROW(mirrorPositions(x, {0, 1}, MirrorKind::kMirrorX, hold), std::invalid_argument);
}

TEST(TextileSymmetry, LatticeNeighbours) {
  EXPECT_TRUE(latticeNeighbours(2, 3, 2, 3, false));
  EXPECT_TRUE(latticeNeighbours(2, 3, 2, 4, false));
  EXPECT_TRUE(latticeNeighbours(2, 3, 1, 3, false));
  EXPECT_FALSE(latticeNeighbours(2, 3, 3, 4, false));
  EXPECT_TRUE(latticeNeighbours(2, 3, 3, 4, true));
  EXPECT_FALSE(latticeNeighbours(2, 3, 4, 3, true));
}

TEST(TextileSymmetry, MirrorSymmetricSpacingIsTheNearestFinerSymmetricGrid) {
  const TextileOutline towel = presetTextile("towel");  // 64 x 46 cm: symmetric grids at 2 cm / n
  const TextileSymmetry s = detectSymmetry(towel);
  auto symmetricGrid = [&](Real d) {
    std::string error;
    const ParticleGrid g = ParticleGrid::rasterize(towel, d, &error);
    for (MirrorKind m : s.mirrors())
      if (mirrorPermutation(g, s, m).empty()) return false;
    return !g.empty();
  };
  ASSERT_FALSE(symmetricGrid(0.0075));
  EXPECT_NEAR(mirrorSymmetricSpacing(towel, s, 0.0075), 0.02 / 3, 1e-12);
  EXPECT_DOUBLE_EQ(mirrorSymmetricSpacing(towel, s, 0.01), 0.01);  // already symmetric: kept
  EXPECT_NEAR(mirrorSymmetricSpacing(towel, s, 0.03), 0.02, 1e-12);
  EXPECT_NEAR(mirrorSymmetricSpacing(towel, s, 0.015), 0.01, 1e-12);
  for (Real d : {0.0075, 0.015, 0.03, 0.011}) {
    const Real snapped = mirrorSymmetricSpacing(towel, s, d);
    EXPECT_LE(snapped, d);
    EXPECT_GE(snapped, 0.5 * d);
    EXPECT_TRUE(symmetricGrid(snapped)) << d << " -> " << snapped;
  }
  // No mirror: nothing to gain, the spacing is kept.
  EXPECT_DOUBLE_EQ(mirrorSymmetricSpacing(towel, TextileSymmetry{}, 0.0075), 0.0075);
  EXPECT_THROW(mirrorSymmetricSpacing(towel, s, std::nan("")), std::invalid_argument);
  EXPECT_THROW(mirrorSymmetricSpacing(towel, s, -0.01), std::invalid_argument);
}
