// Segmentation of the hanging textile in a camera image (OpenCV), optionally gated by depth: a colour
// model of the background, morphological clean-up, and the connected component at the hold point (the
// textile hangs from the gripper). With a registered depth image (or a point cloud in the camera frame,
// point_cloud_segmentation.h) only pixels inside a crop box below the gripper that belong to the 3-D
// cluster connected to the hold point are kept. ROS-free. See docs/recognition.md.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include <opencv2/core.hpp>

#include "textile_handling/recognition/camera_geometry.h"

namespace textile_handling {
namespace recognition {

/// Image encodings accepted (sensor_msgs/image_encodings names): "bgr8" (CV_8UC3), "rgb8" (CV_8UC3),
/// "mono8" (CV_8UC1). Returns a BGR CV_8UC3 copy/view. Throws RecognitionError: kUnsupportedEncoding for
/// any other encoding (named in the message), kInvalidImage for an empty image or a cv::Mat type that
/// does not fit the encoding.
cv::Mat toBgr8(const cv::Mat& image, const std::string& encoding);

/// Depth image registered to the colour image: CV_32FC1 in metres (NaN, inf, <= 0 invalid) or CV_16UC1
/// in millimetres (0 invalid). Returns CV_32FC1 metres with NaN for invalid pixels. Throws
/// RecognitionError(kInvalidDepth) for other types or an empty image.
cv::Mat depthToMetres(const cv::Mat& depth);

enum class BackgroundModel {
  kUniformColour,    ///< a known background colour (backdrop, "green screen")
  kBorderMedian,     ///< the per-channel median of the image border (a uniform backdrop of unknown colour)
  kBackgroundImage,  ///< a picture of the empty scene from the same camera (same size, bgr8)
};

enum class ColourSpace {
  kBgr,  ///< Euclidean distance of the 8-bit B, G, R values
  kLab,  ///< Euclidean distance in OpenCV's 8-bit CIE L*a*b* (L, a, b each 0..255)
  kAb,   ///< Lab without lightness: a*, b* only (robust to shadows and shading; needs a coloured textile
         ///< or backdrop)
};

/// How the depth cluster (if any) combines with the colour mask.
enum class DepthMode {
  kColourOnly,         ///< ignore depth
  kGate,               ///< colour mask AND the depth cluster dilated by gate_dilation_px (default)
  kIntersect,          ///< colour mask AND the depth cluster
  kDepthOnly,          ///< the depth cluster alone (no colour model)
};

/// Names of the segmentation enums as configuration files and ROS parameters spell them ("uniform_colour",
/// "border_median", "background_image"; "bgr", "lab", "ab"; "colour_only", "gate", "intersect",
/// "depth_only"). The parsers take exactly these names and throw RecognitionError(kInvalidOptions) naming
/// the given text and the accepted names for anything else.
const char* toString(BackgroundModel model);
const char* toString(ColourSpace space);
const char* toString(DepthMode mode);
BackgroundModel backgroundModelFromString(const std::string& name);
ColourSpace colourSpaceFromString(const std::string& name);
DepthMode depthModeFromString(const std::string& name);

/// Crop box and Euclidean clustering of depth points (depth image or point cloud).
struct DepthSegmentationOptions {
  /// Crop box in the hold frame H (z up, origin at the hold point): |x|, |y| <= half_width_m around the
  /// hold axis, z in [-max_drop_m, top_m]. top_m below 0 cuts the gripper fingers off.
  double half_width_m = 0.6;
  double max_drop_m = 1.5;
  double top_m = 0.01;
  /// Two points belong to one cluster if they are closer than this [m] (PCL's cluster tolerance). It
  /// must exceed the depth gap between visible layers of the cloth (a fold's back layer seen beside its
  /// front layer is connected only through the hidden fold): 6-8 cm for a 36 x 24 cm towel. Objects
  /// nearer to the textile than this are merged with it (the colour model still applies, kGate).
  double cluster_tolerance_m = 0.10;
  /// Depth image: neighbours up to this many pixels apart are compared (bridges small holes).
  int neighbour_radius_px = 2;
  /// Clusters with a point within seed_radius_m of the hold point are kept (the textile touches the
  /// gripper); none: kSegmentationFailed.
  double seed_radius_m = 0.06;
  /// Smallest kept cluster (points).
  int min_cluster_points = 50;
  /// Point clouds: each kept point marks its pixel; the mark is dilated by this radius [px] (0 = off).
  int splat_radius_px = 1;
  /// Point clouds: points are binned into voxels of this size [m] and the voxel centroids clustered
  /// (0 = a quarter of cluster_tolerance_m, at least 5 mm), so the cost does not grow with resolution.
  double voxel_size_m = 0.0;
};

struct SegmentationOptions {
  BackgroundModel background = BackgroundModel::kUniformColour;
  std::array<std::uint8_t, 3> background_bgr{{235, 235, 235}};  ///< kUniformColour
  cv::Mat background_image;                                      ///< kBackgroundImage, bgr8 (CV_8UC3)
  int border_px = 4;                                             ///< kBorderMedian: border width
  ColourSpace colour_space = ColourSpace::kBgr;
  /// A pixel is textile if its colour distance to the background exceeds this.
  double threshold = 60.0;
  /// Morphological opening (noise speckles) and closing (small gaps) radii [px] (0 = off).
  int open_radius_px = 1;
  int close_radius_px = 1;
  /// Fill holes that the textile component encloses completely (off by default: real silhouettes have
  /// holes between folds, and so do the stored ones).
  bool fill_holes = false;
  /// Keep the component (8-connected) that contains the hold pixel or comes closest to it, if within
  /// this radius [px] (the gripper may hide the hold pixel itself). None: kSegmentationFailed.
  double hold_search_radius_px = 25.0;
  /// Also keep other components whose closest pixel lies within this radius [px] of the kept one
  /// (a textile split by a thin occluder); 0 = only the hold component.
  double merge_radius_px = 0.0;
  /// A kept mask smaller than this (pixels) is rejected (kSegmentationFailed).
  int min_area_px = 200;
  DepthMode depth_mode = DepthMode::kGate;
  int gate_dilation_px = 4;
  DepthSegmentationOptions depth;

  /// Throws RecognitionError(kInvalidOptions) naming the bad field.
  void validate() const;
};

struct SegmentationResult {
  cv::Mat mask;              ///< CV_8UC1, image size, 255 = textile
  int area_px = 0;
  cv::Rect bounding_box;
  int components = 0;        ///< foreground components before the hold component was chosen
  double hold_distance_px = 0;  ///< distance of the kept component from the hold pixel (0 = contains it)
  bool used_depth = false;
  int depth_points = 0;      ///< points in the kept depth cluster(s)
  /// Share of the image's pixels the colour model marks as textile, before depth gating and the choice
  /// of the hold component (-1: no colour model, depth_only). Evidence: EvidenceOptions::max_colour_fraction.
  double colour_fraction = -1;
};

/// The depth cluster connected to the hold point, as a CV_8UC1 mask (255 = kept) of the depth image's
/// size: pixels with valid depth inside the crop box, region-grown over pixel neighbours within
/// neighbour_radius_px whose 3-D distance is below cluster_tolerance_m (Euclidean clustering on the
/// organised cloud), seeded by the points within seed_radius_m of the hold point. `points` gets the
/// number of kept points. Throws kInvalidDepth (type / size: it must match the intrinsics' image size),
/// kSegmentationFailed (no depth point near the hold point, cluster too small), kInvalidOptions.
cv::Mat depthClusterMask(const cv::Mat& depth, const HoldGeometry& geometry, const DepthSegmentationOptions& options,
                         int* points = nullptr);

/// Segments the textile. `image` with `encoding` (toBgr8); `depth_cluster` (optional, CV_8UC1 of the
/// image size, e.g. depthClusterMask() or pointCloudClusterMask()) gates the colour mask per
/// options.depth_mode. Throws RecognitionError: kInvalidImage / kUnsupportedEncoding (image),
/// kInvalidDepth (a depth mask of another size or type), kInvalidOptions, kSegmentationFailed (nothing
/// at the hold point, or a mask below min_area_px; the message gives the numbers).
SegmentationResult segmentTextile(const cv::Mat& image, const std::string& encoding, const HoldGeometry& geometry,
                                  const SegmentationOptions& options = {}, const cv::Mat& depth_cluster = cv::Mat(),
                                  int depth_points = 0);

}  // namespace recognition
}  // namespace textile_handling
