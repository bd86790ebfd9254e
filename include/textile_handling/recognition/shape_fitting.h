// Fitting a matched rest shape to what the camera measured (ROS-free).
//
// Why: a stored rest shape is the simulation of the database's nearest hold point at the database's
// resolution. The real textile (or a held-out simulation at another resolution) hangs a few
// centimetres differently: measured for the thesis towel, rest shapes at d = 2/3 cm and d = 0.5 cm held
// at the same point differ by up to 2-3.4 cm at the corners, d = 1 cm against 0.5 cm by up to 5.5 cm
// (docs/recognition.md, "Fitting the shape to depth"). Grasp frames read off the stored shape inherit
// that error. With a registered depth image the visible surface is known, so the matched shape is
// deformed onto it before the grasp poses are read.
//
// Method: non-rigid ICP with a linear deformation model (Laplacian / edge-vector preservation, as in
// Sorkine et al. 2004 and the non-rigid ICP of Amberg et al. 2007, without their per-vertex affine
// transforms). In each iteration, with X the current camera-frame vertex positions and X0 the matched
// shape:
//   * visible vertices (z-buffer of the current mesh, 1 cm slack) projecting into the segmented mask
//     with a valid measured depth get the target "the measured point on their pixel's ray";
//   * visible vertices projecting outside the mask get the measured point (or their own depth) at the
//     nearest mask pixel;
//   * mask pixels the current mesh does not cover pull the nearest visible vertex (in the image) to
//     their measured point, so the mesh spreads into the observed silhouette;
//   * minimise  sum_i w_i |X_i - t_i|^2 + lambda sum_(i,j) in edges |(X_i - X_j) - (X0_i - X0_j)|^2
//               + mu sum_i |X_i - X0_i|^2,  with the held vertex fixed at X0_held;
//     one sparse symmetric positive definite system (the same matrix for x, y and z), Eigen LDLT.
// Occluded vertices follow their neighbours through the edge term. The result is a shape in the camera
// frame; the caller maps it into its frame of choice.
//
// Several views (fitShapeToDepthViews): the shape lives in a common frame and each view maps it into
// its camera (rotation, translation); the correspondences of all views, mapped back into the common
// frame, enter the same least-squares problem (the data term |X_i - t_i|^2 does not depend on the
// frame). A part hidden in one view and seen in another is then fitted too: the cell turns the gripper
// and fuses two images (docs/recognition.md).
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/recognition/grasp_point_observation.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/sim/types.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace recognition {

struct ShapeFitOptions {
  bool enabled = true;
  /// With several images (fusion), fit to the depth of every image that has it (true) or of the first
  /// only (false).
  bool fuse_views = true;
  int iterations = 10;
  /// Weight of the edge-vector term relative to one data correspondence (weight 1).
  double edge_weight = 4.0;
  /// Weight pulling every vertex towards the matched shape (keeps the fit near it where data are thin).
  double anchor_weight = 0.02;
  /// Weight of a silhouette correspondence (outside-mask vertex, or an uncovered mask pixel).
  double silhouette_weight = 1.0;
  /// A vertex is visible if it is within this distance [m] of the rendered depth on its pixel.
  double visibility_slack_m = 0.01;
  /// Depth targets farther than this [m] from the vertex are ignored (another layer, a wrong pixel)...
  double max_correspondence_m = 0.06;
  /// ...after the first half of the iterations; the first iteration accepts targets up to reach_m, and the
  /// limit shrinks geometrically in between (the robust scale and the silhouette limits with it), so a part
  /// of the matched shape that hangs this far from the data can still be pulled onto it.
  double reach_m = 0.20;
  /// Edge term with a rotation per vertex (as-rigid-as-possible): the edges of the matched shape may turn
  /// with the cloth at no cost, so a flap folded elsewhere moves as a whole (test
  /// ReachesALowerPartTwentyCentimetresAway); false (default): the edge vectors themselves are kept, a
  /// linear model that resists turning. Off by default because the free turning also lets the surface slide
  /// along itself where only depth constrains it: on the recognizer's held-out shapes the worst grasp
  /// points improved and the good ones got worse (docs/recognition.md, "Fitting the shape to depth").
  bool rotations = false;
  /// Cauchy scale of the depth correspondences: weight 1 / (1 + (d / scale)^2).
  double robust_scale_m = 0.015;
  /// Depth is sampled bilinearly; four neighbours spreading more than this [m] are an edge: no sample.
  double depth_discontinuity_m = 0.01;
  /// Silhouette correspondences only beyond this distance [px] between rendered and observed outline.
  double silhouette_slack_px = 2.0;
  /// Uncovered mask pixels are sampled on a grid of this step [px].
  int uncovered_step_px = 2;
};

struct ShapeFitReport {
  int iterations = 0;
  int visible_vertices = 0;        ///< last iteration
  int depth_correspondences = 0;   ///< last iteration
  int silhouette_correspondences = 0;
  double mean_depth_residual_before_m = -1;  ///< mean |vertex - target| over depth correspondences, first iteration
  double mean_depth_residual_after_m = -1;   ///< the same at the end
  double max_displacement_m = 0;   ///< largest |X - X0|
  bool applied = false;            ///< false: too few data (the shape is returned unchanged)
  std::string note;
};

/// One registered depth view of the shape for fitShapeToDepthViews: camera point = rotation * p + translation
/// for a point p of the common frame.
using DepthView = GraspPointView;  // depth required here

/// Fits `positions` (3 per vertex, the common frame [m]) to every view at once (see above); otherwise as
/// fitShapeToDepth, with the correspondence counts summed over the views. Throws RecognitionError for
/// inconsistent input: kInvalidDepth (no view, depth or mask of the wrong type or size), kInvalidGeometry
/// (positions, indices, a non-orthonormal rotation), kInvalidOptions.
VecX fitShapeToDepthViews(const VecX& positions, const std::vector<vision::Triangle>& triangles, Index fixed_vertex,
                          const std::vector<DepthView>& views, const ShapeFitOptions& options = {},
                          ShapeFitReport* report = nullptr);

/// Fits `positions_camera` (3 per vertex, camera optical frame [m]; triangles as for the renderers) to
/// a registered depth image (CV_32FC1 [m], NaN or <= 0 = none) inside `mask` (CV_8UC1, != 0 = textile;
/// both of the intrinsics' size). `fixed_vertex` (>= 0) stays where it is. Returns the fitted positions;
/// the input is returned unchanged (report->applied = false) when fewer than max(10, n / 10) depth
/// correspondences are found (n vertices). Throws RecognitionError as fitShapeToDepthViews().
VecX fitShapeToDepth(const VecX& positions_camera, const std::vector<vision::Triangle>& triangles, Index fixed_vertex,
                     const cv::Mat& depth, const cv::Mat& mask, const vision::PinholeIntrinsics& intrinsics,
                     const ShapeFitOptions& options = {}, ShapeFitReport* report = nullptr);

}  // namespace recognition
}  // namespace textile_handling
