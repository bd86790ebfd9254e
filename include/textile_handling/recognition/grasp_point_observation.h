// Whether the cameras saw a grasp point (ROS-free): the first piece of per-point trust.
//
// A grasp point's position comes from the matched (and depth-fitted) stored shape, so it is a guess
// wherever no image shows that part of the textile. With registered depth the guess can be checked: the
// point is *observed* in an image when it projects into the segmented mask and the measured surface at
// its pixel lies at the point's depth (within a tolerance). A point behind a fold projects into the mask
// too, but the measured surface there is the fold, in front of it: not observed. Without depth there is
// no such check, and no point counts as observed.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace recognition {

/// One image as the observation check sees it: camera point = rotation * p + translation for a point p
/// of the poses' frame.
struct GraspPointView {
  cv::Mat mask;   ///< CV_8UC1, != 0 = textile
  cv::Mat depth;  ///< CV_32FC1 [m], NaN or <= 0 = no return; empty = no depth
  vision::PinholeIntrinsics intrinsics;
  Mat3 rotation = Mat3::Identity();
  Vec3 translation = Vec3::Zero();
};

struct GraspPointObservationOptions {
  /// The measured surface within this distance [m] of the point's depth counts as the point itself.
  double surface_tolerance_m = 0.02;
  /// Half-size [px] of the window searched for the measured depth closest to the point's (a corner sits
  /// on the mask's edge, where the pixel under it may be background).
  int window_px = 2;
};

struct GraspPointObservation {
  int images_in_mask = 0;     ///< images where the point projects into the textile's mask
  int images_observed = 0;    ///< images where the measured surface is at the point (needs depth)
  /// Smallest |measured - point depth| [m] over the images' windows inside the mask; -1 = no depth sample.
  double depth_gap_m = -1;
  bool observed() const { return images_observed > 0; }
};

/// Checks point `p` (the poses' frame) against every view. Views whose mask or depth do not match the
/// intrinsics' size are skipped.
GraspPointObservation observeGraspPoint(const Vec3& p, const std::vector<GraspPointView>& views,
                                        const GraspPointObservationOptions& options = {});

}  // namespace recognition
}  // namespace textile_handling
