// How far a reported grasp point may be from the real one, and whether a robot should grasp it
// (ROS-free).
//
// The uncertainty is an error bound [m]: near the distance that 90 % of the points with the same
// evidence stayed within on the calibration half of the foreign-drape benchmark (drapes the database did
// not make: another cloth model, other materials, holds anywhere; docs/recognition.md, "Where a point
// comes from, and how far to trust it"). It is a step function of the evidence
// (grasp_point_localisation.h) that grows with how far the data moved the point from the matched shape
// (a long move is likelier the wrong outline corner), with a doubtful label and with images that
// disagree, and shrinks where several images agree:
//   u = base(evidence) - agreeing_m  (the base shrinks if >= 2 images placed it and agree)
//       + shift_gain * shift                                 (outline corners, lowest point)
//       + (shift + label margin)  if the label margin < label_margin_m (another named point is nearly
//                                 as near: the name may be its neighbour's)
//       + disagreement            (the farthest placement of another image that did not agree)
//       + roughness_gain * roughness  (the measured surface bends at the tip beyond the depth noise, as
//                                 at a fold's bottom; the least over the images that placed the point)
//   u = base(evidence)                                      (model, surface)
// and doubles when the result's silhouette score is below `weak_score` (`weak_score_agreeing` for a point
// several images agree on): the matched shape explains the images poorly, so its labels are doubtful. A
// fused result with a contradicting image counts as score 0, except for a point several images agree on
// (they saw the same corner, whatever the silhouettes say elsewhere). A point is safe when
// u <= safe_bound_m.
//
// The defaults were chosen on one seed of `foreign_drape_bench` and checked on another; the benchmark
// prints the share of safe points within the safe bound and writes the calibration (error against
// uncertainty) as CSV and chart.
#pragma once

#include "textile_handling/recognition/grasp_point_localisation.h"

namespace textile_handling {
namespace recognition {

struct GraspPointTrustOptions {
  /// Error bound [m] per evidence (grasp_point_localisation.h).
  double model_m = 0.15;
  double surface_m = 0.12;
  double outline_corner_m = 0.025;
  double lowest_point_m = 0.02;
  /// Added bound per metre the data moved a located point.
  double shift_gain = 0.25;
  /// A located point whose label margin is below this [m] may carry its neighbour's name: its bound
  /// becomes the distance to that neighbour (shift + margin) plus its base.
  double label_margin_m = 0.04;
  /// Added bound per metre of tip roughness (GraspPointLocation::tip_roughness_m): 1 mm of depth bending
  /// beyond the noise adds 1 cm.
  double roughness_gain = 10.0;
  /// Taken off the base of a point that two or more images placed at the same outline corner.
  double agreeing_m = 0.005;
  /// Results scoring below this silhouette IoU get every bound doubled ...
  double weak_score = 0.6;
  /// ... or below this one for a point two or more images agree on.
  double weak_score_agreeing = 0.6;
  /// A point is safe to grasp when its bound is at most this [m].
  double safe_bound_m = 0.03;
  /// Throws RecognitionError(kInvalidOptions) naming the bad field.
  void validate() const;
};

/// The error bound [m] of a point located as `location` (locateGraspPoints) in a result whose silhouette
/// score is `score` and which has `contradicting_images` (RecognitionResult).
double graspPointUncertainty(const GraspPointLocation& location, double score, int contradicting_images,
                             const GraspPointTrustOptions& options = {});

}  // namespace recognition
}  // namespace textile_handling
