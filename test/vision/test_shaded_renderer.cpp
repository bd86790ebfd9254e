// Tests for the shaded renderer of synthetic camera images.
#include "textile_handling/vision/shaded_renderer.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "textile_handling/bench/match_benchmark.h"

namespace textile_handling {
namespace vision {
namespace {

ShadedRenderOptions baseOptions(const SyntheticMesh& mesh) {
  ShadedRenderOptions o;
  o.camera = cameraPoseForView(mesh.hold, 30.0, 1.5, -0.35);
  o.noise_sigma = 4.0;
  o.seed = 42;
  return o;
}

SyntheticMesh towel() {
  HangingShapeParams p;
  p.spacing = 0.02;
  return syntheticHangingMesh(p);
}

double maxAbsDiff(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_INF); }

TEST(CameraPose, LookAtIsARightHandedOpticalFrame) {
  const CameraPose p = CameraPose::lookAt(Vec3(0, -2, 1), Vec3(0, 0, 1));
  EXPECT_NEAR((p.rotation.transpose() * p.rotation - Mat3::Identity()).norm(), 0, 1e-12);
  EXPECT_NEAR(p.rotation.determinant(), 1.0, 1e-12);
  EXPECT_NEAR((p.rotation.col(2) - Vec3(0, 1, 0)).norm(), 0, 1e-12);   // optical axis
  EXPECT_NEAR((p.rotation.col(0) - Vec3(1, 0, 0)).norm(), 0, 1e-12);   // image right
  EXPECT_NEAR((p.rotation.col(1) - Vec3(0, 0, -1)).norm(), 0, 1e-12);  // image down
  // cameraPoseForView(0 deg) is the same camera.
  const CameraPose v = cameraPoseForView(Vec3(0, 0, 1), 0.0, 2.0);
  EXPECT_NEAR((v.rotation - p.rotation).norm(), 0, 1e-12);
  EXPECT_NEAR((v.position - p.position).norm(), 0, 1e-12);
  EXPECT_THROW(CameraPose::lookAt(Vec3(0, 0, 0), Vec3(0, 0, 0)), std::invalid_argument);
  EXPECT_THROW(CameraPose::lookAt(Vec3(0, 0, 0), Vec3(0, 0, 1)), std::invalid_argument);  // along up
  Vec2 px;
  EXPECT_FALSE(projectPoint(PinholeIntrinsics{}, p, Vec3(0, -3, 1), &px));  // behind the camera
  ASSERT_TRUE(projectPoint(PinholeIntrinsics{}, p, Vec3(0, 0, 1), &px));
  EXPECT_NEAR(px.x(), 319.5, 1e-9);
  EXPECT_NEAR(px.y(), 239.5, 1e-9);
}

TEST(ShadedRenderer, DeterministicForASeed) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  o.background = BackgroundType::kNoiseTexture;
  const ShadedImage a = renderShaded(mesh.positions, mesh.triangles, o);
  const ShadedImage b = renderShaded(mesh.positions, mesh.triangles, o);
  ASSERT_EQ(a.bgr.type(), CV_8UC3);
  EXPECT_EQ(a.bgr.cols, 640);
  EXPECT_EQ(a.bgr.rows, 480);
  EXPECT_EQ(maxAbsDiff(a.bgr, b.bgr), 0.0);
  EXPECT_EQ(maxAbsDiff(a.mask, b.mask), 0.0);
  o.seed = 43;
  const ShadedImage c = renderShaded(mesh.positions, mesh.triangles, o);
  EXPECT_GT(maxAbsDiff(a.bgr, c.bgr), 0.0);  // other noise and texture
  EXPECT_EQ(maxAbsDiff(a.mask, c.mask), 0.0);  // same geometry
}

TEST(ShadedRenderer, BackgroundTextileDepthAndNoise) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  const ShadedImage img = renderShaded(mesh.positions, mesh.triangles, o);
  ASSERT_EQ(img.mask.type(), CV_8UC1);
  ASSERT_EQ(img.depth.type(), CV_32FC1);
  const int fg = cv::countNonZero(img.mask);
  EXPECT_GT(fg, 5000);
  EXPECT_LT(fg, 640 * 480 / 2);
  // Background: the configured colour plus zero-mean noise of the configured strength.
  cv::Scalar mean, stddev;
  cv::meanStdDev(img.bgr, mean, stddev, img.mask == 0);
  for (int ch = 0; ch < 3; ++ch) {
    EXPECT_NEAR(mean[ch], o.background_bgr[static_cast<std::size_t>(ch)], 0.5);
    EXPECT_NEAR(stddev[ch], o.noise_sigma, 0.5);
  }
  EXPECT_TRUE(std::isnan(img.depth.at<float>(0, 0)));
  // Textile: shaded cloth colour (never brighter than the cloth colour plus noise), depth near 1.5 m.
  cv::Scalar cm = cv::mean(img.bgr, img.mask);
  EXPECT_LT(cm[2], o.cloth_bgr[2] + 3.0);
  EXPECT_GT(cm[2], o.ambient * o.cloth_bgr[2] - 3.0);
  double dmin, dmax;
  cv::Mat depth_fg = img.depth.clone();
  depth_fg.setTo(1.5, img.mask == 0);
  cv::minMaxLoc(depth_fg, &dmin, &dmax);
  EXPECT_GT(dmin, 1.5 - 0.8);
  EXPECT_LT(dmax, 1.5 + 0.8);
  // The hold point is on the textile in the mask.
  Vec2 hp;
  ASSERT_TRUE(projectPoint(o.intrinsics, o.camera, mesh.hold, &hp));
  int near_hold = 0;
  for (int dy = 0; dy <= 6; ++dy)
    for (int dx = -3; dx <= 3; ++dx)
      near_hold += img.mask.at<std::uint8_t>(static_cast<int>(std::lround(hp.y())) + dy, static_cast<int>(std::lround(hp.x())) + dx) > 0;
  EXPECT_GT(near_hold, 0);
  // Without noise the background is exactly the colour.
  o.noise_sigma = 0;
  const ShadedImage clean = renderShaded(mesh.positions, mesh.triangles, o);
  EXPECT_EQ(clean.bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(o.background_bgr[0], o.background_bgr[1], o.background_bgr[2]));
}

TEST(ShadedRenderer, CheckerboardAndOptionalOutputs) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  o.noise_sigma = 0;
  o.background = BackgroundType::kCheckerboard;
  o.render_depth = false;
  o.render_mask = false;
  const ShadedImage img = renderShaded(mesh.positions, mesh.triangles, o);
  EXPECT_TRUE(img.depth.empty());
  EXPECT_TRUE(img.mask.empty());
  EXPECT_EQ(img.bgr.at<cv::Vec3b>(0, 0), cv::Vec3b(o.background_bgr[0], o.background_bgr[1], o.background_bgr[2]));
  EXPECT_EQ(img.bgr.at<cv::Vec3b>(0, 32), cv::Vec3b(o.background2_bgr[0], o.background2_bgr[1], o.background2_bgr[2]));
}

TEST(ShadedRenderer, DepthOnlyGivesTheSameDepthAndMaskWithoutColour) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  const ShadedImage full = renderShaded(mesh.positions, mesh.triangles, o);
  o.render_colour = false;
  const ShadedImage depth_only = renderShaded(mesh.positions, mesh.triangles, o);
  EXPECT_TRUE(depth_only.bgr.empty());
  ASSERT_FALSE(full.bgr.empty());
  ASSERT_EQ(depth_only.depth.size(), full.depth.size());
  ASSERT_EQ(depth_only.mask.size(), full.mask.size());
  // NaN where no textile in both: compare the masks, then the depth where there is textile.
  EXPECT_EQ(cv::countNonZero(depth_only.mask != full.mask), 0);
  EXPECT_GT(cv::countNonZero(full.mask), 1000);
  cv::Mat d_only, d_full;
  depth_only.depth.copyTo(d_only, full.mask);
  full.depth.copyTo(d_full, full.mask);
  d_only.setTo(0, full.mask == 0);
  d_full.setTo(0, full.mask == 0);
  EXPECT_EQ(maxAbsDiff(d_only, d_full), 0.0);
}

// The recognizer renders only the box a shape projects into: that crop shows what the full image shows there
// (up to pixel centres on a triangle edge, where shifting the principal point can round the other way), and
// nothing of the shape lies outside it.
TEST(ShadedRenderer, CropToTheProjectedBoxMatchesTheFullRender) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  o.render_colour = false;
  const ShadedImage full = renderShaded(mesh.positions, mesh.triangles, o);
  VecX camera_points(mesh.positions.size());
  for (Eigen::Index i = 0; i < mesh.positions.size() / 3; ++i)
    camera_points.segment<3>(3 * i) = o.camera.toCamera(mesh.positions.segment<3>(3 * i));
  const cv::Rect box = projectedBox(camera_points, o.intrinsics, 2);
  ASSERT_FALSE(box.empty());
  EXPECT_LT(box.area(), o.intrinsics.width * o.intrinsics.height / 2);
  EXPECT_EQ(cv::countNonZero(full.mask(box)), cv::countNonZero(full.mask));  // all of the shape is inside
  const ShadedImage crop = renderDepthCrop(camera_points, mesh.triangles, o.intrinsics, box, true);
  ASSERT_EQ(crop.mask.size(), box.size());
  const int differing = cv::countNonZero(crop.mask != full.mask(box));
  EXPECT_LE(differing, cv::countNonZero(full.mask) / 200) << differing << " pixels differ";
  // Points behind the camera only, or a box wholly outside the image: empty.
  VecX behind = camera_points;
  for (Eigen::Index i = 0; i < behind.size() / 3; ++i) behind(3 * i + 2) = -1.0;
  EXPECT_TRUE(projectedBox(behind, o.intrinsics, 2).empty());
  VecX beside = camera_points;
  for (Eigen::Index i = 0; i < beside.size() / 3; ++i) beside(3 * i) += 50.0;
  EXPECT_TRUE(projectedBox(beside, o.intrinsics, 2).empty());
}

TEST(ShadedRenderer, NearerSurfaceWins) {
  // Two parallel squares facing the camera; the nearer one (red) hides the farther one (blue).
  VecX x(24);
  const double d[2] = {1.0, 2.0};
  for (int s = 0; s < 2; ++s) {
    const double h = s == 0 ? 0.2 : 0.8;  // 105 px and 210 px half widths
    node3(x, 4 * s + 0) = Vec3(-h, d[s], -h);
    node3(x, 4 * s + 1) = Vec3(h, d[s], -h);
    node3(x, 4 * s + 2) = Vec3(h, d[s], h);
    node3(x, 4 * s + 3) = Vec3(-h, d[s], h);
  }
  std::vector<Triangle> tris = {{{4, 5, 6}}, {{4, 6, 7}}, {{0, 1, 2}}, {{0, 2, 3}}};  // far one first
  ShadedRenderOptions o;
  o.camera = CameraPose::lookAt(Vec3(0, 0, 0), Vec3(0, 1, 0));
  o.noise_sigma = 0;
  const ShadedImage img = renderShaded(x, tris, o);
  EXPECT_NEAR(img.depth.at<float>(240, 320), 1.0f, 1e-5f);
  EXPECT_NEAR(img.depth.at<float>(240, 320 + 150), 2.0f, 1e-5f);  // beyond the near square
}

TEST(ShadedRenderer, BadInputThrows) {
  const SyntheticMesh mesh = towel();
  ShadedRenderOptions o = baseOptions(mesh);
  ShadedRenderOptions bad = o;
  bad.intrinsics.width = 0;
  EXPECT_THROW(renderShaded(mesh.positions, mesh.triangles, bad), std::invalid_argument);
  bad = o;
  bad.noise_sigma = -1;
  EXPECT_THROW(renderShaded(mesh.positions, mesh.triangles, bad), std::invalid_argument);
  bad = o;
  bad.intrinsics.fx = 0;
  EXPECT_THROW(renderShaded(mesh.positions, mesh.triangles, bad), std::invalid_argument);
  VecX nan_x = mesh.positions;
  nan_x[0] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(renderShaded(nan_x, mesh.triangles, o), std::invalid_argument);
  EXPECT_THROW(renderShaded(mesh.positions, {}, o), std::invalid_argument);
  EXPECT_THROW(cameraPoseForView(mesh.hold, 0.0, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace vision
}  // namespace textile_handling
