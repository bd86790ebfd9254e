#include "textile_handling/recognition/grasp_point_localisation.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

bool locatedFromData(GraspPointEvidence e) {
  return e == GraspPointEvidence::kOutlineCorner || e == GraspPointEvidence::kLowestPoint;
}

std::string toString(GraspPointEvidence e) {
  switch (e) {
    case GraspPointEvidence::kModel: return "model";
    case GraspPointEvidence::kSurface: return "surface";
    case GraspPointEvidence::kOutlineCorner: return "outline_corner";
    case GraspPointEvidence::kLowestPoint: return "lowest_point";
  }
  return "model";
}

void GraspPointLocalisationOptions::validate() const {
  auto bad = [](const std::string& what) { throw RecognitionError(RecognitionErrorCode::kInvalidOptions, what); };
  if (!(search_radius_m >= 0) || !(search_radius_m <= 2.0) || !(lowest_search_radius_m >= 0) || !(lowest_search_radius_m <= 2.0))
    bad("localisation.search_radius_m and lowest_search_radius_m must be in [0, 2]");
  if (!(lowest_height_slack_m >= 0) || !std::isfinite(lowest_height_slack_m))
    bad("localisation.lowest_height_slack_m must be finite and >= 0");
  if (!(hold_exclusion_m >= 0) || !std::isfinite(hold_exclusion_m)) bad("localisation.hold_exclusion_m must be finite and >= 0");
  if (!(arm_m > 0) || !(arm_m <= 0.5)) bad("localisation.arm_m must be in (0, 0.5]");
  if (!(max_corner_angle_deg > 0) || !(max_corner_angle_deg < 180)) bad("localisation.max_corner_angle_deg must be in (0, 180)");
  if (depth_window_px < 0 || depth_window_px > 32) bad("localisation.depth_window_px must be in 0..32");
  if (!(agreement_m >= 0) || !std::isfinite(agreement_m)) bad("localisation.agreement_m must be finite and >= 0");
  if (!std::isfinite(min_move_margin_m)) bad("localisation.min_move_margin_m must be finite");
}

namespace {

bool validView(const GraspPointView& v) {
  const int w = v.intrinsics.width, h = v.intrinsics.height;
  return w > 0 && h > 0 && v.mask.type() == CV_8UC1 && v.mask.cols == w && v.mask.rows == h && !v.depth.empty() &&
         v.depth.type() == CV_32FC1 && v.depth.cols == w && v.depth.rows == h && v.intrinsics.fx > 0 && v.intrinsics.fy > 0;
}

bool validDepth(float d) { return std::isfinite(d) && d > 0; }

// Median measured depth of the mask pixels in rows [y0, y1] and columns [x0, x1] (clipped), every
// `step`-th pixel; NaN if none.
double medianMaskDepth(const GraspPointView& v, int x0, int y0, int x1, int y1, int step = 1) {
  std::vector<float> d;
  for (int y = std::max(0, y0); y <= std::min(v.mask.rows - 1, y1); y += step)
    for (int x = std::max(0, x0); x <= std::min(v.mask.cols - 1, x1); x += step)
      if (v.mask.at<std::uint8_t>(y, x) != 0 && validDepth(v.depth.at<float>(y, x))) d.push_back(v.depth.at<float>(y, x));
  if (d.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

Vec3 toPosesFrame(const GraspPointView& v, double u, double row, double z) {
  const Vec3 c((u - v.intrinsics.cx) / v.intrinsics.fx * z, (row - v.intrinsics.cy) / v.intrinsics.fy * z, z);
  return v.rotation.transpose() * (c - v.translation);
}

// The textile has one lowest point: a view's lowest outline corner hanging more than `agreement_m`
// above another view's is a fold or a side corner (the real lowest point is round or hidden in that
// view), so it loses the mark.
void keepOneLowestHeight(double agreement_m, std::vector<std::vector<OutlineCorner>>* per_view) {
  double lowest_z = std::numeric_limits<double>::infinity();
  for (const auto& corners : *per_view)
    for (const OutlineCorner& c : corners)
      if (c.lowest) lowest_z = std::min(lowest_z, c.position.z());
  for (auto& corners : *per_view)
    for (OutlineCorner& c : corners)
      if (c.lowest && c.position.z() > lowest_z + agreement_m) c.lowest = false;
}


// OutlineCorner::tip_depth_residual_m: the RMS residual [m] of a plane z = a X + b Y + c (X, Y lateral
// metric coordinates) fitted to the mask's measured depth within `radius_px` of pixel (u, row); NaN with
// fewer than 6 pixels.
double tipDepthResidual(const GraspPointView& v, int u, int row, int radius_px) {
  Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
  Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
  std::vector<Eigen::Vector3d> pts;
  for (int y = std::max(0, row - radius_px); y <= std::min(v.mask.rows - 1, row + radius_px); ++y)
    for (int x = std::max(0, u - radius_px); x <= std::min(v.mask.cols - 1, u + radius_px); ++x) {
      if ((x - u) * (x - u) + (y - row) * (y - row) > radius_px * radius_px) continue;
      const float z = v.depth.at<float>(y, x);
      if (v.mask.at<std::uint8_t>(y, x) == 0 || !validDepth(z)) continue;
      pts.emplace_back((x - v.intrinsics.cx) / v.intrinsics.fx * z, (y - v.intrinsics.cy) / v.intrinsics.fy * z, z);
    }
  if (pts.size() < 6) return std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : pts) mean += p;
  mean /= static_cast<double>(pts.size());
  for (const auto& p : pts) {
    const Eigen::Vector3d r(p.x() - mean.x(), p.y() - mean.y(), 1.0);
    AtA += r * r.transpose();
    Atb += r * (p.z() - mean.z());
  }
  const Eigen::Vector3d abc = AtA.ldlt().solve(Atb);
  double ss = 0;
  for (const auto& p : pts) {
    const double e = p.z() - mean.z() - abc(0) * (p.x() - mean.x()) - abc(1) * (p.y() - mean.y()) - abc(2);
    ss += e * e;
  }
  return std::sqrt(ss / pts.size());
}

// The depth noise of one view [m]: the standard deviation of independent per-pixel noise, from the median
// absolute second difference d(x-1) - 2 d(x) + d(x+1) along rows of mask pixels (std sqrt(6) sigma for
// independent noise; the cloth's own curvature adds little over 3 pixels). NaN without such triples.
double depthNoiseSigma(const GraspPointView& v) {
  std::vector<float> second;
  for (int y = 0; y < v.mask.rows; ++y) {
    const std::uint8_t* m = v.mask.ptr<std::uint8_t>(y);
    const float* d = v.depth.ptr<float>(y);
    for (int x = 1; x + 1 < v.mask.cols; ++x)
      if (m[x - 1] && m[x] && m[x + 1] && validDepth(d[x - 1]) && validDepth(d[x]) && validDepth(d[x + 1]))
        second.push_back(std::abs(d[x - 1] - 2 * d[x] + d[x + 1]));
  }
  if (second.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::nth_element(second.begin(), second.begin() + static_cast<long>(second.size() / 2), second.end());
  return second[second.size() / 2] / (0.6745 * std::sqrt(6.0));
}

}  // namespace

std::vector<OutlineCorner> findOutlineCorners(const GraspPointView& view, const GraspPointLocalisationOptions& o) {
  std::vector<OutlineCorner> out;
  if (!validView(view)) return out;
  const double z_median = medianMaskDepth(view, 0, 0, view.mask.cols - 1, view.mask.rows - 1, 2);
  if (!std::isfinite(z_median)) return out;
  cv::Mat m;
  cv::compare(view.mask, 0, m, cv::CMP_NE);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(m, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  if (contours.empty()) return out;
  const auto largest = std::max_element(contours.begin(), contours.end(), [](const auto& a, const auto& b) {
    return std::abs(cv::contourArea(a)) < std::abs(cv::contourArea(b));
  });
  const std::vector<cv::Point>& c = *largest;
  const int n = static_cast<int>(c.size());
  const int k = std::max(2, static_cast<int>(std::lround(o.arm_m * view.intrinsics.fx / z_median)));
  if (n < 4 * k) return out;
  // Orientation of the contour: the sign of its area decides which turn is convex.
  const double orientation = cv::contourArea(c, true) > 0 ? 1.0 : -1.0;
  double noise_sigma = -1;  // depthNoiseSigma(view), computed for the first corner that needs it
  std::vector<double> angle(n, 180.0);
  std::vector<bool> convex(n, false);
  for (int i = 0; i < n; ++i) {
    const cv::Point a = c[(i - k + n) % n] - c[i], b = c[(i + k) % n] - c[i];
    const double na = std::hypot(a.x, a.y), nb = std::hypot(b.x, b.y);
    if (na < 1e-9 || nb < 1e-9) continue;
    const double cosang = std::clamp((a.x * b.x + a.y * b.y) / (na * nb), -1.0, 1.0);
    angle[i] = std::acos(cosang) * 180.0 / M_PI;
    // Walking c[i-k] -> c[i] -> c[i+k], a convex vertex turns the same way as the contour's orientation.
    const cv::Point d1 = c[i] - c[(i - k + n) % n], d2 = c[(i + k) % n] - c[i];
    convex[i] = orientation * (static_cast<double>(d1.x) * d2.y - static_cast<double>(d1.y) * d2.x) > 0;
  }
  for (int i = 0; i < n; ++i) {
    if (!convex[i] || !(angle[i] < o.max_corner_angle_deg)) continue;
    bool minimum = true;
    for (int j = -k; j <= k && minimum; ++j) {
      if (j == 0) continue;
      const int q = (i + j + n) % n;
      // Strict on one side so that a flat-bottomed minimum yields one corner.
      if (angle[q] < angle[i] || (j < 0 && angle[q] <= angle[i])) minimum = false;
    }
    if (!minimum) continue;
    const int r = o.depth_window_px;
    const double z = medianMaskDepth(view, c[i].x - r, c[i].y - r, c[i].x + r, c[i].y + r);
    if (!std::isfinite(z)) continue;
    OutlineCorner oc;
    oc.angle_deg = angle[i];
    oc.position = toPosesFrame(view, c[i].x, c[i].y, z);
    if (oc.position.norm() < o.hold_exclusion_m) continue;
    const double residual = tipDepthResidual(view, c[i].x, c[i].y, k);
    oc.tip_depth_residual_m = std::isfinite(residual) ? residual : 0.0;
    if (noise_sigma < 0) {
      const double s = depthNoiseSigma(view);
      noise_sigma = std::isfinite(s) ? s : 0.0;
    }
    oc.depth_noise_m = noise_sigma;
    out.push_back(oc);
  }
  if (!out.empty()) {
    auto low = std::min_element(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.position.z() < b.position.z(); });
    low->lowest = true;
  }
  return out;
}

std::vector<GraspPointLocation> locateGraspPoints(const std::vector<Vec3>& predicted, const std::vector<bool>& is_corner,
                                                  const std::vector<bool>& observed,
                                                  const std::vector<GraspPointView>& views,
                                                  const GraspPointLocalisationOptions& o) {
  const std::size_t n = predicted.size();
  if (is_corner.size() != n || observed.size() != n)
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "locateGraspPoints: is_corner and observed need one entry per point");
  std::vector<GraspPointLocation> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    out[i].position = predicted[i];
    out[i].evidence = observed[i] ? GraspPointEvidence::kSurface : GraspPointEvidence::kModel;
  }
  if (!o.enabled) return out;
  double lowest_predicted = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < n; ++i)
    if (is_corner[i] && predicted[i].allFinite()) lowest_predicted = std::min(lowest_predicted, predicted[i].z());
  // Per point, the outline corners assigned to it (one per image).
  std::vector<std::vector<OutlineCorner>> per_view;
  for (const GraspPointView& v : views) per_view.push_back(findOutlineCorners(v, o));
  keepOneLowestHeight(o.agreement_m, &per_view);
  std::vector<std::vector<OutlineCorner>> assigned(n);
  for (const std::vector<OutlineCorner>& corners : per_view) {
    std::vector<bool> point_used(n, false), corner_used(corners.size(), false);
    std::vector<std::tuple<double, std::size_t, std::size_t>> pairs;
    for (std::size_t i = 0; i < n; ++i) {
      if (!is_corner[i] || !predicted[i].allFinite()) continue;
      const bool hangs_low = predicted[i].z() <= lowest_predicted + o.lowest_height_slack_m;
      for (std::size_t j = 0; j < corners.size(); ++j) {
        const double d = (corners[j].position - predicted[i]).norm();
        const double radius = corners[j].lowest && hangs_low ? std::max(o.lowest_search_radius_m, o.search_radius_m) : o.search_radius_m;
        if (d <= radius) pairs.emplace_back(d, i, j);
      }
    }
    std::sort(pairs.begin(), pairs.end());
    for (const auto& [d, i, j] : pairs) {
      if (point_used[i] || corner_used[j]) continue;
      point_used[i] = corner_used[j] = true;
      assigned[i].push_back(corners[j]);
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (assigned[i].empty()) continue;
    const auto nearest = std::min_element(assigned[i].begin(), assigned[i].end(), [&](const auto& a, const auto& b) {
      return (a.position - predicted[i]).norm() < (b.position - predicted[i]).norm();
    });
    GraspPointLocation L;
    Vec3 sum = Vec3::Zero();
    bool lowest = false;
    L.tip_roughness_m = std::numeric_limits<double>::infinity();
    for (const OutlineCorner& c : assigned[i]) {
      if ((c.position - nearest->position).norm() > o.agreement_m) continue;
      sum += c.position;
      ++L.images;
      lowest = lowest || c.lowest;
      L.tip_roughness_m = std::min(L.tip_roughness_m, c.tipRoughness());
    }
    L.position = sum / L.images;
    for (const OutlineCorner& c : assigned[i]) {
      if ((c.position - nearest->position).norm() <= o.agreement_m) continue;
      ++L.disagreeing_images;
      L.disagreement_m = std::max(L.disagreement_m, (c.position - L.position).norm());
    }
    L.shift_m = (L.position - predicted[i]).norm();
    for (std::size_t j = 0; j < n; ++j)
      if (j != i && predicted[j].allFinite())
        L.label_margin_m = std::min(L.label_margin_m, (L.position - predicted[j]).norm() - L.shift_m);
    L.evidence = lowest ? GraspPointEvidence::kLowestPoint : GraspPointEvidence::kOutlineCorner;
    L.tip_angle_deg = nearest->angle_deg;
    // An ambiguous long move is not made: the point keeps its prior (out[i]).
    if (L.shift_m > o.search_radius_m && L.label_margin_m < o.min_move_margin_m) continue;
    out[i] = L;
  }
  return out;
}

}  // namespace recognition
}  // namespace textile_handling
