// Camera geometry of the recogniser: hold pixel, scale, virtual horizontal camera, hold frame and camera
// azimuth; rectification of tilted / rolled cameras into the renderer's pinhole view; bad input.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "recognition_test_support.h"
#include "textile_handling/recognition/camera_geometry.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/vision/mask_cv.h"
#include "textile_handling/bench/match_benchmark.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;
using textile_handling::test_support::throwsCode;
using textile_handling::test_support::vga;

namespace {

struct View {
  vision::CameraPose pose;
  HoldGeometry g;
};

View viewOf(const vision::CameraPose& pose, const Vec3& hold, bool heading = true) {
  View v;
  v.pose = pose;
  v.g = computeHoldGeometry(vga(), pose.toCamera(hold), pose.rotation.transpose() * Vec3::UnitZ(),
                            heading ? std::optional<Vec3>(pose.rotation.transpose() * Vec3::UnitX()) : std::nullopt);
  return v;
}

}  // namespace

TEST(CameraGeometry, AzimuthConventions) {
  for (double a : {0.0, 10.0, 90.0, 137.5, 180.0, 271.0, 359.0}) {
    EXPECT_NEAR(azimuthOfDirection(vision::viewDirection(a)), a, 1e-9);
    EXPECT_LT((rotationZ(25.0) * vision::viewDirection(a) - vision::viewDirection(a + 25.0)).norm(), 1e-12);
  }
  EXPECT_NEAR(wrapDegrees(-10.0), 350.0, 1e-12);
  EXPECT_NEAR(wrapDegrees(725.0), 5.0, 1e-12);
}

TEST(CameraGeometry, HorizontalCameraIsTheRenderersPinholeCamera) {
  const Vec3 hold(0.1, -0.2, 1.0);
  const vision::CameraPose pose = vision::cameraPoseForView(hold, 50.0, 1.5, -0.3);
  const View v = viewOf(pose, hold);
  const HoldGeometry& g = v.g;
  EXPECT_FALSE(g.rectified);
  EXPECT_NEAR(g.horizontal_distance_m, 1.5, 1e-9);
  EXPECT_NEAR(g.camera_height_m, -0.3, 1e-9);
  EXPECT_NEAR(g.camera_azimuth_deg, 50.0, 1e-9);
  EXPECT_NEAR(g.elevation_deg, std::atan2(0.3, 1.5) * 180 / kPi, 1e-9);
  EXPECT_NEAR(g.tilt_deg, 0.0, 1e-9);
  EXPECT_NEAR(g.roll_deg, 0.0, 1e-9);
  Vec2 px;
  double depth = 0;
  ASSERT_TRUE(vision::projectPoint(vga(), pose, hold, &px, &depth));
  EXPECT_LT((g.hold_pixel - px).norm(), 1e-9);
  EXPECT_LT((g.virtual_hold_pixel - px).norm(), 1e-9);
  EXPECT_NEAR(g.hold_depth_m, depth, 1e-12);
  EXPECT_NEAR(g.virtual_metres_per_pixel.x(), 1.5 / 525.0, 1e-12);
  // The hold frame is the world frame moved to the hold point (the heading is the world x axis).
  EXPECT_LT((pose.rotation * g.rotation_camera_hold - Mat3::Identity()).norm(), 1e-9);
  EXPECT_LT((g.cameraPositionHold() - (pose.position - hold)).norm(), 1e-9);
  const Vec3 p(0.05, 0.1, -0.3);
  EXPECT_LT((g.holdToCamera(p) - pose.toCamera(hold + p)).norm(), 1e-9);
  EXPECT_LT((g.cameraToHold(g.holdToCamera(p)) - p).norm(), 1e-12);
  // Without a heading, H's x axis is the camera's horizontal image-right: azimuth 0 by construction.
  const View u = viewOf(pose, hold, false);
  EXPECT_NEAR(u.g.camera_azimuth_deg, 0.0, 1e-9);
  EXPECT_LT((pose.rotation * u.g.rotation_camera_hold.col(0) - vision::viewRight(50.0)).norm(), 1e-9);
}

// A tilted, rolled camera that does not aim at the hold point: its mask, rectified, is the renderer's
// pinhole view of the same camera position (horizontal, looking at the hold axis).
TEST(CameraGeometry, TiltedRolledCameraIsRectifiedIntoThePinholeView) {
  vision::HangingShapeParams hp;
  hp.width = 0.5;
  hp.height = 0.36;
  hp.hold_u = 0.1;
  hp.hold_v = 0.36;
  const vision::SyntheticMesh mesh = vision::syntheticHangingMesh(hp, Vec3(0, 0, 1.2));
  const double az = 30.0, dist = 1.2, height = -0.25;
  const Vec3 eye = mesh.hold - dist * vision::viewDirection(az) + Vec3(0, 0, height);
  const vision::CanonicalFrame frame = vision::CanonicalFrame::fromMetric(0.8, 0.8, 64);
  const vision::BitMask direct = vision::renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, az,
                                                          vision::SilhouetteProjection::pinhole(vga(), dist, height), frame);
  for (double roll : {0.0, 8.0}) {
    for (double aim_down : {0.0, 0.35}) {
      vision::CameraPose pose = vision::CameraPose::lookAt(eye, mesh.hold + Vec3(0, 0, -aim_down) + 0.15 * vision::viewRight(az));
      pose.rotation = pose.rotation * Eigen::AngleAxisd(roll * kPi / 180, Vec3::UnitZ()).toRotationMatrix();
      vision::ShadedRenderOptions ro;
      ro.intrinsics = vga();
      ro.camera = pose;
      ro.noise_sigma = 0;
      const vision::ShadedImage img = vision::renderShaded(mesh.positions, mesh.triangles, ro);
      const View v = viewOf(pose, mesh.hold);
      EXPECT_TRUE(v.g.rectified);
      EXPECT_NEAR(v.g.camera_azimuth_deg, az, 1e-9);
      EXPECT_NEAR(v.g.horizontal_distance_m, dist, 1e-9);
      EXPECT_NEAR(v.g.camera_height_m, height, 1e-9);
      const vision::BitMask rect = canonicaliseObservationMask(img.mask, v.g, frame);
      const vision::BitMask naive = vision::canonicaliseCameraMask(img.mask, v.g.hold_pixel, v.g.metres_per_pixel, frame);
      const double iou_rect = vision::iou(rect, direct), iou_naive = vision::iou(naive, direct);
      std::printf("roll %.0f aim down %.2f m: IoU rectified %.3f, unrectified %.3f\n", roll, aim_down, iou_rect, iou_naive);
      EXPECT_GT(iou_rect, 0.93);
      // Roll and aiming beside the hold axis distort the unrectified mask clearly; a pure tilt of 16 deg
      // only a little.
      if (roll > 0 || aim_down == 0) {
        EXPECT_GT(iou_rect, iou_naive + 0.05);
      } else {
        EXPECT_GE(iou_rect, iou_naive - 0.005);
      }
    }
  }
}

TEST(CameraGeometry, ClearsMaskAboveTheHoldPoint) {
  const Vec3 hold(0, 0, 1);
  const vision::CameraPose pose = vision::cameraPoseForView(hold, 0.0, 1.5);
  const View v = viewOf(pose, hold);
  cv::Mat mask(480, 640, CV_8UC1, cv::Scalar(0));
  const cv::Point hp(static_cast<int>(std::lround(v.g.hold_pixel.x())), static_cast<int>(std::lround(v.g.hold_pixel.y())));
  cv::rectangle(mask, cv::Rect(hp.x - 30, hp.y, 60, 100), cv::Scalar(255), cv::FILLED);       // the textile
  cv::rectangle(mask, cv::Rect(hp.x - 10, hp.y - 20, 20, 20), cv::Scalar(255), cv::FILLED);   // the gripper
  const vision::CanonicalFrame frame;  // 1/64 m per pixel, hold 2 px below the top
  CanonicalisationOptions keep;
  keep.clear_above_hold_m = -1;
  const vision::BitMask with = canonicaliseObservationMask(mask, v.g, frame, keep);
  const vision::BitMask without = canonicaliseObservationMask(mask, v.g, frame);
  // Row 0 lies 1.6 - 3.1 cm above the hold point: the gripper there is cleared; below the hold point
  // (rows >= 2) nothing changes.
  int above_with = 0, above_without = 0;
  for (int x = 0; x < frame.width_px; ++x) {
    above_with += with.get(x, 0);
    above_without += without.get(x, 0);
  }
  EXPECT_GT(above_with, 0);
  EXPECT_EQ(above_without, 0);
  for (int y = 2; y < frame.height_px; ++y)
    for (int x = 0; x < frame.width_px; ++x) ASSERT_EQ(with.get(x, y), without.get(x, y)) << x << ", " << y;
}

TEST(CameraGeometry, BadInputIsRejected) {
  const vision::PinholeIntrinsics k = vga();
  const Vec3 hold(0, -0.2, 1.5), up(0, -1, 0);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  auto geom = [&](vision::PinholeIntrinsics kk, Vec3 h, Vec3 u, std::optional<Vec3> head = std::nullopt,
                  CameraGeometryOptions o = {}) { return [=] { computeHoldGeometry(kk, h, u, head, o); }; };
  EXPECT_NO_THROW(computeHoldGeometry(k, hold, up));
  vision::PinholeIntrinsics bad = k;
  bad.fx = nan;
  EXPECT_TRUE(throwsCode(geom(bad, hold, up), RecognitionErrorCode::kInvalidGeometry));
  bad = k;
  bad.cx = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(throwsCode(geom(bad, hold, up), RecognitionErrorCode::kInvalidGeometry));
  bad = k;
  bad.fy = 0;
  EXPECT_TRUE(throwsCode(geom(bad, hold, up), RecognitionErrorCode::kInvalidGeometry));
  bad = k;
  bad.height = -1;
  EXPECT_TRUE(throwsCode(geom(bad, hold, up), RecognitionErrorCode::kInvalidGeometry));
  EXPECT_TRUE(throwsCode(geom(k, Vec3(0, -0.2, -1.5), up), RecognitionErrorCode::kInvalidGeometry));  // behind
  EXPECT_TRUE(throwsCode(geom(k, Vec3(0, -0.2, 0.01), up), RecognitionErrorCode::kInvalidGeometry));  // too close
  EXPECT_TRUE(throwsCode(geom(k, Vec3(nan, 0, 1), up), RecognitionErrorCode::kInvalidGeometry));
  EXPECT_TRUE(throwsCode(geom(k, hold, Vec3::Zero()), RecognitionErrorCode::kInvalidGeometry));
  EXPECT_TRUE(throwsCode(geom(k, hold, Vec3(nan, 1, 0)), RecognitionErrorCode::kInvalidGeometry));
  EXPECT_TRUE(throwsCode(geom(k, Vec3(0, -1.2, 1.5), up), RecognitionErrorCode::kInvalidGeometry));  // 39 deg above
  EXPECT_TRUE(throwsCode(geom(k, hold, Vec3(0, -0.5, 0.866)), RecognitionErrorCode::kInvalidGeometry));  // tilt 60
  EXPECT_TRUE(throwsCode(geom(k, Vec3(3, -0.2, 1.5), up), RecognitionErrorCode::kInvalidGeometry));  // far outside
  EXPECT_TRUE(throwsCode(geom(k, hold, up, Vec3(0, -2, 0)), RecognitionErrorCode::kInvalidGeometry));  // vertical heading
  CameraGeometryOptions o;
  o.max_elevation_deg = nan;
  EXPECT_TRUE(throwsCode(geom(k, hold, up, std::nullopt, o), RecognitionErrorCode::kInvalidOptions));
  // Masks: type and size must fit the camera.
  const HoldGeometry g = computeHoldGeometry(k, hold, up);
  EXPECT_TRUE(throwsCode([&] { canonicaliseObservationMask(cv::Mat(), g, {}); }, RecognitionErrorCode::kInvalidImage));
  EXPECT_TRUE(throwsCode([&] { canonicaliseObservationMask(cv::Mat(480, 640, CV_32FC1, cv::Scalar(0)), g, {}); },
                         RecognitionErrorCode::kInvalidImage));
  EXPECT_TRUE(throwsCode([&] { canonicaliseObservationMask(cv::Mat(240, 320, CV_8UC1, cv::Scalar(0)), g, {}); },
                         RecognitionErrorCode::kInvalidImage));
}
