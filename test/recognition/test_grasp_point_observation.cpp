// observeGraspPoint (grasp_point_observation.h): a point on the measured surface is observed; one
// behind a nearer layer, outside the mask, or without depth is not; counts add over images.
#include <gtest/gtest.h>

#include <cmath>

#include "textile_handling/recognition/grasp_point_observation.h"

using namespace textile_handling;
using namespace textile_handling::recognition;

namespace {

// A 64 x 48 camera looking along +z at a textile patch 1 m away that fills the left half of the image.
GraspPointView patchView(double depth_m, bool with_depth = true) {
  GraspPointView v;
  v.intrinsics = vision::PinholeIntrinsics{50.0, 50.0, 31.5, 23.5, 64, 48};
  v.mask = cv::Mat::zeros(48, 64, CV_8UC1);
  v.mask(cv::Rect(0, 0, 32, 48)).setTo(255);
  if (with_depth) {
    v.depth = cv::Mat(48, 64, CV_32FC1, cv::Scalar(std::nanf("")));
    v.depth(cv::Rect(0, 0, 32, 48)).setTo(depth_m);
  }
  return v;
}

const Vec3 kOnPatch(-0.2, 0.0, 1.0);   // projects to u = 21.5, inside the patch
const Vec3 kOffPatch(0.3, 0.0, 1.0);   // u = 46.5, background

}  // namespace

TEST(GraspPointObservation, APointOnTheMeasuredSurfaceIsObserved) {
  const GraspPointObservation o = observeGraspPoint(kOnPatch, {patchView(1.005)});
  EXPECT_EQ(o.images_in_mask, 1);
  EXPECT_EQ(o.images_observed, 1);
  EXPECT_TRUE(o.observed());
  EXPECT_NEAR(o.depth_gap_m, 0.005, 1e-6);
}

TEST(GraspPointObservation, APointBehindAFoldIsInTheMaskButNotObserved) {
  // The measured surface is 10 cm in front of the point: another layer of cloth hides it.
  const GraspPointObservation o = observeGraspPoint(kOnPatch, {patchView(0.9)});
  EXPECT_EQ(o.images_in_mask, 1);
  EXPECT_FALSE(o.observed());
  EXPECT_NEAR(o.depth_gap_m, 0.1, 1e-6);
}

TEST(GraspPointObservation, OutsideTheMaskOrWithoutDepthIsNotObserved) {
  GraspPointObservation o = observeGraspPoint(kOffPatch, {patchView(1.0)});
  EXPECT_EQ(o.images_in_mask, 0);
  EXPECT_FALSE(o.observed());
  EXPECT_EQ(o.depth_gap_m, -1.0);
  o = observeGraspPoint(kOnPatch, {patchView(1.0, false)});
  EXPECT_EQ(o.images_in_mask, 1);
  EXPECT_FALSE(o.observed());
  // Behind the camera, or a mask of the wrong size: skipped.
  EXPECT_EQ(observeGraspPoint(Vec3(0, 0, -1), {patchView(1.0)}).images_in_mask, 0);
  GraspPointView bad = patchView(1.0);
  bad.mask = cv::Mat::zeros(10, 10, CV_8UC1);
  EXPECT_EQ(observeGraspPoint(kOnPatch, {bad}).images_in_mask, 0);
}

TEST(GraspPointObservation, ImagesAddUpAndTheViewTransformIsApplied) {
  // The second camera sees the poses' frame shifted by 0.5 m in x: the point lands on the background.
  GraspPointView shifted = patchView(1.0);
  shifted.translation = Vec3(0.5, 0.0, 0.0);
  const GraspPointObservation o = observeGraspPoint(kOnPatch, {patchView(1.0), patchView(1.01), shifted});
  EXPECT_EQ(o.images_in_mask, 2);
  EXPECT_EQ(o.images_observed, 2);
  EXPECT_NEAR(o.depth_gap_m, 0.0, 1e-6);
}
