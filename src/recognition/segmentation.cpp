#include "textile_handling/recognition/segmentation.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <sstream>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

namespace {

[[noreturn]] void optionError(const std::string& what) {
  throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "segmentation: " + what);
}

bool finiteNonNeg(double v) { return std::isfinite(v) && v >= 0; }

cv::Mat ellipse(int r) { return cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)); }

// The image converted into the distance space (CV_8UC3) and the channels that count.
cv::Mat toSpace(const cv::Mat& bgr, ColourSpace s) {
  if (s == ColourSpace::kBgr) return bgr;
  cv::Mat lab;
  cv::cvtColor(bgr, lab, cv::COLOR_BGR2Lab);
  return lab;
}

int firstChannel(ColourSpace s) { return s == ColourSpace::kAb ? 1 : 0; }

std::array<double, 3> borderMedian(const cv::Mat& img, int border) {
  std::array<std::vector<std::uint8_t>, 3> v;
  const int b = std::max(1, std::min({border, img.rows / 2, img.cols / 2}));
  for (int y = 0; y < img.rows; ++y) {
    const cv::Vec3b* p = img.ptr<cv::Vec3b>(y);
    const bool full_row = y < b || y >= img.rows - b;
    for (int x = 0; x < img.cols; ++x) {
      if (!full_row && x >= b && x < img.cols - b) x = img.cols - b;
      for (int c = 0; c < 3; ++c) v[static_cast<std::size_t>(c)].push_back(p[x][c]);
    }
  }
  std::array<double, 3> m{};
  for (int c = 0; c < 3; ++c) {
    auto& w = v[static_cast<std::size_t>(c)];
    std::nth_element(w.begin(), w.begin() + static_cast<long>(w.size() / 2), w.end());
    m[static_cast<std::size_t>(c)] = w[w.size() / 2];
  }
  return m;
}

}  // namespace

cv::Mat toBgr8(const cv::Mat& image, const std::string& encoding) {
  const bool known = encoding == "bgr8" || encoding == "rgb8" || encoding == "mono8";
  if (!known)
    throw RecognitionError(RecognitionErrorCode::kUnsupportedEncoding,
                           "image encoding '" + encoding + "' is not supported (use bgr8, rgb8 or mono8)");
  if (image.empty()) throw RecognitionError(RecognitionErrorCode::kInvalidImage, "the camera image is empty");
  const int want = encoding == "mono8" ? CV_8UC1 : CV_8UC3;
  if (image.type() != want)
    throw RecognitionError(RecognitionErrorCode::kInvalidImage,
                           "a " + encoding + " image must be " + (want == CV_8UC1 ? "CV_8UC1" : "CV_8UC3") +
                               ", got cv::Mat type " + std::to_string(image.type()));
  if (encoding == "bgr8") return image;
  cv::Mat out;
  cv::cvtColor(image, out, encoding == "rgb8" ? cv::COLOR_RGB2BGR : cv::COLOR_GRAY2BGR);
  return out;
}

cv::Mat depthToMetres(const cv::Mat& depth) {
  if (depth.empty()) throw RecognitionError(RecognitionErrorCode::kInvalidDepth, "the depth image is empty");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat out(depth.size(), CV_32FC1);
  if (depth.type() == CV_32FC1) {
    for (int y = 0; y < depth.rows; ++y) {
      const float* s = depth.ptr<float>(y);
      float* d = out.ptr<float>(y);
      for (int x = 0; x < depth.cols; ++x) d[x] = std::isfinite(s[x]) && s[x] > 0 ? s[x] : nan;
    }
  } else if (depth.type() == CV_16UC1) {
    for (int y = 0; y < depth.rows; ++y) {
      const std::uint16_t* s = depth.ptr<std::uint16_t>(y);
      float* d = out.ptr<float>(y);
      for (int x = 0; x < depth.cols; ++x) d[x] = s[x] > 0 ? 0.001f * static_cast<float>(s[x]) : nan;
    }
  } else {
    throw RecognitionError(RecognitionErrorCode::kInvalidDepth,
                           "depth must be CV_32FC1 (metres) or CV_16UC1 (millimetres), got cv::Mat type " +
                               std::to_string(depth.type()));
  }
  return out;
}

const char* toString(BackgroundModel model) {
  switch (model) {
    case BackgroundModel::kUniformColour: return "uniform_colour";
    case BackgroundModel::kBorderMedian: return "border_median";
    case BackgroundModel::kBackgroundImage: return "background_image";
  }
  return "unknown";
}

const char* toString(ColourSpace space) {
  switch (space) {
    case ColourSpace::kBgr: return "bgr";
    case ColourSpace::kLab: return "lab";
    case ColourSpace::kAb: return "ab";
  }
  return "unknown";
}

const char* toString(DepthMode mode) {
  switch (mode) {
    case DepthMode::kColourOnly: return "colour_only";
    case DepthMode::kGate: return "gate";
    case DepthMode::kIntersect: return "intersect";
    case DepthMode::kDepthOnly: return "depth_only";
  }
  return "unknown";
}

namespace {

// The enumerator whose toString() is `name`; kInvalidOptions naming `field` and the accepted names.
template <typename Enum, std::size_t N>
Enum enumFromString(const std::string& name, const char* field, const Enum (&values)[N]) {
  std::string accepted;
  for (Enum v : values) {
    if (name == toString(v)) return v;
    accepted += (accepted.empty() ? "" : ", ") + std::string(toString(v));
  }
  optionError(std::string(field) + " '" + name + "' is not one of " + accepted);
}

}  // namespace

BackgroundModel backgroundModelFromString(const std::string& name) {
  static const BackgroundModel kAll[] = {BackgroundModel::kUniformColour, BackgroundModel::kBorderMedian,
                                         BackgroundModel::kBackgroundImage};
  return enumFromString(name, "background", kAll);
}

ColourSpace colourSpaceFromString(const std::string& name) {
  static const ColourSpace kAll[] = {ColourSpace::kBgr, ColourSpace::kLab, ColourSpace::kAb};
  return enumFromString(name, "colour_space", kAll);
}

DepthMode depthModeFromString(const std::string& name) {
  static const DepthMode kAll[] = {DepthMode::kColourOnly, DepthMode::kGate, DepthMode::kIntersect, DepthMode::kDepthOnly};
  return enumFromString(name, "depth_mode", kAll);
}

void SegmentationOptions::validate() const {
  if (!finiteNonNeg(threshold)) optionError("threshold must be finite and >= 0");
  if (open_radius_px < 0 || close_radius_px < 0 || gate_dilation_px < 0 || border_px < 1)
    optionError("radii must be >= 0 and border_px >= 1");
  if (open_radius_px > 100 || close_radius_px > 100 || gate_dilation_px > 100) optionError("radii must be <= 100 px");
  if (!finiteNonNeg(hold_search_radius_px) || !finiteNonNeg(merge_radius_px))
    optionError("hold_search_radius_px and merge_radius_px must be finite and >= 0");
  if (min_area_px < 1) optionError("min_area_px must be >= 1");
  if (background == BackgroundModel::kBackgroundImage && (background_image.empty() || background_image.type() != CV_8UC3))
    optionError("the background-image model needs a non-empty CV_8UC3 (bgr8) background_image");
  const DepthSegmentationOptions& d = depth;
  if (!(d.half_width_m > 0) || !std::isfinite(d.half_width_m) || !(d.max_drop_m > 0) || !std::isfinite(d.max_drop_m) ||
      !std::isfinite(d.top_m) || !(d.cluster_tolerance_m > 0) || !std::isfinite(d.cluster_tolerance_m) ||
      !(d.seed_radius_m > 0) || !std::isfinite(d.seed_radius_m) || !(d.voxel_size_m >= 0) || !std::isfinite(d.voxel_size_m))
    optionError("depth crop box, cluster tolerance and seed radius must be finite and > 0");
  if (d.neighbour_radius_px < 1 || d.neighbour_radius_px > 10 || d.min_cluster_points < 1 || d.splat_radius_px < 0 ||
      d.splat_radius_px > 20)
    optionError("depth neighbour_radius_px must be in 1..10, min_cluster_points >= 1, splat_radius_px in 0..20");
}

cv::Mat depthClusterMask(const cv::Mat& depth_in, const HoldGeometry& g, const DepthSegmentationOptions& o,
                         int* points) {
  SegmentationOptions check;
  check.depth = o;
  check.validate();
  const cv::Mat depth = depthToMetres(depth_in);
  if (depth.cols != g.intrinsics.width || depth.rows != g.intrinsics.height) {
    std::ostringstream os;
    os << "the depth image is " << depth.cols << " x " << depth.rows << " px, the colour camera's is "
       << g.intrinsics.width << " x " << g.intrinsics.height << " (it must be registered to the colour image)";
    throw RecognitionError(RecognitionErrorCode::kInvalidDepth, os.str());
  }
  const int w = depth.cols, h = depth.rows;
  const auto& k = g.intrinsics;
  const Mat3 rt = g.rotation_camera_hold.transpose();
  // Back-projected points inside the crop box (camera frame), NaN elsewhere.
  cv::Mat pts(h, w, CV_32FC3, cv::Scalar::all(std::numeric_limits<float>::quiet_NaN()));
  std::vector<int> seeds;
  const double seed2 = o.seed_radius_m * o.seed_radius_m;
  for (int y = 0; y < h; ++y) {
    const float* d = depth.ptr<float>(y);
    cv::Vec3f* p = pts.ptr<cv::Vec3f>(y);
    for (int x = 0; x < w; ++x) {
      const float z = d[x];
      if (!std::isfinite(z)) continue;
      const Vec3 pc(z * (x - k.cx) / k.fx, z * (y - k.cy) / k.fy, z);
      const Vec3 q = rt * (pc - g.hold_camera);
      if (std::abs(q.x()) > o.half_width_m || std::abs(q.y()) > o.half_width_m || q.z() < -o.max_drop_m || q.z() > o.top_m)
        continue;
      p[x] = cv::Vec3f(static_cast<float>(pc.x()), static_cast<float>(pc.y()), static_cast<float>(pc.z()));
      if (q.squaredNorm() <= seed2) seeds.push_back(y * w + x);
    }
  }
  if (seeds.empty()) {
    std::ostringstream os;
    os << "no depth point inside the crop box lies within " << o.seed_radius_m
       << " m of the hold point: is the textile held, and is the depth image registered to the colour image?";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  // Region growing from the seeds (Euclidean clustering on the organised cloud).
  cv::Mat out(h, w, CV_8UC1, cv::Scalar(0));
  std::deque<int> queue;
  for (int s : seeds) {
    out.data[s] = 255;
    queue.push_back(s);
  }
  const float tol2 = static_cast<float>(o.cluster_tolerance_m * o.cluster_tolerance_m);
  const int r = o.neighbour_radius_px;
  int count = 0;
  while (!queue.empty()) {
    const int idx = queue.front();
    queue.pop_front();
    ++count;
    const int x = idx % w, y = idx / w;
    const cv::Vec3f p = pts.at<cv::Vec3f>(y, x);
    for (int yy = std::max(0, y - r); yy <= std::min(h - 1, y + r); ++yy) {
      const cv::Vec3f* row = pts.ptr<cv::Vec3f>(yy);
      std::uint8_t* orow = out.ptr<std::uint8_t>(yy);
      for (int xx = std::max(0, x - r); xx <= std::min(w - 1, x + r); ++xx) {
        if (orow[xx] || !std::isfinite(row[xx][2])) continue;
        const cv::Vec3f d = row[xx] - p;
        if (d.dot(d) <= tol2) {
          orow[xx] = 255;
          queue.push_back(yy * w + xx);
        }
      }
    }
  }
  if (count < o.min_cluster_points) {
    std::ostringstream os;
    os << "the depth cluster at the hold point has only " << count << " points (minimum " << o.min_cluster_points << ")";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  if (points) *points = count;
  return out;
}

SegmentationResult segmentTextile(const cv::Mat& image, const std::string& encoding, const HoldGeometry& g,
                                  const SegmentationOptions& o, const cv::Mat& depth_cluster, int depth_points) {
  o.validate();
  const cv::Mat bgr = toBgr8(image, encoding);
  if (bgr.cols != g.intrinsics.width || bgr.rows != g.intrinsics.height) {
    std::ostringstream os;
    os << "the image is " << bgr.cols << " x " << bgr.rows << " px, the camera info says " << g.intrinsics.width
       << " x " << g.intrinsics.height;
    throw RecognitionError(RecognitionErrorCode::kInvalidImage, os.str());
  }
  const bool use_depth = !depth_cluster.empty() && o.depth_mode != DepthMode::kColourOnly;
  if (use_depth && (depth_cluster.type() != CV_8UC1 || depth_cluster.size() != bgr.size()))
    throw RecognitionError(RecognitionErrorCode::kInvalidDepth,
                           "the depth cluster mask must be CV_8UC1 of the colour image's size");
  if (!use_depth && o.depth_mode == DepthMode::kDepthOnly)
    throw RecognitionError(RecognitionErrorCode::kInvalidDepth, "depth_mode depth_only needs a depth image or point cloud");

  SegmentationResult res;
  cv::Mat mask;
  if (use_depth && o.depth_mode == DepthMode::kDepthOnly) {
    mask = depth_cluster.clone();
  } else {
    const cv::Mat img = toSpace(bgr, o.colour_space);
    const int c0 = firstChannel(o.colour_space);
    mask = cv::Mat(bgr.size(), CV_8UC1, cv::Scalar(0));
    const double t2 = o.threshold * o.threshold;
    cv::Mat bg_img;
    std::array<double, 3> bg{};
    if (o.background == BackgroundModel::kBackgroundImage) {
      if (o.background_image.size() != bgr.size())
        throw RecognitionError(RecognitionErrorCode::kInvalidImage,
                               "the background image's size differs from the camera image's");
      bg_img = toSpace(o.background_image, o.colour_space);
    } else if (o.background == BackgroundModel::kBorderMedian) {
      bg = borderMedian(img, o.border_px);
    } else {
      cv::Mat px(1, 1, CV_8UC3, cv::Scalar(o.background_bgr[0], o.background_bgr[1], o.background_bgr[2]));
      const cv::Vec3b c = toSpace(px, o.colour_space).at<cv::Vec3b>(0, 0);
      bg = {static_cast<double>(c[0]), static_cast<double>(c[1]), static_cast<double>(c[2])};
    }
    for (int y = 0; y < img.rows; ++y) {
      const cv::Vec3b* p = img.ptr<cv::Vec3b>(y);
      const cv::Vec3b* b = bg_img.empty() ? nullptr : bg_img.ptr<cv::Vec3b>(y);
      std::uint8_t* m = mask.ptr<std::uint8_t>(y);
      for (int x = 0; x < img.cols; ++x) {
        double d2 = 0;
        for (int c = c0; c < 3; ++c) {
          const double ref = b ? static_cast<double>(b[x][c]) : bg[static_cast<std::size_t>(c)];
          const double d = static_cast<double>(p[x][c]) - ref;
          d2 += d * d;
        }
        m[x] = d2 > t2 ? 255 : 0;
      }
    }
    res.colour_fraction = static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(mask.total());
    if (use_depth) {
      cv::Mat gate;  // never write into the caller's mask
      if (o.depth_mode == DepthMode::kGate && o.gate_dilation_px > 0)
        cv::dilate(depth_cluster, gate, ellipse(o.gate_dilation_px));
      else
        gate = depth_cluster;
      cv::bitwise_and(mask, gate, mask);
    }
  }
  res.used_depth = use_depth;
  res.depth_points = use_depth ? depth_points : 0;
  if (o.open_radius_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_OPEN, ellipse(o.open_radius_px));
  if (o.close_radius_px > 0) cv::morphologyEx(mask, mask, cv::MORPH_CLOSE, ellipse(o.close_radius_px));

  // The component at the hold pixel.
  cv::Mat labels, stats, centroids;
  const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  res.components = n - 1;
  const Vec2 hp = g.hold_pixel;
  const double r = o.hold_search_radius_px;
  std::vector<double> best(static_cast<std::size_t>(n), std::numeric_limits<double>::infinity());
  const int x0 = std::max(0, static_cast<int>(std::floor(hp.x() - r))), x1 = std::min(mask.cols - 1, static_cast<int>(std::ceil(hp.x() + r)));
  const int y0 = std::max(0, static_cast<int>(std::floor(hp.y() - r))), y1 = std::min(mask.rows - 1, static_cast<int>(std::ceil(hp.y() + r)));
  for (int y = y0; y <= y1; ++y) {
    const int* l = labels.ptr<int>(y);
    for (int x = x0; x <= x1; ++x) {
      if (l[x] == 0) continue;
      const double d = std::hypot(x - hp.x(), y - hp.y());
      double& b = best[static_cast<std::size_t>(l[x])];
      b = std::min(b, d);
    }
  }
  int keep = 0;
  for (int l = 1; l < n; ++l) {
    const double d = best[static_cast<std::size_t>(l)];
    if (!(d <= r)) continue;
    const double bd = keep ? best[static_cast<std::size_t>(keep)] : std::numeric_limits<double>::infinity();
    if (d < bd - 1e-9 || (std::abs(d - bd) <= 1e-9 && stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(keep, cv::CC_STAT_AREA)))
      keep = l;
  }
  if (keep == 0) {
    int largest = 0;
    for (int l = 1; l < n; ++l) largest = std::max(largest, stats.at<int>(l, cv::CC_STAT_AREA));
    std::ostringstream os;
    os << "no textile component within " << r << " px of the hold pixel (" << hp.x() << ", " << hp.y() << "); "
       << res.components << " foreground component(s)" << (res.components ? ", the largest " + std::to_string(largest) + " px" : "")
       << (use_depth ? " after depth gating" : "") << ": check the background model and the hold point";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  res.hold_distance_px = best[static_cast<std::size_t>(keep)];
  cv::Mat kept = labels == keep;
  if (o.merge_radius_px > 0) {
    cv::Mat grown;
    cv::dilate(kept, grown, ellipse(static_cast<int>(std::ceil(o.merge_radius_px))));
    std::vector<char> merge(static_cast<std::size_t>(n), 0);
    for (int y = 0; y < mask.rows; ++y) {
      const int* l = labels.ptr<int>(y);
      const std::uint8_t* gr = grown.ptr<std::uint8_t>(y);
      for (int x = 0; x < mask.cols; ++x)
        if (l[x] > 0 && gr[x]) merge[static_cast<std::size_t>(l[x])] = 1;
    }
    for (int y = 0; y < mask.rows; ++y) {
      const int* l = labels.ptr<int>(y);
      std::uint8_t* kp = kept.ptr<std::uint8_t>(y);
      for (int x = 0; x < mask.cols; ++x)
        if (l[x] > 0 && merge[static_cast<std::size_t>(l[x])]) kp[x] = 255;
    }
  }
  if (o.fill_holes) {
    cv::Mat inv;
    cv::bitwise_not(kept, inv);
    cv::Mat padded;
    cv::copyMakeBorder(inv, padded, 1, 1, 1, 1, cv::BORDER_CONSTANT, cv::Scalar(255));
    cv::floodFill(padded, cv::Point(0, 0), cv::Scalar(0));
    cv::Mat holes = padded(cv::Rect(1, 1, kept.cols, kept.rows));
    cv::bitwise_or(kept, holes, kept);
  }
  res.area_px = cv::countNonZero(kept);
  if (res.area_px < o.min_area_px) {
    std::ostringstream os;
    os << "the textile component at the hold point has " << res.area_px << " px, fewer than min_area_px = " << o.min_area_px
       << " (too small or too far away)";
    throw RecognitionError(RecognitionErrorCode::kSegmentationFailed, os.str());
  }
  res.bounding_box = cv::boundingRect(kept);
  res.mask = kept;
  return res;
}

}  // namespace recognition
}  // namespace textile_handling
