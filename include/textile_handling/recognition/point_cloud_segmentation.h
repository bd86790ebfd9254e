// Depth segmentation from an (unorganised) point cloud, e.g. a sensor_msgs/PointCloud2 converted by the
// node: pcl::CropBox below the gripper, voxel centroids, pcl::EuclideanClusterExtraction, keeping the
// cluster(s) that touch the hold point, projected into the colour image as a mask that gates the colour
// segmentation (segmentation.h). PCL stays inside the .cpp. See docs/recognition.md.
#pragma once

#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/recognition/camera_geometry.h"
#include "textile_handling/recognition/segmentation.h"

namespace textile_handling {
namespace recognition {

/// `points_camera`: points in the colour camera's optical frame [m] (transform them there first);
/// non-finite points are skipped. Returns a CV_8UC1 mask of the intrinsics' image size: 255 at the
/// projection of every kept point, dilated by options.splat_radius_px. `points` gets the number of kept
/// points. Throws RecognitionError: kInvalidDepth (no finite point), kSegmentationFailed (no cluster
/// within seed_radius_m of the hold point, too few points), kInvalidOptions.
cv::Mat pointCloudClusterMask(const std::vector<Vec3>& points_camera, const HoldGeometry& geometry,
                              const DepthSegmentationOptions& options, int* points = nullptr);

/// The organised-cloud points of a depth image (for tests and for nodes that want a cloud): one point
/// per valid pixel, in the optical frame. Throws kInvalidDepth as depthToMetres().
std::vector<Vec3> depthImageToPoints(const cv::Mat& depth, const vision::PinholeIntrinsics& intrinsics);

}  // namespace recognition
}  // namespace textile_handling
