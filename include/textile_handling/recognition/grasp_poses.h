// Grasp poses of a recognised textile: every named point (corners and predefined grasp points) of a
// stored rest shape, placed in the gravity-aligned hold frame H of camera_geometry.h, with an orientation
// built from the local surface normal and the textile's edge direction. ROS-free. docs/recognition.md.
//
// Placement: the stored shape (simulation world, z up, held particle at x_hold) seen at stored view
// azimuth theta_m is rotated about the vertical hold axis by phi = theta_cam - theta_m, so that its view
// direction d(theta_m) becomes the camera's horizontal viewing direction d(theta_cam) in H:
//   p_H = R_z(phi) (x - x_hold).
//
// Orientation of a pose (columns of `rotation`, all in H):
//   z = unit surface normal at the point (du x dv of the rest shape's map from the flat textile, the
//       "front" face; by default flipped to point towards the camera),
//   x = the textile's outward direction at the point (in the flat textile: the outward bisector of the
//       two edges at a corner, the edge's outward normal on an edge, the warp (+x) direction inside),
//       mapped onto the surface and made orthogonal to z,
//   y = z cross x.
// A gripper approaching along -z with its fingers closing along y pinches the edge at the point.
// `edge_direction` is the outline's counter-clockwise tangent at the point (at a corner: along the
// edge that leaves it counter-clockwise; inside: the warp direction), mapped onto the surface.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "textile_handling/recognition/camera_geometry.h"
#include "textile_handling/recognition/grasp_point_localisation.h"
#include "textile_handling/recognition/grasp_point_observation.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace recognition {

enum class NormalConvention {
  kTowardsCamera,  ///< z points to the camera's side of the surface (default)
  kTextileFront,   ///< z is the flat textile's +z face (du x dv), whichever way it faces
};

struct GraspPoseOptions {
  NormalConvention normal = NormalConvention::kTowardsCamera;
  /// Also give a pose to every outline vertex that no named point covers (name "vertex_<k>", kind
  /// "corner"), for textiles registered without named corners.
  bool include_outline_vertices = false;
  /// A named point within this distance [m] of the outline counts as on it (corner / edge).
  double boundary_tolerance_m = 1e-3;
};

struct GraspPose {
  std::string name;
  std::string kind;                   ///< "corner" or "grasp" (as stored)
  Vec2 textile_position = Vec2::Zero();  ///< the named point in the textile frame [m]
  bool on_outline_vertex = false;
  bool on_outline_edge = false;
  Vec3 position = Vec3::Zero();       ///< hold frame H [m]
  Mat3 rotation = Mat3::Identity();   ///< columns x, y, z of the pose in H
  Vec3 edge_direction = Vec3::UnitX();  ///< unit, H
  Vec3 position_camera = Vec3::Zero();  ///< camera optical frame [m]
  Mat3 rotation_camera = Mat3::Identity();
  /// What the images showed of this point (filled by TextileRecognizer; zero counts otherwise).
  GraspPointObservation observation;
  /// Where `position` came from (filled by TextileRecognizer; kModel otherwise) and how far the data moved
  /// it from the matched shape's prediction [m] (grasp_point_localisation.h).
  GraspPointEvidence evidence = GraspPointEvidence::kModel;
  double located_shift_m = 0;
  int located_images = 0;  ///< images whose outline corner placed the point (agreeing within localisation.agreement_m)
  int disagreeing_images = 0;  ///< GraspPointLocation::disagreeing_images (another image placed it elsewhere)
  double disagreement_m = 0;   ///< GraspPointLocation::disagreement_m
  /// GraspPointLocation::label_margin_m (+infinity when not located).
  double label_margin_m = std::numeric_limits<double>::infinity();
  /// GraspPointLocation::tip_angle_deg and tip_roughness_m (0 when not located).
  double tip_angle_deg = 0;
  double tip_roughness_m = 0;
  /// Position uncertainty [m]: the calibrated error bound of this kind of point (grasp_point_trust.h;
  /// -1 = not assessed), and whether the point is safe to grasp (uncertainty within the safe bound).
  double uncertainty_m = -1;
  bool safe = false;
  Vec3 normal() const { return rotation.col(2); }
  Eigen::Quaterniond orientation() const { return Eigen::Quaterniond(rotation); }
  Eigen::Quaterniond orientationCamera() const { return Eigen::Quaterniond(rotation_camera); }
};

/// Position and tangents of a rest shape at a textile-frame point.
struct RestShapeSample {
  Vec3 position = Vec3::Zero();
  Vec3 du = Vec3::UnitX();  ///< d position / d textile x
  Vec3 dv = Vec3::UnitY();  ///< d position / d textile y
  bool interpolated = true; ///< bilinear in a complete grid cell; false: nearest particle + differences
};

/// Samples the rest shape (positions: 3 per active particle of `grid`) at textile point p: bilinear
/// interpolation in the grid cell containing p when its four nodes are active, else the nearest active
/// particle with finite-difference tangents. Throws RecognitionError(kInvalidGeometry) for a size mismatch,
/// an empty grid or a non-finite p.
RestShapeSample sampleRestShape(const ParticleGrid& grid, const VecX& positions, const Vec2& p);

/// The shape placed in H: p_H = R_z(rotation_deg) (x - x_hold) for every particle. Throws
/// RecognitionError(kInvalidGeometry) for positions not 3 per particle or a held particle out of range.
VecX placeInHoldFrame(const VecX& positions, Index held_particle, double rotation_deg);

/// The shape mirrored across the vertical plane through the held particle whose normal is the view
/// direction d(view_deg): the same (orthographic) silhouette at view_deg, the other chirality; particle
/// labels are kept. Throws RecognitionError as placeInHoldFrame().
VecX reflectAcrossView(const VecX& positions, Index held_particle, double view_deg);

/// Poses of the named points of `textile` (and outline vertices, per options) on the rest shape
/// `positions` (grid = the textile rasterised at the simulation's spacing), placed with
/// placeInHoldFrame(rotation_deg); camera-frame copies via `geometry`. Throws RecognitionError:
/// kInvalidGeometry for inconsistent input (size mismatch, bad held particle), kInvalidOptions for a
/// negative or non-finite boundary tolerance.
std::vector<GraspPose> computeGraspPoses(const TextileOutline& textile, const ParticleGrid& grid, const VecX& positions,
                                         Index held_particle, double rotation_deg, const HoldGeometry& geometry,
                                         const GraspPoseOptions& options = {});

}  // namespace recognition
}  // namespace textile_handling
