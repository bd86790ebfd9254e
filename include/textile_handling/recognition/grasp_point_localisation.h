// Corners located from the data, the matched shape as prior (ROS-free).
//
// Why: a corner read off the matched stored shape inherits every difference between the database's
// simulation and the real drape (another hold point between lattice points, another material, a fold the
// simulation did not make): measured on foreign drapes, a median 4 cm. Where a corner hangs free, the
// images show it directly: a sharp convex turn of the silhouette's outline, with the measured surface
// behind it. So each corner the shape predicts is moved to the nearest such outline corner that the depth
// places in 3-D, if there is one within `search_radius_m`; the shape still names the corner, places the
// ones the images do not show, and decides which outline corner is which.
//
// Outline corners of one image (mask + registered depth):
//   * the outer contour of the largest mask component, sampled at every pixel;
//   * the turn at contour pixel i: the angle between c[i-k] - c[i] and c[i+k] - c[i], k the pixels of
//     `arm_m` at the textile's median depth; a corner where the angle is below `max_corner_angle_deg`,
//     the turn is convex (towards the outside) and the angle is the smallest within +-k;
//   * its 3-D point: the pixel's ray at the median measured depth of the mask pixels within
//     `depth_window_px` (the tip pixel itself is often a mixed or missing return);
//   * outline corners within `hold_exclusion_m` of the hold point are the gripper's apex: dropped;
//   * the corner whose point hangs lowest (gravity, the poses' frame z) is marked as the lowest point;
//     with several views, only if it is within `agreement_m` of the lowest outline corner of every view
//     (the textile has one lowest point; a view whose own lowest sharp turn hangs higher sees a fold or
//     side corner there, the real lowest point being round or hidden in that view).
// Assignment per image: every (predicted corner, outline corner) pair closer than `search_radius_m` in
// 3-D, nearest pair first, each used once; the lowest outline corner may reach `lowest_search_radius_m`
// but only predicted corners hanging within `lowest_height_slack_m` of the lowest predicted corner.
// Measured on foreign drapes, a 5-8 cm radius for the other outline corners moved as many corners to the
// wrong outline corner (a fold's tip, a neighbour) as to the right one; the short default only corrects
// corners the shape already places near an outline corner. A corner located in several images takes the mean of the
// locations that agree within `agreement_m` with the one nearest to its prediction.
#pragma once

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "textile_handling/recognition/grasp_point_observation.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace recognition {

/// Where a grasp point's position came from.
enum class GraspPointEvidence {
  kModel,          ///< the matched (and depth-fitted) stored shape only; no image shows it
  kSurface,        ///< the fitted shape, and the measured surface is at the point (GraspPointObservation)
  kOutlineCorner,  ///< located at an outline corner of the images
  kLowestPoint,    ///< located at the outline corner that hangs lowest
};
/// "model", "surface", "outline_corner", "lowest_point".
std::string toString(GraspPointEvidence e);
/// True for the evidence kinds that placed the point from the images (outline corner, lowest point).
bool locatedFromData(GraspPointEvidence e);

struct GraspPointLocalisationOptions {
  bool enabled = true;
  /// Farthest [m] a predicted corner may move to an outline corner (the "20 cm when the data says so").
  double search_radius_m = 0.03;
  /// The lowest outline corner may be farther [m] from its predicted corner: the lowest point of a hanging
  /// textile is almost always a corner (measured: 0.6 cm median error after the move on foreign drapes).
  double lowest_search_radius_m = 0.20;
  /// ... but only to a predicted corner that hangs within this [m] of the lowest predicted corner (the
  /// matched shape agrees that it hangs low; a fold's bottom must not pull a side corner down).
  double lowest_height_slack_m = 0.08;
  /// A move longer than search_radius_m whose label margin (GraspPointLocation) is below this [m] is not
  /// made: the outline corner is about as near to another predicted corner, and moving the wrong one
  /// makes it worse (a towel held at the middle of an edge hangs two corners side by side).
  double min_move_margin_m = 0.03;
  /// Outline corners nearer than this [m] to the hold point (the poses' frame origin) are the gripper's
  /// apex or cloth folded over it, not a corner it can place better than the shape (a corner this near
  /// the hold is a short, well-predicted reach from it): ignored.
  double hold_exclusion_m = 0.10;
  /// Arm length [m] of the turn measurement along the outline.
  double arm_m = 0.025;
  /// A turn sharper than this [deg] (interior angle) is an outline corner.
  double max_corner_angle_deg = 125.0;
  /// Half-size [px] of the window whose median depth places an outline corner.
  int depth_window_px = 3;
  /// Locations of one corner in several images agreeing within this [m] are averaged.
  double agreement_m = 0.03;
  /// Throws RecognitionError(kInvalidOptions) naming the bad field.
  void validate() const;
};

/// One outline corner of one image, in the poses' frame.
struct OutlineCorner {
  Vec3 position = Vec3::Zero();
  double angle_deg = 180;   ///< interior angle of the turn
  bool lowest = false;      ///< the lowest outline corner of its image
  /// The measured surface within one arm of the tip: the RMS residual [m] of a plane fitted to the mask's
  /// depth there (0 if too few pixels). A corner's tip is the cloth's edge on one sheet, flat at that
  /// scale; at a fold's bottom the window holds the layer coming down in front and the one going back up
  /// behind, or a surface turning away, and the depth departs from a plane. Measured on foreign drapes:
  /// lowest points on a fold rather than at a corner had a median 5 mm, real corners 3 mm (the noise).
  double tip_depth_residual_m = 0;
  /// The image's depth noise [m] (standard deviation per pixel, from the median absolute second difference
  /// of the mask's depth along rows; 0 without depth).
  double depth_noise_m = 0;
  /// The residual beyond the noise [m]: max(0, tip_depth_residual_m - depth_noise_m).
  double tipRoughness() const { return std::max(0.0, tip_depth_residual_m - depth_noise_m); }
};

/// The outline corners of one view (needs its mask and depth; none without depth). Positions in the
/// poses' frame (p = R^T (c - t) for camera point c).
std::vector<OutlineCorner> findOutlineCorners(const GraspPointView& view, const GraspPointLocalisationOptions& options);

/// The location of one predicted point.
struct GraspPointLocation {
  GraspPointEvidence evidence = GraspPointEvidence::kModel;
  Vec3 position = Vec3::Zero();  ///< the located position (= the prediction for kModel / kSurface)
  double shift_m = 0;            ///< |located - predicted|
  int images = 0;                ///< images whose outline corner was used
  /// Images that assigned this point an outline corner farther than `agreement_m` from the location
  /// (another view saw something else there), and the largest such distance [m] (0 if none).
  int disagreeing_images = 0;
  double disagreement_m = 0;
  /// How clearly the label fits: the located position's distance to the nearest other predicted point
  /// (corner or named point: an edge midpoint hanging as low as a corner is not one) minus its distance
  /// to this one [m]. Small or negative: another named point of the matched shape hangs as near the
  /// outline corner, and the name may be wrong. +infinity without other points or for an unlocated point.
  double label_margin_m = std::numeric_limits<double>::infinity();
  /// The interior angle [deg] of the outline corner nearest to the prediction among those used (0 for an
  /// unlocated point).
  double tip_angle_deg = 0;
  /// The least OutlineCorner::tipRoughness() [m] of the outline corners used (one image seeing a flat
  /// tip suffices: a corner seen edge-on can look rough; 0 for an unlocated point).
  double tip_roughness_m = 0;
};

/// Locates the points `predicted` (poses' frame, shape N) flagged in `is_corner` (shape N) at the views'
/// outline corners; the others, and corners no outline corner is near, keep their prediction with
/// evidence kSurface if `observed[i]`, else kModel. Returns shape N.
std::vector<GraspPointLocation> locateGraspPoints(const std::vector<Vec3>& predicted, const std::vector<bool>& is_corner,
                                                  const std::vector<bool>& observed,
                                                  const std::vector<GraspPointView>& views,
                                                  const GraspPointLocalisationOptions& options = {});

}  // namespace recognition
}  // namespace textile_handling
