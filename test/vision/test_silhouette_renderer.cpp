// Tests for the canonical silhouette renderer and the canonicalisation of camera masks.
#include "textile_handling/vision/silhouette_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <limits>
#include <stdexcept>
#include <string>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/vision/mask_cv.h"
#include "textile_handling/bench/match_benchmark.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace vision {
namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TextileOutline rectangle(double w, double h) {
  TextileOutline t;
  t.name = "rect";
  t.outline = {Vec2(0, 0), Vec2(w, 0), Vec2(w, h), Vec2(0, h)};
  return t;
}

// A flat w x h sheet hanging in the world x-z plane (y = 0), held at the middle of its top edge,
// which is at (0, 0, 1). Built from the simulator's grid and topology.
struct Sheet {
  VecX x;
  std::vector<Triangle> tris;
  Vec3 hold = Vec3(0, 0, 1.0);
};

Sheet flatSheet(double w, double h, double d) {
  std::string err;
  const ParticleGrid grid = ParticleGrid::rasterize(rectangle(w, h), d, &err);
  EXPECT_FALSE(grid.empty()) << err;
  const ParticleTopology topo = ParticleTopology::fromGrid(grid);
  Sheet s;
  s.x.resize(3 * grid.numActive());
  for (Index i = 0; i < grid.numActive(); ++i) {
    const Vec2 p = grid.activePosition(i);
    node3(s.x, i) = Vec3(p.x() - 0.5 * w, 0.0, 1.0 - (h - p.y()));
  }
  s.tris = trianglesFromTopology(topo);
  return s;
}

// Sum of the triangles' areas in the flat textile (grid positions); every triangle must be counter-clockwise.
double flatArea(const ParticleGrid& g, const std::vector<Triangle>& tris) {
  double area = 0;
  for (const auto& t : tris) {
    const Vec2 a = g.activePosition(t[0]), b = g.activePosition(t[1]), c = g.activePosition(t[2]);
    const double s = 0.5 * ((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
    EXPECT_GT(s, 0);
    area += s;
  }
  return area;
}

TEST(Triangles, FromTopologyCoversEveryCompleteCell) {
  std::string err;
  const ParticleGrid rect = ParticleGrid::rasterize(rectangle(0.3, 0.2), 0.05, &err);
  ASSERT_FALSE(rect.empty()) << err;
  const auto tris = trianglesFromTopology(ParticleTopology::fromGrid(rect));
  EXPECT_EQ(tris.size(), static_cast<std::size_t>(2 * (rect.rows() - 1) * (rect.cols() - 1)));
  // Triangle areas in the flat textile sum to the rectangle's area, and all are positive (CCW).
  EXPECT_NEAR(flatArea(rect, tris), 0.3 * 0.2, 1e-12);

  // L shape: the missing quadrant has no cells.
  TextileOutline l;
  l.outline = {Vec2(0, 0), Vec2(0.2, 0), Vec2(0.2, 0.1), Vec2(0.1, 0.1), Vec2(0.1, 0.2), Vec2(0, 0.2)};
  const ParticleGrid lg = ParticleGrid::rasterize(l, 0.05, &err);
  ASSERT_FALSE(lg.empty()) << err;
  EXPECT_EQ(trianglesFromTopology(ParticleTopology::fromGrid(lg)).size(), static_cast<std::size_t>(2 * 12));
}

// The coarse triangulation covers exactly the fine one's area (no gaps, no overlap, nothing outside a
// concave outline), stride 1 is the fine one, and a curved hanging sheet looks the same in the canonical
// frame with about a pixel per block.
TEST(Triangles, CoarseGridTrianglesCoverTheSameSheet) {
  std::string err;
  TextileOutline l;  // concave: an L whose notch cuts blocks in half
  l.outline = {Vec2(0, 0), Vec2(0.33, 0), Vec2(0.33, 0.13), Vec2(0.17, 0.13), Vec2(0.17, 0.25), Vec2(0, 0.25)};
  for (const TextileOutline& t : {rectangle(0.31, 0.2), l}) {
    const ParticleGrid g = ParticleGrid::rasterize(t, 0.01, &err);
    ASSERT_FALSE(g.empty()) << err;
    const auto fine = trianglesFromTopology(ParticleTopology::fromGrid(g));
    const auto one = coarseGridTriangles(g, 1);
    EXPECT_EQ(one.size(), fine.size());
    EXPECT_NEAR(flatArea(g, one), flatArea(g, fine), 1e-12);
    for (int stride : {2, 3, 5}) {
      const auto coarse = coarseGridTriangles(g, stride);
      EXPECT_LT(coarse.size(), fine.size() / 2) << stride;
      EXPECT_NEAR(flatArea(g, coarse), flatArea(g, fine), 1e-12) << stride;  // positive areas summing up: no overlap
      for (const auto& tri : coarse) {
        const Vec2 centroid = (g.activePosition(tri[0]) + g.activePosition(tri[1]) + g.activePosition(tri[2])) / 3.0;
        EXPECT_TRUE(pointInPolygon(t.outline, centroid, 0.0)) << stride;
      }
    }
  }
  // A 0.64 x 0.46 m towel at d = 2/3 cm bent into a U (a half cylinder of radius 8 cm, the sides straight):
  // 1.6 cm pixels, blocks of 2 x 2 cells. The silhouettes differ by at most a few edge pixels.
  const double w = 0.64, h = 0.46, d = 0.02 / 3;
  const ParticleGrid g = ParticleGrid::rasterize(rectangle(w, h), d, &err);
  ASSERT_FALSE(g.empty()) << err;
  VecX x(3 * g.numActive());
  for (Index i = 0; i < g.numActive(); ++i) {
    const Vec2 p = g.activePosition(i);
    const double u = p.x() - 0.5 * w, R = 0.08, arc = R * M_PI / 2;  // a U: the arc, then straight back
    const double X = std::abs(u) <= arc ? R * std::sin(u / R) : std::copysign(R, u);
    const double Y = std::abs(u) <= arc ? R * std::cos(u / R) : -(std::abs(u) - arc);
    node3(x, i) = Vec3(X, Y,
                       1.0 - (h - p.y()));
  }
  const auto fine = trianglesFromTopology(ParticleTopology::fromGrid(g));
  const auto coarse = coarseGridTriangles(g, 2);
  EXPECT_LT(coarse.size(), fine.size() / 3);
  for (double az : {0.0, 30.0, 90.0, 135.0}) {
    const BitMask a = renderSilhouette(x, fine, Vec3(0, 0.08, 1.0), az);
    const BitMask b = renderSilhouette(x, coarse, Vec3(0, 0.08, 1.0), az);
    int differ = 0;
    for (int r = 0; r < a.height(); ++r)
      for (int c = 0; c < a.width(); ++c) differ += a.get(c, r) != b.get(c, r);
    std::cout << "azimuth " << az << ": " << differ << " of " << a.count() << " silhouette pixels differ\n";
    EXPECT_LE(differ, 2) << "azimuth " << az << ", " << a.count() << " pixels";
    EXPECT_GT(a.count(), 200);
  }
  EXPECT_THROW(coarseGridTriangles(g, 0), std::invalid_argument);
}

// Golden cases of the rasterisation rule: pixel centres inside a triangle are covered, and every row whose
// centre line crosses a triangle gets at least the pixel under the span's midpoint.
TEST(Raster, PixelCentresInsideAndOnePixelPerCrossedRow) {
  std::vector<std::uint8_t> canvas;
  // Right triangle with legs of 4 px: rows cover 4, 3, 2, 1 pixels from the left.
  detail::rasterTriangles({Vec2(0, 0), Vec2(4, 0), Vec2(0, 4)}, {{0, 1, 2}}, 6, 6, canvas);
  const int expected_row_width[6] = {4, 3, 2, 1, 0, 0};
  for (int r = 0; r < 6; ++r) {
    int n = 0;
    for (int c = 0; c < 6; ++c) n += canvas[static_cast<std::size_t>(r * 6 + c)];
    EXPECT_EQ(n, expected_row_width[r]) << "row " << r;
    for (int c = 0; c < expected_row_width[r]; ++c) EXPECT_EQ(canvas[static_cast<std::size_t>(r * 6 + c)], 1);
  }
  // A sliver 0.2 px wide between x = 2.6 and 2.8 covers no pixel centre: one pixel per row (x = 2).
  detail::rasterTriangles({Vec2(2.6, 0), Vec2(2.8, 0), Vec2(2.7, 5)}, {{0, 1, 2}}, 6, 6, canvas);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) EXPECT_EQ(canvas[static_cast<std::size_t>(r * 6 + c)], r < 5 && c == 2) << r << "," << c;
  // A flat triangle on a row's centre line (y = 1.5) leaves that row's span; one off the centre lines nothing.
  detail::rasterTriangles({Vec2(0.2, 1.5), Vec2(3.9, 1.5), Vec2(2, 1.5)}, {{0, 1, 2}}, 6, 6, canvas);
  int n = 0;
  for (std::uint8_t v : canvas) n += v;
  EXPECT_EQ(n, 4);  // row 1, centres 0.5 ... 3.5 lie in [0.2, 3.9]
  EXPECT_EQ(canvas[6 + 0] + canvas[6 + 1] + canvas[6 + 2] + canvas[6 + 3], 4);
  detail::rasterTriangles({Vec2(0.2, 1.2), Vec2(3.9, 1.2), Vec2(2, 1.2)}, {{0, 1, 2}}, 6, 6, canvas);
  n = 0;
  for (std::uint8_t v : canvas) n += v;
  EXPECT_EQ(n, 0);
}

// renderSilhouette rasterises only the band of rows and columns the mesh covers; the mask equals the one
// from the whole canvas, and the 4 x 4 box filter equals the plain sum.
TEST(Raster, BandOfTheMeshEqualsTheWholeCanvas) {
  Sheet s = flatSheet(0.40, 0.50, 0.01);
  for (Index i = 0; i < s.x.size() / 3; ++i) {  // crumple it: folds towards the camera and sideways
    Vec3 p = node3(s.x, i);
    p.y() += 0.08 * std::sin(17.0 * p.x()) * std::cos(9.0 * p.z());
    p.x() += 0.05 * std::sin(11.0 * p.z());
    node3(s.x, i) = p;
  }
  const CanonicalFrame f;
  for (double az : {0.0, 35.0, 90.0, 200.0}) {
    const BitMask banded = renderSilhouette(s.x, s.tris, s.hold, az, SilhouetteProjection::pinhole({}, 1.6, 0.3), f);
    // The same mapping by hand: pinhole view, whole canvas, plain box filter.
    std::vector<Vec2> pts;
    for (Index i = 0; i < s.x.size() / 3; ++i) pts.push_back(canonicalPixel(node3(s.x, i), s.hold, az, SilhouetteProjection::pinhole({}, 1.6, 0.3), f) * f.supersample);
    std::vector<std::uint8_t> canvas;
    const int ss = f.supersample;
    detail::rasterTriangles(pts, s.tris, f.width_px * ss, f.height_px * ss, canvas);
    BitMask whole(f.width_px, f.height_px);
    const int need = static_cast<int>(std::ceil(f.coverage_threshold * ss * ss - 1e-9));
    for (int y = 0; y < f.height_px; ++y)
      for (int x = 0; x < f.width_px; ++x) {
        int c = 0;
        for (int sy = 0; sy < ss; ++sy)
          for (int sx = 0; sx < ss; ++sx) c += canvas[static_cast<std::size_t>((y * ss + sy) * f.width_px * ss + x * ss + sx)];
        if (c >= std::max(1, need)) whole.set(x, y);
      }
    EXPECT_GT(whole.count(), 100u) << az;
    EXPECT_EQ(banded, whole) << "azimuth " << az;
    EXPECT_EQ(detail::downsampleCoverage(canvas, f.width_px, f.height_px, ss, f.coverage_threshold), whole) << az;
  }
}

TEST(SilhouetteRenderer, FlatSheetHasMetricSizeWithHoldPointAtTopCentre) {
  const Sheet s = flatSheet(0.40, 0.50, 0.01);
  const CanonicalFrame f;  // 64 x 64 px, 1/64 m per px, hold point at (32, 2)
  const BitMask m = renderSilhouette(s.x, s.tris, s.hold, 0.0, SilhouetteProjection::orthographic(), f);
  int x0, y0, x1, y1;
  ASSERT_TRUE(m.boundingBox(&x0, &y0, &x1, &y1));
  // 0.40 m = 25.6 px centred on x = 32 -> [19.2, 44.8]; 0.50 m = 32 px below y = 2.
  EXPECT_EQ(x0, 19);
  EXPECT_EQ(x1, 45);
  EXPECT_EQ(y0, 2);
  EXPECT_EQ(y1, 34);
  EXPECT_NEAR(static_cast<double>(m.count()), 25.6 * 32, 0.06 * 25.6 * 32);
  // Metric scale kept: the same sheet in a frame of half the resolution is half as many pixels wide.
  CanonicalFrame coarse = CanonicalFrame::fromMetric(1.0, 1.0, 32);
  coarse.top_margin_px = 1.0;
  const BitMask mc = renderSilhouette(s.x, s.tris, s.hold, 0.0, {}, coarse);
  ASSERT_TRUE(mc.boundingBox(&x0, &y0, &x1, &y1));
  EXPECT_NEAR(x1 - x0, 13, 1);
  EXPECT_NEAR(y1 - y0, 16, 1);
  EXPECT_EQ(y0, 1);
  // Moving the whole sheet (and hold point) in the world does not change the canonical mask.
  Sheet moved = s;
  for (Index i = 0; i < moved.x.size() / 3; ++i) node3(moved.x, i) += Vec3(0.3, -0.2, 0.5);
  EXPECT_EQ(renderSilhouette(moved.x, moved.tris, Vec3(s.hold + Vec3(0.3, -0.2, 0.5)), 0.0), m);
}

TEST(SilhouetteRenderer, EdgeOnSheetIsAThinSliver) {
  const Sheet s = flatSheet(0.40, 0.50, 0.01);
  const BitMask face = renderSilhouette(s.x, s.tris, s.hold, 0.0);
  const BitMask edge = renderSilhouette(s.x, s.tris, s.hold, 90.0);
  int x0, y0, x1, y1;
  ASSERT_TRUE(edge.boundingBox(&x0, &y0, &x1, &y1));
  EXPECT_LE(x1 - x0, 2);
  EXPECT_NEAR(y1 - y0, 32, 1);
  EXPECT_LT(edge.count(), face.count() / 10);
  // 180 deg shows the mirrored sheet, identical for a symmetric sheet.
  EXPECT_EQ(renderSilhouette(s.x, s.tris, s.hold, 180.0), face);
  // 60 deg: projected width 0.40 * cos(60 deg) = 0.2 m = 12.8 px.
  const BitMask oblique = renderSilhouette(s.x, s.tris, s.hold, 60.0);
  ASSERT_TRUE(oblique.boundingBox(&x0, &y0, &x1, &y1));
  EXPECT_NEAR(x1 - x0, 13.5, 1.0);
}

TEST(SilhouetteRenderer, HoldPointMapsToTopCentreInBothProjections) {
  const Vec3 hold(0.1, -0.3, 1.2);
  const PinholeIntrinsics k;
  for (double a : {0.0, 37.0, 200.0}) {
    const Vec2 po = canonicalPixel(hold, hold, a);
    EXPECT_NEAR(po.x(), 32.0, 1e-12);
    EXPECT_NEAR(po.y(), 2.0, 1e-12);
    const Vec2 pp = canonicalPixel(hold, hold, a, SilhouetteProjection::pinhole(k, 1.5, -0.4));
    EXPECT_NEAR(pp.x(), 32.0, 1e-9);
    EXPECT_NEAR(pp.y(), 2.0, 1e-9);
  }
  // A point 0.5 m below the hold point is 32 px lower (orthographic), and the view's right is +x at 0 deg.
  EXPECT_NEAR(canonicalPixel(hold + Vec3(0, 0, -0.5), hold, 0.0).y(), 34.0, 1e-9);
  EXPECT_NEAR(canonicalPixel(hold + Vec3(0.25, 0, 0), hold, 0.0).x(), 48.0, 1e-9);
  EXPECT_NEAR(canonicalPixel(hold + Vec3(0.25, 0, 0), hold, 90.0).x(), 32.0, 1e-9);
  EXPECT_NEAR(canonicalPixel(hold + Vec3(0, 0.25, 0), hold, 90.0).x(), 48.0, 1e-9);
  // Pinhole: a point nearer to the camera looks bigger than at the hold point's depth.
  const auto pin = SilhouetteProjection::pinhole(k, 1.0);
  const double near_x = canonicalPixel(hold + Vec3(0.25, -0.2, 0), hold, 0.0, pin).x();  // 0.2 m nearer
  EXPECT_NEAR(near_x, 32.0 + 16.0 / 0.8, 1e-9);
}

TEST(SilhouetteRenderer, OrthographicAndPinholeAgreeAtLargeDistance) {
  HangingShapeParams p;  // towel held at a corner, folded in 3-D
  const SyntheticMesh mesh = syntheticHangingMesh(p);
  const PinholeIntrinsics k;
  for (double a : {0.0, 50.0, 130.0}) {
    const BitMask o = renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, a);
    const BitMask far =
        renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, a, SilhouetteProjection::pinhole(k, 500.0));
    EXPECT_GT(iou(o, far), 0.97) << "angle " << a;
    const BitMask nearby =
        renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, a, SilhouetteProjection::pinhole(k, 1.0, -0.3));
    EXPECT_LT(iou(o, nearby), iou(o, far)) << "perspective should matter at 1 m";
  }
}

TEST(SilhouetteRenderer, RenderViewsDefaultsToThirtySixViews) {
  HangingShapeParams p;
  p.spacing = 0.04;
  const SyntheticMesh mesh = syntheticHangingMesh(p);
  const auto views = renderViews(mesh.positions, mesh.triangles, mesh.hold);
  ASSERT_EQ(views.size(), 36u);
  for (std::size_t i = 0; i < views.size(); ++i) {
    EXPECT_DOUBLE_EQ(views[i].view_angle_deg, 10.0 * i);
    EXPECT_EQ(views[i].mask.width(), 64);
    EXPECT_GT(views[i].mask.count(), 0);
  }
  // Hold particle overload gives the same mask as the hold position.
  EXPECT_EQ(renderSilhouette(mesh.positions, mesh.triangles, mesh.hold_vertex, 20.0),
            renderSilhouette(mesh.positions, mesh.triangles, Vec3(node3(mesh.positions, mesh.hold_vertex)), 20.0));
}

TEST(SilhouetteRenderer, CanonicalisedCameraRenderMatchesDirectRender) {
  HangingShapeParams p;
  p.spacing = 0.01;
  const SyntheticMesh mesh = syntheticHangingMesh(p);
  PinholeIntrinsics k;  // 640 x 480, f = 525 px
  const double distance = 1.5, height = -0.35;
  for (double a : {0.0, 70.0, 240.0}) {
    ShadedRenderOptions o;
    o.intrinsics = k;
    o.camera = cameraPoseForView(mesh.hold, a, distance, height);
    const ShadedImage img = renderShaded(mesh.positions, mesh.triangles, o);
    Vec2 hold_px;
    double depth = 0;
    ASSERT_TRUE(projectPoint(k, o.camera, mesh.hold, &hold_px, &depth));
    EXPECT_NEAR(depth, distance, 1e-12);
    const BitMask from_camera = canonicaliseCameraMask(img.mask, hold_px, metresPerPixelAtDepth(k, depth));
    const BitMask direct = renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, a,
                                            SilhouetteProjection::pinhole(k, distance, height));
    EXPECT_GT(iou(from_camera, direct), 0.9) << "angle " << a << "\n" << from_camera.toString() << "\n" << direct.toString();
    EXPECT_GE(bestShiftIou(from_camera, direct, 2, 2).score, iou(from_camera, direct));
  }
}

TEST(SilhouetteRenderer, CanonicaliseCameraMaskKeepsMetricSize) {
  // A 200 x 300 px rectangle at 2 mm per pixel = 0.4 x 0.6 m, hold point at its top centre.
  cv::Mat cam(480, 640, CV_8UC1, cv::Scalar(0));
  cam(cv::Rect(220, 100, 200, 300)).setTo(255);
  const Vec2 hold(319.5, 99.5);  // pixel centres at integers: the top edge is at y = 99.5
  const BitMask m = canonicaliseCameraMask(cam, hold, Vec2(0.002, 0.002));
  int x0, y0, x1, y1;
  ASSERT_TRUE(m.boundingBox(&x0, &y0, &x1, &y1));
  // 0.4 m = 25.6 px centred at 32; 0.6 m = 38.4 px below y = 2.
  EXPECT_EQ(x0, 19);
  EXPECT_EQ(x1, 45);
  EXPECT_EQ(y0, 2);
  EXPECT_EQ(y1, 41);
  const cv::Mat cov = canonicalCoverage(cam, hold, Vec2(0.002, 0.002));
  EXPECT_NEAR(cov.at<float>(10, 32), 1.0f, 1e-5f);
  EXPECT_NEAR(cov.at<float>(10, 19), 0.8f, 1e-4f);  // pixel [19, 20) is 80 % inside [19.2, 44.8]
  EXPECT_NEAR(cov.at<float>(10, 5), 0.0f, 1e-6f);
  EXPECT_NEAR(cv::sum(cov)[0], 25.6 * 38.4, 1e-2);
}

TEST(SilhouetteRenderer, BadInputGivesClearErrors) {
  const Sheet s = flatSheet(0.2, 0.2, 0.05);
  auto expectThrow = [](auto&& fn, const std::string& part) {
    try {
      fn();
      ADD_FAILURE() << "expected std::invalid_argument containing '" << part << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(contains(e.what(), part)) << e.what();
    }
  };
  VecX nan_x = s.x;
  nan_x[7] = std::numeric_limits<double>::quiet_NaN();
  expectThrow([&] { renderSilhouette(nan_x, s.tris, s.hold, 0.0); }, "not finite");
  expectThrow([&] { renderSilhouette(VecX(7), s.tris, s.hold, 0.0); }, "3 values per vertex");
  expectThrow([&] { renderSilhouette(s.x, {}, s.hold, 0.0); }, "no triangles");
  expectThrow([&] { renderSilhouette(s.x, {Triangle{{0, 1, 999}}}, s.hold, 0.0); }, "outside");
  expectThrow([&] { renderSilhouette(s.x, s.tris, Vec3(0, std::nan(""), 0), 0.0); }, "hold point");
  expectThrow([&] { renderSilhouette(s.x, s.tris, s.hold, std::nan("")); }, "view angle");
  expectThrow([&] { renderSilhouette(s.x, s.tris, Index(-1), 0.0); }, "hold particle");
  ViewSet none;
  none.count = 0;
  expectThrow([&] { renderViews(s.x, s.tris, s.hold, none); }, "count");
  CanonicalFrame bad;
  bad.width_px = 0;
  expectThrow([&] { renderSilhouette(s.x, s.tris, s.hold, 0.0, {}, bad); }, "CanonicalFrame");
  bad = CanonicalFrame();
  bad.coverage_threshold = 0;
  expectThrow([&] { renderSilhouette(s.x, s.tris, s.hold, 0.0, {}, bad); }, "coverage_threshold");
  // Pinhole camera inside the textile's reach.
  // (at 90 deg the sheet, in the x-z plane, points at the camera and reaches 0.1 m towards it)
  expectThrow([&] { renderSilhouette(s.x, s.tris, s.hold, 90.0, SilhouetteProjection::pinhole({}, 0.05)); },
              "behind or too close");
  expectThrow([&] { renderSilhouette(s.x, s.tris, s.hold, 0.0, SilhouetteProjection::pinhole({}, -1.0)); },
              "camera_distance");
  // Camera masks.
  expectThrow([&] { canonicaliseCameraMask(cv::Mat(), Vec2(1, 1), Vec2(0.01, 0.01)); }, "empty");
  expectThrow([&] { canonicaliseCameraMask(cv::Mat(4, 4, CV_32FC1), Vec2(1, 1), Vec2(0.01, 0.01)); }, "CV_8UC1");
  expectThrow([&] { canonicaliseCameraMask(cv::Mat(4, 4, CV_8UC1), Vec2(1, 1), Vec2(0, 0.01)); }, "metres_per_pixel");
  expectThrow([&] { canonicaliseCameraMask(cv::Mat(4, 4, CV_8UC1), Vec2(std::nan(""), 1), Vec2(0.01, 0.01)); },
              "hold pixel");
  expectThrow([&] { metresPerPixelAtDepth(PinholeIntrinsics{}, 0.0); }, "depth");
}

}  // namespace
}  // namespace vision
}  // namespace textile_handling
