#include "textile_handling/recognition/point_cloud_segmentation.h"

#include <cmath>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <sstream>

#include <opencv2/imgproc.hpp>
#include <pcl/filters/crop_box.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

std::vector<Vec3> depthImageToPoints(const cv::Mat& depth_in, const vision::PinholeIntrinsics& k) {
  const cv::Mat depth = depthToMetres(depth_in);
  std::vector<Vec3> out;
  for (int y = 0; y < depth.rows; ++y) {
    const float* d = depth.ptr<float>(y);
    for (int x = 0; x < depth.cols; ++x)
      if (std::isfinite(d[x])) out.emplace_back(d[x] * (x - k.cx) / k.fx, d[x] * (y - k.cy) / k.fy, d[x]);
  }
  return out;
}

cv::Mat pointCloudClusterMask(const std::vector<Vec3>& pts, const HoldGeometry& g, const DepthSegmentationOptions& o,
                              int* points) {
  SegmentationOptions check;
  check.depth = o;
  check.validate();
  // The cloud in the hold frame H (z up, origin at the hold point); `source` maps back to pts.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<std::size_t> source;
  cloud->reserve(pts.size());
  const Mat3 rt = g.rotation_camera_hold.transpose();
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (!pts[i].allFinite()) continue;
    const Vec3 q = rt * (pts[i] - g.hold_camera);
    cloud->push_back(pcl::PointXYZ(static_cast<float>(q.x()), static_cast<float>(q.y()), static_cast<float>(q.z())));
    source.push_back(i);
  }
  if (cloud->empty()) throw RecognitionError(RecognitionErrorCode::kInvalidDepth, "the point cloud has no finite point");

  pcl::CropBox<pcl::PointXYZ> crop;
  crop.setInputCloud(cloud);
  crop.setMin(Eigen::Vector4f(static_cast<float>(-o.half_width_m), static_cast<float>(-o.half_width_m),
                              static_cast<float>(-o.max_drop_m), 1.f));
  crop.setMax(Eigen::Vector4f(static_cast<float>(o.half_width_m), static_cast<float>(o.half_width_m),
                              static_cast<float>(o.top_m), 1.f));
  pcl::IndicesPtr inside(new pcl::Indices);
  crop.filter(*inside);
  if (inside->empty())
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed,
                           "no point of the cloud lies in the crop box below the hold point");

  // Voxel centroids (a voxel a quarter of the cluster tolerance wide): clustering cost no longer grows
  // with the sensor's resolution.
  const double voxel = o.voxel_size_m > 0 ? o.voxel_size_m : std::max(0.005, 0.25 * o.cluster_tolerance_m);
  std::unordered_map<std::int64_t, int> voxel_of_key;
  std::vector<int> voxel_of_point(inside->size());
  pcl::PointCloud<pcl::PointXYZ>::Ptr centroids(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<int> members;
  for (std::size_t k = 0; k < inside->size(); ++k) {
    const pcl::PointXYZ& p = (*cloud)[static_cast<std::size_t>((*inside)[k])];
    const std::int64_t ix = static_cast<std::int64_t>(std::floor(p.x / voxel)) + (1 << 20);
    const std::int64_t iy = static_cast<std::int64_t>(std::floor(p.y / voxel)) + (1 << 20);
    const std::int64_t iz = static_cast<std::int64_t>(std::floor(p.z / voxel)) + (1 << 20);
    const std::int64_t key = (ix << 42) | (iy << 21) | iz;
    auto it = voxel_of_key.find(key);
    if (it == voxel_of_key.end()) {
      it = voxel_of_key.emplace(key, static_cast<int>(centroids->size())).first;
      centroids->push_back(pcl::PointXYZ(0.f, 0.f, 0.f));
      members.push_back(0);
    }
    pcl::PointXYZ& c = (*centroids)[static_cast<std::size_t>(it->second)];
    c.x += p.x;
    c.y += p.y;
    c.z += p.z;
    ++members[static_cast<std::size_t>(it->second)];
    voxel_of_point[k] = it->second;
  }
  for (std::size_t v = 0; v < centroids->size(); ++v) {
    const float m = static_cast<float>(members[v]);
    (*centroids)[v].x /= m;
    (*centroids)[v].y /= m;
    (*centroids)[v].z /= m;
  }

  pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
  tree->setInputCloud(centroids);
  pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
  ec.setClusterTolerance(o.cluster_tolerance_m);
  ec.setMinClusterSize(1);
  ec.setMaxClusterSize(std::numeric_limits<int>::max());
  ec.setSearchMethod(tree);
  ec.setInputCloud(centroids);
  std::vector<pcl::PointIndices> clusters;
  ec.extract(clusters);

  // Clusters with a voxel within the seed radius of the hold point (the centroid may sit up to half a
  // voxel diagonal from its points).
  const double seed = o.seed_radius_m + 0.87 * voxel;
  const float seed2 = static_cast<float>(seed * seed);
  std::vector<char> keep_voxel(centroids->size(), 0);
  bool any_seed = false;
  for (const auto& c : clusters) {
    bool seeded = false;
    for (const auto idx : c.indices) {
      const pcl::PointXYZ& p = (*centroids)[static_cast<std::size_t>(idx)];
      if (p.x * p.x + p.y * p.y + p.z * p.z <= seed2) {
        seeded = true;
        break;
      }
    }
    if (!seeded) continue;
    any_seed = true;
    for (const auto idx : c.indices) keep_voxel[static_cast<std::size_t>(idx)] = 1;
  }
  cv::Mat mask(g.intrinsics.height, g.intrinsics.width, CV_8UC1, cv::Scalar(0));
  int kept = 0;
  const auto& k = g.intrinsics;
  for (std::size_t j = 0; j < inside->size(); ++j) {
    if (!keep_voxel[static_cast<std::size_t>(voxel_of_point[j])]) continue;
    ++kept;
    const Vec3& pc = pts[source[static_cast<std::size_t>((*inside)[j])]];
    if (!(pc.z() > 1e-6)) continue;
    const int u = static_cast<int>(std::lround(k.fx * pc.x() / pc.z() + k.cx));
    const int v = static_cast<int>(std::lround(k.fy * pc.y() / pc.z() + k.cy));
    if (u < 0 || v < 0 || u >= mask.cols || v >= mask.rows) continue;
    mask.at<std::uint8_t>(v, u) = 255;
  }
  if (!any_seed) {
    std::ostringstream os;
    os << "no point cluster comes within " << o.seed_radius_m << " m of the hold point (" << clusters.size()
       << " cluster(s) in the crop box): is the textile held, and is the cloud in the colour camera's optical frame?";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  if (kept < o.min_cluster_points) {
    std::ostringstream os;
    os << "the point cluster at the hold point has only " << kept << " points (minimum " << o.min_cluster_points << ")";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  if (o.splat_radius_px > 0)
    cv::dilate(mask, mask,
               cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * o.splat_radius_px + 1, 2 * o.splat_radius_px + 1)));
  if (points) *points = kept;
  return mask;
}

}  // namespace recognition
}  // namespace textile_handling
