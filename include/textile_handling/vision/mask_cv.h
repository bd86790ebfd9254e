// OpenCV side of the silhouette pipeline: BitMask <-> cv::Mat, and canonicalising a segmented camera
// mask into the canonical frame of the renderer (silhouette_renderer.h), so that camera images and
// database renders are compared at the same metric scale. See docs/vision.md.
#pragma once

#include <opencv2/core.hpp>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace vision {

/// CV_8UC1 image, 255 where the mask is set and 0 elsewhere.
cv::Mat toMat(const BitMask& mask);
/// Mask of the non-zero pixels of a single-channel 8-bit image (CV_8UC1; other types throw
/// std::invalid_argument). An empty cv::Mat gives an empty BitMask.
BitMask fromMat(const cv::Mat& image);

/// Metres per pixel (x, y) at depth `depth` [m] along the optical axis: (depth / fx, depth / fy).
/// Throws std::invalid_argument for a non-positive / non-finite depth or focal length.
Vec2 metresPerPixelAtDepth(const PinholeIntrinsics& intrinsics, double depth);

/// Limits of canonicaliseCameraMask() (docs/vision.md): the hold pixel lies at most kMaxHoldPixelOffset
/// px from the image origin; one canonical pixel spans between 1/kMaxScaleRatio and kMaxScaleRatio
/// camera pixels (a camera 10^4 times finer or coarser than the database frame is a wrong scale, not a
/// camera); the resampling allocates at most kMaxCoverageBytes.
constexpr double kMaxHoldPixelOffset = 1e7;
constexpr double kMaxScaleRatio = 1e4;
constexpr std::size_t kMaxCoverageBytes = std::size_t{512} << 20;

/// Puts a segmented camera mask into the canonical frame.
///  mask:            CV_8UC1, non-zero = textile (any size);
///  hold_pixel:      the hold point's image position (pixel centres at integer coordinates, as in the
///                   intrinsics);
///  metres_per_pixel: (x, y) scale at the hold point's depth, e.g. metresPerPixelAtDepth(K, depth).
/// Each canonical pixel takes the exact area-weighted fraction of textile pixels under it (camera pixels
/// are treated as uniformly covered squares; outside the image counts as background) and is set when
/// that fraction is >= frame.coverage_threshold, the same rule the mesh renderer applies.
/// Throws std::invalid_argument for an empty or wrongly typed mask, non-finite hold pixel, or
/// non-positive scale, or an invalid frame, and (before allocating) for a hold pixel, scale or
/// resampling size beyond the limits above.
BitMask canonicaliseCameraMask(const cv::Mat& mask, const Vec2& hold_pixel, const Vec2& metres_per_pixel,
                               const CanonicalFrame& frame = {});

/// Coverage fractions (CV_32FC1, frame size) behind canonicaliseCameraMask(); for tests and debugging.
cv::Mat canonicalCoverage(const cv::Mat& mask, const Vec2& hold_pixel, const Vec2& metres_per_pixel,
                          const CanonicalFrame& frame = {});

}  // namespace vision
}  // namespace textile_handling
