// Where the held textile is in a camera image, at what scale, and from which azimuth the camera sees it:
// everything the recogniser derives from the intrinsics, the hold (gripper) point in the camera optical
// frame and the gravity "up" direction in that frame. ROS-free. See docs/recognition.md.
//
// Frames:
//  * camera (optical) frame C: x right, y down, z forward (OpenCV / ROS camera_info convention);
//  * virtual camera V: the same optical centre, rotated so that its optical axis is the horizontal
//    direction from the camera towards the hold axis, image down = -up, no roll. A pure rotation about
//    the optical centre maps images by the homography K R^T K^-1, so a tilted or rolled camera's mask is
//    rectified exactly into V's image; V is then the pinhole camera of the silhouette renderer
//    (silhouette_renderer.h: horizontal distance D, camera height relative to the hold point), whose
//    canonicalised masks the database stores (orthographic = the limit D -> infinity);
//  * hold frame H: origin at the hold point, z = up, x = the horizontal part of a heading reference
//    (e.g. the gripper's or the world's x axis, given in C), or, without one, V's image-right direction;
//    y = z cross x. The camera's azimuth in H (silhouette convention: the camera looks along
//    d(theta) = (-sin theta, cos theta, 0)) is camera_azimuth_deg; without a heading it is 0 by
//    construction.
#pragma once

#include <optional>

#include <opencv2/core.hpp>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace recognition {

struct CameraGeometryOptions {
  /// Largest angle [deg] between the line of sight camera -> hold point and the horizontal plane. The
  /// stored silhouettes are horizontal views; a camera far above or below the hold point sees the
  /// textile from above / below, which no rotation of the image undoes. Larger: kInvalidGeometry.
  double max_elevation_deg = 30.0;
  /// Largest tilt [deg] of the optical axis out of the horizontal plane and largest roll [deg] of the
  /// image x axis; within these the mask is rectified exactly (homography), beyond: kInvalidGeometry.
  double max_tilt_deg = 60.0;
  double max_roll_deg = 45.0;
  /// The hold point must be at least this far in front of the camera (optical-axis depth) [m] and at
  /// least this far from the camera horizontally [m].
  double min_depth_m = 0.05;
  double min_horizontal_distance_m = 0.2;
  /// The hold pixel may lie outside the image by at most this many pixels (a gripper just above the
  /// picture); farther: kInvalidGeometry.
  double max_hold_pixel_outside_px = 50.0;
  /// Tilt and roll below this [deg] count as zero: the mask is used as it is (no resampling).
  double rectify_epsilon_deg = 1e-4;
  /// Plausible cameras (kInvalidGeometry outside): the horizontal and vertical fields of view
  /// 2 atan(size / 2f) lie in [min_fov_deg, max_fov_deg] (fx = 1 px on a VGA image means 179.6 deg:
  /// a broken camera_info, not a lens; 3..150 deg spans telephoto to fisheye-free wide angle), fy / fx
  /// lies in [1 / max_aspect, max_aspect] (square pixels are 1), the principal point lies at most
  /// max_principal_point_outside times the image size outside the image, and the hold point is at most
  /// max_hold_distance_m from the camera (a cell camera sees the textile from a few metres; farther, a
  /// 64 px canonical window is a few camera pixels).
  double min_fov_deg = 3.0;
  double max_fov_deg = 150.0;
  double max_aspect = 2.0;
  double max_principal_point_outside = 0.5;
  double max_hold_distance_m = 20.0;
};

/// The result of computeHoldGeometry().
struct HoldGeometry {
  vision::PinholeIntrinsics intrinsics;
  Vec3 hold_camera = Vec3::Zero();   ///< hold point in C [m]
  Vec3 up_camera = Vec3::UnitZ();    ///< unit up in C
  Vec2 hold_pixel = Vec2::Zero();    ///< hold point in the real image (pixel centres at integers)
  double hold_depth_m = 0;           ///< optical-axis depth of the hold point in C [m]
  Vec2 metres_per_pixel = Vec2::Zero();  ///< real camera at the hold depth (depth / fx, depth / fy)

  // Virtual horizontal camera V (same intrinsics K).
  Mat3 rotation_camera_virtual = Mat3::Identity();  ///< columns: V's axes in C (p_C = R p_V)
  bool rectified = false;            ///< V differs from C (the mask is resampled)
  Vec2 virtual_hold_pixel = Vec2::Zero();   ///< hold point in V's image: (cx, cy + fy * height / D)
  double horizontal_distance_m = 0;  ///< D: horizontal distance camera centre -> hold axis [m]
  double camera_height_m = 0;        ///< camera centre height relative to the hold point [m]
  Vec2 virtual_metres_per_pixel = Vec2::Zero();  ///< (D / fx, D / fy): canonical scale
  double elevation_deg = 0;          ///< line of sight to the hold point above the horizontal
  double tilt_deg = 0;               ///< optical axis above the horizontal
  double roll_deg = 0;               ///< image x axis above the horizontal

  // Hold frame H.
  Mat3 rotation_camera_hold = Mat3::Identity();  ///< columns: H's axes in C (p_C = R p_H + hold_camera)
  bool has_heading = false;          ///< H's x axis came from a heading reference
  Vec3 view_direction_hold = Vec3::UnitY();  ///< V's optical axis in H (horizontal, unit)
  double camera_azimuth_deg = 0;     ///< azimuth of V in H, [0, 360), silhouette convention

  /// The pinhole projection of the silhouette renderer that corresponds to V.
  vision::SilhouetteProjection projection() const {
    return vision::SilhouetteProjection::pinhole(intrinsics, horizontal_distance_m, camera_height_m);
  }
  /// Camera position in H.
  Vec3 cameraPositionHold() const { return -(rotation_camera_hold.transpose() * hold_camera); }
  /// H -> C for points / C -> H.
  Vec3 holdToCamera(const Vec3& p_hold) const { return rotation_camera_hold * p_hold + hold_camera; }
  Vec3 cameraToHold(const Vec3& p_camera) const { return rotation_camera_hold.transpose() * (p_camera - hold_camera); }
};

/// Validates the intrinsics (finite fx, fy > 0, finite cx, cy, width and height > 0, plausible field of
/// view, aspect and principal point: see CameraGeometryOptions) and the inputs,
/// and derives the geometry. `heading_camera` (optional) is a direction in C whose horizontal part
/// becomes H's x axis; it must not be (nearly) vertical.
/// Throws RecognitionError(kInvalidGeometry) with the reason: NaN anywhere, non-positive focal length or
/// image size, zero or NaN up vector, hold point behind (or too close in front of) the camera, hold
/// point (nearly) straight above or below the camera, elevation / tilt / roll beyond the options, a hold
/// pixel too far outside the image, a vertical heading; kInvalidOptions for bad options.
HoldGeometry computeHoldGeometry(const vision::PinholeIntrinsics& intrinsics, const Vec3& hold_camera,
                                 const Vec3& up_camera, const std::optional<Vec3>& heading_camera = std::nullopt,
                                 const CameraGeometryOptions& options = {});

/// Azimuth [deg, in [0, 360)] of a horizontal direction in the silhouette convention:
/// the theta with d(theta) = (-sin theta, cos theta, 0) parallel to (d.x, d.y).
double azimuthOfDirection(const Vec3& direction);
/// Wraps an angle to [0, 360).
double wrapDegrees(double a);
/// Rotation about +z by `deg` degrees.
Mat3 rotationZ(double deg);

/// Options of canonicaliseObservationMask().
struct CanonicalisationOptions {
  /// Clear rectified mask pixels more than this far [m] above the hold point (the gripper, its
  /// fingers' upper part): a hanging textile has nothing above its hold point. Negative: keep all.
  double clear_above_hold_m = 0.005;
  /// Largest rectified canvas (pixels per side) the rectification may allocate.
  int max_canvas_px = 8192;
};

/// Puts a segmented camera mask (CV_8UC1, non-zero = textile, the real image's size) into the canonical
/// frame: rectifies it into V (if needed: bilinear resampling, threshold at half), then
/// vision::canonicaliseCameraMask() with V's hold pixel and the scale at the horizontal distance D.
/// Throws RecognitionError(kInvalidImage) for an empty / wrongly typed / wrongly sized mask,
/// kInvalidGeometry if the canonical window would need a canvas larger than max_canvas_px.
vision::BitMask canonicaliseObservationMask(const cv::Mat& mask, const HoldGeometry& geometry,
                                            const vision::CanonicalFrame& frame,
                                            const CanonicalisationOptions& options = {});

/// The rectified mask in V's image, cropped to the canonical window (for debugging); `origin` gets the
/// V pixel coordinates of the crop's top-left pixel.
cv::Mat rectifyMaskForFrame(const cv::Mat& mask, const HoldGeometry& geometry, const vision::CanonicalFrame& frame,
                            const CanonicalisationOptions& options, cv::Point* origin);

}  // namespace recognition
}  // namespace textile_handling
