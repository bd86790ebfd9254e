// Shaded renderer for synthetic camera images of a hanging textile: a pinhole camera, z-buffered
// triangles, two-sided diffuse (Lambert) lighting, a background (uniform, checkerboard or random
// texture) and Gaussian pixel noise. Outputs a BGR8 image, optionally a depth image (CV_32FC1, metres
// along the optical axis, NaN where no textile, as in REP 118) and the ground-truth mask (CV_8UC1,
// 255 = textile). Deterministic for a given seed (OpenCV's cv::RNG). Used by tests and bag writers.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace vision {

/// Camera pose in the world: p_world = rotation * p_camera + position. The camera frame is the
/// OpenCV/ROS optical frame: x right, y down, z forward (optical axis).
struct CameraPose {
  Mat3 rotation = Mat3::Identity();
  Vec3 position = Vec3::Zero();

  /// World point -> camera frame.
  Vec3 toCamera(const Vec3& p_world) const { return rotation.transpose() * (p_world - position); }
  /// Camera at `eye` looking at `target`, image up as close to `up` as possible. Throws
  /// std::invalid_argument if eye == target or the line of sight is parallel to `up`.
  static CameraPose lookAt(const Vec3& eye, const Vec3& target, const Vec3& up = Vec3::UnitZ());
};

/// The camera of view `azimuth_deg` of the silhouette renderer's pinhole projection: at horizontal
/// distance `distance` from the hold axis, at height hold.z + height, looking horizontally along
/// viewDirection(azimuth_deg). Its renders canonicalise to renderSilhouette(..., pinhole(K, distance,
/// height)) (docs/vision.md).
CameraPose cameraPoseForView(const Vec3& hold, double azimuth_deg, double distance, double height = 0.0);

/// Projects a world point to pixel coordinates (pixel centres at integers); returns false if the point
/// is not in front of the camera (z <= 1e-9).
bool projectPoint(const PinholeIntrinsics& k, const CameraPose& pose, const Vec3& p_world, Vec2* pixel,
                  double* depth = nullptr);

enum class BackgroundType { kUniform, kCheckerboard, kNoiseTexture };

struct ShadedRenderOptions {
  PinholeIntrinsics intrinsics;          ///< width and height (> 0) set the image size
  CameraPose camera;
  Vec3 light_direction = Vec3(0.3, -1.0, 0.6);  ///< world, from the scene towards the light (normalised)
  double ambient = 0.3;                  ///< intensity = ambient + diffuse * |n . l| (two-sided cloth)
  double diffuse = 0.7;
  std::array<std::uint8_t, 3> cloth_bgr{{70, 110, 200}};
  BackgroundType background = BackgroundType::kUniform;
  std::array<std::uint8_t, 3> background_bgr{{235, 235, 235}};
  std::array<std::uint8_t, 3> background2_bgr{{170, 170, 170}};  ///< checkerboard / texture second colour
  int checker_px = 32;                   ///< checkerboard square size [px]
  int texture_blob_px = 24;              ///< feature size of the random texture [px]
  double noise_sigma = 2.0;              ///< Gaussian pixel noise, standard deviation in grey levels (0 = off)
  std::uint64_t seed = 1;                ///< seeds the texture and the noise
  bool render_depth = true;
  bool render_mask = true;
  /// false: only the z-buffer (depth and mask) is made; no normals, shading, background or noise, and
  /// `bgr` stays empty. Depth and mask are the same as with colour. For callers that need the visible
  /// surface only (the recognizer's depth fits), where shading took most of the render.
  bool render_colour = true;
};

struct ShadedImage {
  cv::Mat bgr;    ///< CV_8UC3, or empty (render_colour = false)
  cv::Mat depth;  ///< CV_32FC1 [m] or empty (render_depth = false); NaN where no textile
  cv::Mat mask;   ///< CV_8UC1, 255 = textile; or empty (render_mask = false)
};

/// Renders the mesh (positions: 3 per vertex, world, metres; triangles as for renderSilhouette).
/// A pixel belongs to the textile if its centre lies in a triangle (nearest surface wins). Triangles
/// with a vertex behind the near plane (1 cm) are skipped. Throws std::invalid_argument for bad mesh
/// input (as renderSilhouette), an image size <= 0, bad intrinsics, or negative noise / lighting.
ShadedImage renderShaded(const VecX& positions, const std::vector<Triangle>& triangles,
                         const ShadedRenderOptions& options);

/// Pixel box, clipped to the k.width x k.height image, that the points `camera_points` (3 per point, camera
/// optical frame [m]) lying more than 1 cm in front of the camera project into, grown by `margin` px on
/// every side; empty if none does. A mesh rendered with the intrinsics shifted by the box's corner and
/// sized to it (cropIntrinsics) shows, in the box, what the full render shows there.
cv::Rect projectedBox(const VecX& camera_points, const PinholeIntrinsics& k, int margin);
/// The intrinsics of the crop `box` of an image with intrinsics `k`.
PinholeIntrinsics cropIntrinsics(const PinholeIntrinsics& k, const cv::Rect& box);
/// The z-buffer of the camera-frame points `camera_points` (camera at the origin) rendered into the crop
/// `box` (non-empty) of an image with intrinsics `k`: depth, and the mask if `with_mask`, no colour.
ShadedImage renderDepthCrop(const VecX& camera_points, const std::vector<Triangle>& triangles,
                            const PinholeIntrinsics& k, const cv::Rect& box, bool with_mask);

}  // namespace vision
}  // namespace textile_handling
