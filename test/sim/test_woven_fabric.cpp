// Tests for sim/woven_fabric.h and sim/yarn_grid.h: weaves, fabric checks, YAML, yarns laid in outlines.
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_grid.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <vector>

#include "textile_handling/sim/material.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/textile_geometry.h"

#ifndef TEXTILE_HANDLING_SOURCE_DIR
#define TEXTILE_HANDLING_SOURCE_DIR "/work/main"
#endif

namespace textile_handling {
namespace {

std::vector<Vec2> rectangle(Real w, Real h) { return {Vec2(0, 0), Vec2(w, 0), Vec2(w, h), Vec2(0, h)}; }

// The message of the exception `f` throws (empty if none, "other" for another type).
template <class E, class F>
std::string errorOf(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  } catch (...) {
    return "other";
  }
  return "";
}

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

TEST(WeavePattern, NamedWeavesFollowTheirRules) {
  const WeavePattern plain = namedWeave("plain"), twill = namedWeave("twill_2_2"), satin = namedWeave("satin_5");
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j) {
      EXPECT_EQ(plain.warpOnTop(i, j), (i + j) % 2 == 0);
      EXPECT_EQ(twill.warpOnTop(i, j), (i + j) % 4 < 2);
      EXPECT_EQ(satin.warpOnTop(i, j), ((j - 2 * i) % 5 + 5) % 5 != 0);
    }
  // A 5-harness satin: every warp and every weft has exactly one weft-on-top crossing per repeat.
  for (int i = 0; i < 5; ++i) {
    int weft_on_top_row = 0, weft_on_top_col = 0;
    for (int j = 0; j < 5; ++j) {
      weft_on_top_row += !satin.warpOnTop(i, j);
      weft_on_top_col += !satin.warpOnTop(j, i);
    }
    EXPECT_EQ(weft_on_top_row, 1);
    EXPECT_EQ(weft_on_top_col, 1);
  }
}

TEST(WeavePattern, CustomRepeatsAndBadOnes) {
  const WeavePattern w = customWeave({{1, 1, 0}, {0, 1, 1}});
  EXPECT_EQ(w.name, "custom");
  EXPECT_TRUE(w.warpOnTop(0, 0));
  EXPECT_FALSE(w.warpOnTop(0, 2));
  EXPECT_FALSE(w.warpOnTop(3, 0));  // row 3 % 2 = 1
  EXPECT_TRUE(w.warpOnTop(3, 4));   // column 4 % 3 = 1
  EXPECT_TRUE(contains(errorOf<SimError>([] { customWeave({}); }), "at least one row"));
  EXPECT_TRUE(contains(errorOf<SimError>([] { customWeave({{1, 0}, {1}}); }), "row 1 has 1 entries"));
  EXPECT_TRUE(contains(errorOf<SimError>([] { customWeave({{1, 2}}); }), "entry (0, 1) is 2"));
  EXPECT_TRUE(contains(errorOf<SimError>([] { customWeave(std::vector<std::vector<int>>(65, {1})); }), "more than 64"));
  EXPECT_TRUE(contains(errorOf<SimError>([] { namedWeave("twill_3_1"); }), "weave 'twill_3_1' is not known"));
}

TEST(WovenFabric, DefaultsAreTheSourcesShirt) {
  const WovenFabric f;
  EXPECT_EQ(wovenFabricErrors(f), "");
  EXPECT_DOUBLE_EQ(f.warpSpacing(), 1e-3);
  // phi_j = 2 asin(R / L) = 0.505 rad for R / L = 0.25 (notes section 6.1).
  EXPECT_NEAR(f.jammingAngle(), 0.5054, 1e-4);
}

TEST(WovenFabric, BadFieldsAreNamed) {
  auto errorsWith = [](auto change) {
    WovenFabric f;
    change(f);
    return wovenFabricErrors(f);
  };
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.yarn_radius_m = 0.5e-3; }), "yarn_radius_m"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.yarn_radius_m = 0.5e-3; }), "half the warp spacing"));
  // Anisotropic: the finer weft spacing limits the radius.
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.weft_density_per_m = 2500; }), "half the weft spacing"));
  EXPECT_EQ(errorsWith([](WovenFabric& f) { f.weft_density_per_m = 1500; }), "");
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.warp_density_per_m = 0; }), "warp_density_per_m 0 must be finite and > 0"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.weft_density_per_m = -3; }), "weft_density_per_m -3"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.warp_density_per_m = 1e6; }), "10 per mm"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.young_modulus_pa = std::nan(""); }), "young_modulus_pa nan"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.linear_density_kg_per_m = 0; }), "linear_density_kg_per_m 0 must be finite and > 0"));
  EXPECT_TRUE(contains(errorsWith([](WovenFabric& f) { f.sliding_friction = -0.1; }), "sliding_friction -0.1 must be finite and >= 0"));
  EXPECT_EQ(errorsWith([](WovenFabric& f) { f.sliding_friction = 0; }), "");  // frictionless is allowed
  // Two bad fields: two lines.
  const std::string two = errorsWith([](WovenFabric& f) {
    f.shear_modulus_pa = std::numeric_limits<Real>::infinity();
    f.damping_mass_per_s = -1;
  });
  EXPECT_TRUE(contains(two, "shear_modulus_pa inf"));
  EXPECT_TRUE(contains(two, "\ndamping_mass_per_s -1"));
  WovenFabric bad;
  bad.yarn_radius_m = 1;
  EXPECT_TRUE(contains(errorOf<SimError>([&] { validateWovenFabric(bad); }), "woven fabric: yarn_radius_m 1"));
}

TEST(WovenFabricYaml, RoundTripAndDefaults) {
  WovenFabric f;
  f.weave = customWeave({{1, 0, 0}, {0, 1, 0}, {0, 0, 1}});
  f.weft_density_per_m = 1200;
  f.bending_modulus = 2e-2;
  f.sliding_friction = 0.25;
  const WovenFabric g = parseWovenFabricYaml(wovenFabricToYaml(f));
  EXPECT_EQ(g.weave.warp_on_top, f.weave.warp_on_top);
  EXPECT_EQ(g.weft_density_per_m, 1200);
  EXPECT_EQ(g.bending_modulus, 2e-2);
  EXPECT_EQ(g.sliding_friction, 0.25);
  const WovenFabric twill = parseWovenFabricYaml("type: woven_fabric\nweave: twill_2_2\n");
  EXPECT_EQ(twill.weave.name, "twill_2_2");
  EXPECT_EQ(twill.young_modulus_pa, WovenFabric().young_modulus_pa);
}

TEST(WovenFabricYaml, BundledFabricsLoad) {
  for (const std::string w : {"plain", "twill_2_2", "satin_5"}) {
    const WovenFabric f = loadWovenFabricYaml(std::string(TEXTILE_HANDLING_SOURCE_DIR) + "/data/fabrics/" + w + ".yaml");
    EXPECT_EQ(f.weave.name, w);
    EXPECT_EQ(f.weave.warp_on_top, namedWeave(w).warp_on_top);
    EXPECT_EQ(f.yarn_radius_m, WovenFabric().yarn_radius_m);
    EXPECT_EQ(f.shear_modulus_pa, WovenFabric().shear_modulus_pa);
  }
}

TEST(WovenFabricYaml, BadDocumentsNameTheField) {
  auto err = [](const std::string& yaml) { return errorOf<MaterialError>([&] { parseWovenFabricYaml(yaml, "f.yaml"); }); };
  EXPECT_TRUE(contains(err("weave: plain\n"), "f.yaml: type must be woven_fabric"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nweave: basket\n"), "weave 'basket' is not known"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nyarn_radius: 1\n"), "unknown key 'yarn_radius'"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nyarn_radius_m: 0.6e-3\n"), "yarn_radius_m 0.0006 must be below half the warp spacing 0.001 m"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nyoung_modulus_pa: .nan\n"), "young_modulus_pa"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nyoung_modulus_pa: stiff\n"), "young_modulus_pa 'stiff' is not a number"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nwarp_density_per_m: [1]\n"), "warp_density_per_m must be a single value"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nweave: custom\n"), "needs weave_repeat"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nweave: custom\nweave_repeat: [[1, 0], [0, x]]\n"), "entry (1, 1) must be 0 or 1"));
  EXPECT_TRUE(contains(err("type: woven_fabric\nweave: plain\nweave_repeat: [[1]]\n"), "only for weave: custom"));
  EXPECT_TRUE(contains(err("[1, 2"), "not valid YAML"));
  EXPECT_TRUE(contains(err(std::string(2 << 20, 'a')), "more than the limit"));
  EXPECT_TRUE(contains(errorOf<MaterialError>([] { loadWovenFabricYaml("/nonexistent/fabric.yaml"); }), "/nonexistent/fabric.yaml"));
}

TEST(YarnGrid, RectangleGivesEveryCrossingAndTwoEndsPerYarn) {
  const WovenFabric f;  // 1 yarn per mm
  const YarnGrid g = layYarnGrid(rectangle(0.05, 0.03), f);
  EXPECT_EQ(g.warp_lines, 30u);
  EXPECT_EQ(g.weft_lines, 50u);
  EXPECT_EQ(g.crossings.size(), 1500u);
  ASSERT_EQ(g.pieces.size(), 80u);
  EXPECT_EQ(g.ends.size(), 160u);
  for (const YarnPiece& p : g.pieces) {
    ASSERT_EQ(p.nodes.size(), (p.warp ? 50u : 30u) + 2);
    // Ends on the outline, half a spacing beyond the outermost crossings; arc length increasing by L.
    EXPECT_TRUE(g.isEnd(p.nodes.front()));
    EXPECT_TRUE(g.isEnd(p.nodes.back()));
    EXPECT_NEAR(p.arc_length_m.front(), 0.0, 1e-12);
    EXPECT_NEAR(p.arc_length_m.back(), p.warp ? 0.05 : 0.03, 1e-12);
    for (std::size_t k = 1; k + 2 < p.nodes.size(); ++k) EXPECT_NEAR(p.arc_length_m[k + 1] - p.arc_length_m[k], 1e-3, 1e-12);
    for (std::size_t k = 1; k + 1 < p.nodes.size(); ++k) {
      const YarnCrossing& c = g.crossings[p.nodes[k]];
      EXPECT_EQ(p.warp ? c.warp : c.weft, p.line);
      EXPECT_EQ(c.warp_on_top, f.weave.warpOnTop(c.warp, c.weft));
    }
  }
  // Every crossing lies on exactly one warp and one weft piece.
  std::vector<int> on_warp(g.crossings.size(), 0), on_weft(g.crossings.size(), 0);
  for (const YarnPiece& p : g.pieces)
    for (std::size_t n : p.nodes)
      if (!g.isEnd(n)) ++(p.warp ? on_warp : on_weft)[n];
  for (std::size_t c = 0; c < g.crossings.size(); ++c) {
    EXPECT_EQ(on_warp[c], 1);
    EXPECT_EQ(on_weft[c], 1);
  }
}

TEST(YarnGrid, ConcaveOutlineSplitsYarnsAndKeepsEverythingInside) {
  // An L: 4 x 4 cm with the 2 x 2 cm top-right square cut out, at 2 yarns per cm (5 mm spacing, R 1 mm).
  const std::vector<Vec2> l = {Vec2(0, 0), Vec2(0.04, 0), Vec2(0.04, 0.02), Vec2(0.02, 0.02), Vec2(0.02, 0.04), Vec2(0, 0.04)};
  WovenFabric f;
  f.warp_density_per_m = f.weft_density_per_m = 200;
  f.yarn_radius_m = 1e-3;
  const YarnGrid g = layYarnGrid(l, f);
  EXPECT_EQ(g.crossings.size(), 8u * 4 + 4u * 4);  // lower 4 warp lines x 8 weft, upper 4 x 4
  for (const YarnCrossing& c : g.crossings) EXPECT_TRUE(pointInPolygon(l, c.position, 0.0));
  for (const Vec2& e : g.ends) {
    Real d = 1e9;
    for (std::size_t k = 0; k < l.size(); ++k) d = std::min(d, pointSegmentDistance(e, l[k], l[(k + 1) % l.size()]));
    EXPECT_LT(d, 1e-12);
  }
  std::size_t long_warps = 0;
  for (const YarnPiece& p : g.pieces) long_warps += p.warp && p.nodes.size() == 10;
  EXPECT_EQ(long_warps, 4u);

  // A triangle: every crossing inside; ends closer than a quarter spacing to a crossing are dropped.
  const std::vector<Vec2> tri = {Vec2(0, 0), Vec2(0.05, 0), Vec2(0, 0.05)};
  const YarnGrid t = layYarnGrid(tri, f);
  EXPECT_GT(t.crossings.size(), 30u);
  for (const YarnCrossing& c : t.crossings) EXPECT_TRUE(pointInPolygon(tri, c.position, 0.0));
  for (const YarnPiece& p : t.pieces)
    for (std::size_t k = 0; k + 1 < p.nodes.size(); ++k)
      EXPECT_GE(p.arc_length_m[k + 1] - p.arc_length_m[k], 0.25 * 5e-3 - 1e-12);
}

TEST(YarnGrid, FloatsGrowFromPlainToTwillToSatin) {
  auto interlacedShare = [](const std::string& weave) {
    WovenFabric f;
    f.weave = namedWeave(weave);
    const WeaveSegmentCounts n = countWeaveSegments(layYarnGrid(rectangle(0.04, 0.04), f));
    return static_cast<double>(n.interlaced) / static_cast<double>(n.interlaced + n.floats);
  };
  EXPECT_DOUBLE_EQ(interlacedShare("plain"), 1.0);
  EXPECT_NEAR(interlacedShare("twill_2_2"), 0.5, 0.01);
  EXPECT_NEAR(interlacedShare("satin_5"), 0.4, 0.01);
}

TEST(YarnGrid, BadOutlinesAndHugeGridsAreRefused) {
  const WovenFabric f;
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid({Vec2(0, 0), Vec2(1, 0)}, f); }), "yarn grid outline"));
  const std::vector<Vec2> nan_poly = {Vec2(0, 0), Vec2(std::nan(""), 0), Vec2(0, 1)};
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid(nan_poly, f); }), "yarn grid outline"));
  // 2 x 2 m at 1 yarn/mm: 4 million crossings, refused before allocating.
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid(rectangle(2, 2), f); }), "more than 1000000 crossings"));
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid(rectangle(1e12, 1e12), f); }), "more than 1000000 crossings"));
  WovenFabric bad;
  bad.weft_density_per_m = std::nan("");
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid(rectangle(0.01, 0.01), bad); }), "weft_density_per_m nan"));
  YarnGridOptions o;
  o.min_end_segment_fraction = 1.5;
  EXPECT_TRUE(contains(errorOf<SimError>([&] { layYarnGrid(rectangle(0.01, 0.01), f, o); }), "min_end_segment_fraction"));
}

}  // namespace
}  // namespace textile_handling
