// Segmentation of the held textile: encodings, background models, the component at the hold point,
// morphology, depth crop box + clustering (organised depth image and PCL point cloud), bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include <opencv2/imgproc.hpp>

#include "recognition_test_support.h"
#include "textile_handling/recognition/point_cloud_segmentation.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/recognition/segmentation.h"
#include "textile_handling/bench/match_benchmark.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;
using textile_handling::test_support::throwsCode;
using textile_handling::test_support::vga;

namespace {

double maskIou(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat i, u;
  cv::bitwise_and(a, b, i);
  cv::bitwise_or(a, b, u);
  return static_cast<double>(cv::countNonZero(i)) / std::max(1, cv::countNonZero(u));
}

// A horizontal camera 1.5 m from the hold point (0, 0, 1) at azimuth 20 deg.
struct Scene {
  vision::CameraPose pose;
  HoldGeometry g;
  vision::SyntheticMesh mesh;
};

Scene scene() {
  Scene s;
  vision::HangingShapeParams hp;
  hp.width = 0.5;
  hp.height = 0.36;
  hp.hold_u = 0.1;
  hp.hold_v = 0.36;
  s.mesh = vision::syntheticHangingMesh(hp, Vec3(0, 0, 1));
  s.pose = vision::cameraPoseForView(s.mesh.hold, 20.0, 1.5, -0.2);
  s.g = computeHoldGeometry(vga(), s.pose.toCamera(s.mesh.hold), s.pose.rotation.transpose() * Vec3::UnitZ(),
                            s.pose.rotation.transpose() * Vec3::UnitX());
  return s;
}

vision::ShadedImage render(const Scene& s, const VecX& x, const std::vector<vision::Triangle>& tris,
                           vision::BackgroundType bg = vision::BackgroundType::kUniform,
                           std::array<std::uint8_t, 3> bg_bgr = {{235, 235, 235}}) {
  vision::ShadedRenderOptions ro;
  ro.intrinsics = vga();
  ro.camera = s.pose;
  ro.noise_sigma = 3.0;
  ro.background = bg;
  ro.background_bgr = bg_bgr;
  return vision::renderShaded(x, tris, ro);
}

// The scene's mesh plus a second (clutter) copy moved by `offset`.
void withClutter(const Scene& s, const Vec3& offset, VecX* x, std::vector<vision::Triangle>* tris) {
  const Eigen::Index n = s.mesh.positions.size();
  x->resize(2 * n);
  x->head(n) = s.mesh.positions;
  for (Eigen::Index k = 0; k < n / 3; ++k) x->segment<3>(n + 3 * k) = s.mesh.positions.segment<3>(3 * k) + offset;
  *tris = s.mesh.triangles;
  const Index shift = static_cast<Index>(n / 3);
  for (const auto& t : s.mesh.triangles) tris->push_back({t[0] + shift, t[1] + shift, t[2] + shift});
}

}  // namespace

TEST(Segmentation, Encodings) {
  cv::Mat bgr(4, 5, CV_8UC3, cv::Scalar(10, 20, 30));
  EXPECT_EQ(toBgr8(bgr, "bgr8").at<cv::Vec3b>(0, 0), cv::Vec3b(10, 20, 30));
  cv::Mat rgb(4, 5, CV_8UC3, cv::Scalar(30, 20, 10));
  EXPECT_EQ(toBgr8(rgb, "rgb8").at<cv::Vec3b>(1, 1), cv::Vec3b(10, 20, 30));
  cv::Mat mono(4, 5, CV_8UC1, cv::Scalar(77));
  EXPECT_EQ(toBgr8(mono, "mono8").at<cv::Vec3b>(2, 3), cv::Vec3b(77, 77, 77));
  for (const char* e : {"bgra8", "rgb16", "mono16", "32FC1", "yuv422", "", "BGR8"})
    EXPECT_TRUE(throwsCode([&] { toBgr8(bgr, e); }, RecognitionErrorCode::kUnsupportedEncoding)) << e;
  EXPECT_TRUE(throwsCode([&] { toBgr8(mono, "bgr8"); }, RecognitionErrorCode::kInvalidImage));
  EXPECT_TRUE(throwsCode([&] { toBgr8(bgr, "mono8"); }, RecognitionErrorCode::kInvalidImage));
  EXPECT_TRUE(throwsCode([&] { toBgr8(cv::Mat(4, 5, CV_16UC3), "rgb8"); }, RecognitionErrorCode::kInvalidImage));
  EXPECT_TRUE(throwsCode([&] { toBgr8(cv::Mat(), "bgr8"); }, RecognitionErrorCode::kInvalidImage));
}

TEST(Segmentation, EnumNamesRoundTrip) {
  for (BackgroundModel m : {BackgroundModel::kUniformColour, BackgroundModel::kBorderMedian, BackgroundModel::kBackgroundImage})
    EXPECT_EQ(backgroundModelFromString(toString(m)), m);
  for (ColourSpace c : {ColourSpace::kBgr, ColourSpace::kLab, ColourSpace::kAb}) EXPECT_EQ(colourSpaceFromString(toString(c)), c);
  for (DepthMode d : {DepthMode::kColourOnly, DepthMode::kGate, DepthMode::kIntersect, DepthMode::kDepthOnly})
    EXPECT_EQ(depthModeFromString(toString(d)), d);
  EXPECT_STREQ(toString(BackgroundModel::kBorderMedian), "border_median");
  std::string msg;
  EXPECT_TRUE(throwsCode([] { depthModeFromString("Gate"); }, RecognitionErrorCode::kInvalidOptions, &msg));
  EXPECT_NE(msg.find("depth_mode 'Gate'"), std::string::npos) << msg;
  EXPECT_NE(msg.find("colour_only, gate, intersect, depth_only"), std::string::npos) << msg;
  EXPECT_TRUE(throwsCode([] { colourSpaceFromString(""); }, RecognitionErrorCode::kInvalidOptions));
  EXPECT_TRUE(throwsCode([] { backgroundModelFromString("green"); }, RecognitionErrorCode::kInvalidOptions));
}

TEST(Segmentation, DepthUnits) {
  cv::Mat mm(2, 2, CV_16UC1);
  mm.at<std::uint16_t>(0, 0) = 1500;
  mm.at<std::uint16_t>(0, 1) = 0;
  mm.at<std::uint16_t>(1, 0) = 1;
  mm.at<std::uint16_t>(1, 1) = 65535;
  const cv::Mat m = depthToMetres(mm);
  EXPECT_FLOAT_EQ(m.at<float>(0, 0), 1.5f);
  EXPECT_TRUE(std::isnan(m.at<float>(0, 1)));
  EXPECT_FLOAT_EQ(m.at<float>(1, 0), 0.001f);
  cv::Mat f(1, 4, CV_32FC1);
  f.at<float>(0, 0) = 2.0f;
  f.at<float>(0, 1) = -1.0f;
  f.at<float>(0, 2) = std::numeric_limits<float>::infinity();
  f.at<float>(0, 3) = 0.0f;
  const cv::Mat fm = depthToMetres(f);
  EXPECT_FLOAT_EQ(fm.at<float>(0, 0), 2.0f);
  for (int x = 1; x < 4; ++x) EXPECT_TRUE(std::isnan(fm.at<float>(0, x)));
  EXPECT_TRUE(throwsCode([] { depthToMetres(cv::Mat(2, 2, CV_8UC1)); }, RecognitionErrorCode::kInvalidDepth));
  EXPECT_TRUE(throwsCode([] { depthToMetres(cv::Mat(2, 2, CV_64FC1)); }, RecognitionErrorCode::kInvalidDepth));
  EXPECT_TRUE(throwsCode([] { depthToMetres(cv::Mat()); }, RecognitionErrorCode::kInvalidDepth));
}

TEST(Segmentation, KeepsTheComponentAtTheHoldPoint) {
  const Scene s = scene();
  VecX x;
  std::vector<vision::Triangle> tris;
  withClutter(s, 0.8 * vision::viewRight(20.0), &x, &tris);  // a second textile beside it
  const vision::ShadedImage img = render(s, x, tris);
  const vision::ShadedImage truth = render(s, s.mesh.positions, s.mesh.triangles);
  const SegmentationResult r = segmentTextile(img.bgr, "bgr8", s.g);
  EXPECT_GE(r.components, 2);
  EXPECT_NEAR(r.hold_distance_px, 0.0, 3.0);
  EXPECT_GT(maskIou(r.mask, truth.mask), 0.97);
  EXPECT_EQ(r.area_px, cv::countNonZero(r.mask));
  EXPECT_FALSE(r.used_depth);
  // The same from rgb8 and mono8 images.
  cv::Mat rgb, mono;
  cv::cvtColor(img.bgr, rgb, cv::COLOR_BGR2RGB);
  cv::cvtColor(img.bgr, mono, cv::COLOR_BGR2GRAY);
  EXPECT_EQ(cv::countNonZero(segmentTextile(rgb, "rgb8", s.g).mask != r.mask), 0);
  EXPECT_GT(maskIou(segmentTextile(mono, "mono8", s.g).mask, truth.mask), 0.95);
  // Nothing near the hold point, or too little of it: clear errors.
  SegmentationOptions o;
  o.min_area_px = 1000000;
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", s.g, o); }, RecognitionErrorCode::kSegmentationFailed));
  HoldGeometry far = s.g;
  far.hold_pixel += Vec2(0, -120);
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", far); }, RecognitionErrorCode::kSegmentationFailed));
  cv::Mat small;
  cv::resize(img.bgr, small, cv::Size(320, 240));
  EXPECT_TRUE(throwsCode([&] { segmentTextile(small, "bgr8", s.g); }, RecognitionErrorCode::kInvalidImage));
  o = SegmentationOptions();
  o.threshold = -1;
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", s.g, o); }, RecognitionErrorCode::kInvalidOptions));
  o = SegmentationOptions();
  o.background = BackgroundModel::kBackgroundImage;  // without a background image
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", s.g, o); }, RecognitionErrorCode::kInvalidOptions));
}

TEST(Segmentation, BackgroundModels) {
  const Scene s = scene();
  const std::array<std::uint8_t, 3> green{{60, 170, 60}};
  const vision::ShadedImage img = render(s, s.mesh.positions, s.mesh.triangles, vision::BackgroundType::kUniform, green);
  // The default model expects a light grey backdrop: everything is "textile", the component is huge.
  const SegmentationResult wrong = segmentTextile(img.bgr, "bgr8", s.g);
  EXPECT_LT(maskIou(wrong.mask, img.mask), 0.5);
  SegmentationOptions o;
  o.background = BackgroundModel::kBorderMedian;
  EXPECT_GT(maskIou(segmentTextile(img.bgr, "bgr8", s.g, o).mask, img.mask), 0.97);
  o = SegmentationOptions();
  o.background_bgr = green;
  o.colour_space = ColourSpace::kLab;
  o.threshold = 30;
  EXPECT_GT(maskIou(segmentTextile(img.bgr, "bgr8", s.g, o).mask, img.mask), 0.97);
  // A textured background and a picture of the empty scene.
  const vision::ShadedImage tex = render(s, s.mesh.positions, s.mesh.triangles, vision::BackgroundType::kNoiseTexture);
  VecX none = s.mesh.positions;
  for (Eigen::Index k = 0; k < none.size() / 3; ++k) none[3 * k + 1] += 100.0;  // out of view
  vision::ShadedRenderOptions ro;
  ro.intrinsics = vga();
  ro.camera = s.pose;
  ro.noise_sigma = 3.0;
  ro.background = vision::BackgroundType::kNoiseTexture;
  ro.seed = 1;
  const cv::Mat empty = vision::renderShaded(none, s.mesh.triangles, ro).bgr;
  o = SegmentationOptions();
  o.background = BackgroundModel::kBackgroundImage;
  o.background_image = empty;
  o.threshold = 40;
  EXPECT_GT(maskIou(segmentTextile(tex.bgr, "bgr8", s.g, o).mask, tex.mask), 0.95);
  o.background_image = cv::Mat(10, 10, CV_8UC3);
  EXPECT_TRUE(throwsCode([&] { segmentTextile(tex.bgr, "bgr8", s.g, o); }, RecognitionErrorCode::kInvalidImage));
}

// A shadow on the backdrop next to the textile: lightness changes, chromaticity does not.
TEST(Segmentation, ChromaticityIgnoresShadows) {
  const Scene s = scene();
  const vision::ShadedImage img = render(s, s.mesh.positions, s.mesh.triangles);
  cv::Mat shadowed = img.bgr.clone();
  // The shadow hugs the textile's lower half: the band of 12 px around it, background pixels only.
  cv::Mat band;
  cv::dilate(img.mask, band, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(25, 25)));
  const cv::Rect box = cv::boundingRect(img.mask);
  band(cv::Rect(0, 0, band.cols, box.y + box.height / 2)).setTo(0);
  band.setTo(0, img.mask);
  cv::Mat darker;
  img.bgr.convertTo(darker, -1, 0.55, 0);
  darker.copyTo(shadowed, band);
  const SegmentationResult bgr = segmentTextile(shadowed, "bgr8", s.g);
  SegmentationOptions o;
  o.colour_space = ColourSpace::kAb;
  o.threshold = 15;
  const SegmentationResult ab = segmentTextile(shadowed, "bgr8", s.g, o);
  EXPECT_LT(maskIou(bgr.mask, img.mask), 0.9);  // the shadow joins the textile
  EXPECT_GT(maskIou(ab.mask, img.mask), 0.95);
}

TEST(Segmentation, DepthCropBoxAndClusterRemoveClutter) {
  const Scene s = scene();
  // Clutter of the textile's colour 0.8 m behind it (more than the cluster tolerance of 10 cm from every
  // point of it), overlapping it in the image.
  VecX x;
  std::vector<vision::Triangle> tris;
  withClutter(s, 0.8 * vision::viewDirection(20.0) + 0.3 * vision::viewRight(20.0) + Vec3(0, 0, -0.1), &x, &tris);
  const vision::ShadedImage img = render(s, x, tris);
  const vision::ShadedImage truth = render(s, s.mesh.positions, s.mesh.triangles);
  const SegmentationResult colour = segmentTextile(img.bgr, "bgr8", s.g);
  EXPECT_LT(maskIou(colour.mask, truth.mask), 0.8);  // the clutter touches the textile in the image
  int points = 0;
  const DepthSegmentationOptions d;
  const cv::Mat cluster = depthClusterMask(img.depth, s.g, d, &points);
  EXPECT_GT(points, 1000);
  const SegmentationResult gated = segmentTextile(img.bgr, "bgr8", s.g, SegmentationOptions(), cluster, points);
  EXPECT_TRUE(gated.used_depth);
  EXPECT_EQ(gated.depth_points, points);
  EXPECT_GT(maskIou(gated.mask, truth.mask), 0.97);
  SegmentationOptions depth_only;
  depth_only.depth_mode = DepthMode::kDepthOnly;
  EXPECT_GT(maskIou(segmentTextile(img.bgr, "bgr8", s.g, depth_only, cluster, points).mask, truth.mask), 0.97);
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", s.g, depth_only); }, RecognitionErrorCode::kInvalidDepth));
  // Millimetre depth gives the same cluster up to quantisation.
  cv::Mat mm(img.depth.size(), CV_16UC1, cv::Scalar(0));
  for (int yy = 0; yy < mm.rows; ++yy)
    for (int xx = 0; xx < mm.cols; ++xx) {
      const float z = img.depth.at<float>(yy, xx);
      if (std::isfinite(z)) mm.at<std::uint16_t>(yy, xx) = static_cast<std::uint16_t>(std::lround(z * 1000));
    }
  EXPECT_GT(maskIou(depthClusterMask(mm, s.g, d), cluster), 0.99);
  // The same with an unorganised point cloud through PCL (CropBox + EuclideanClusterExtraction).
  int cloud_points = 0;
  const cv::Mat from_cloud = pointCloudClusterMask(depthImageToPoints(img.depth, vga()), s.g, d, &cloud_points);
  EXPECT_NEAR(cloud_points, points, 0.02 * points);
  EXPECT_GT(maskIou(from_cloud, truth.mask), 0.95);
  // A crop box that excludes the textile, a wrongly placed hold point, bad data: clear errors.
  DepthSegmentationOptions tight = d;
  tight.max_drop_m = 0.01;
  tight.top_m = -0.005;
  EXPECT_TRUE(throwsCode([&] { depthClusterMask(img.depth, s.g, tight); }, RecognitionErrorCode::kSegmentationFailed));
  EXPECT_TRUE(throwsCode([&] { pointCloudClusterMask(depthImageToPoints(img.depth, vga()), s.g, tight); },
                         RecognitionErrorCode::kSegmentationFailed));
  HoldGeometry moved = computeHoldGeometry(vga(), s.g.hold_camera + Vec3(0.3, 0, 0), s.g.up_camera);
  EXPECT_TRUE(throwsCode([&] { depthClusterMask(img.depth, moved, d); }, RecognitionErrorCode::kSegmentationFailed));
  EXPECT_TRUE(throwsCode([&] { depthClusterMask(cv::Mat(240, 320, CV_32FC1, cv::Scalar(1.0f)), s.g, d); },
                         RecognitionErrorCode::kInvalidDepth));
  EXPECT_TRUE(throwsCode([&] { pointCloudClusterMask({Vec3(std::nan(""), 0, 1)}, s.g, d); }, RecognitionErrorCode::kInvalidDepth));
  DepthSegmentationOptions bad = d;
  bad.cluster_tolerance_m = 0;
  EXPECT_TRUE(throwsCode([&] { depthClusterMask(img.depth, s.g, bad); }, RecognitionErrorCode::kInvalidOptions));
  EXPECT_TRUE(throwsCode([&] { segmentTextile(img.bgr, "bgr8", s.g, SegmentationOptions(), cv::Mat(10, 10, CV_8UC1)); },
                         RecognitionErrorCode::kInvalidDepth));
}
