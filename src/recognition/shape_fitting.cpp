#include "textile_handling/recognition/shape_fitting.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>

#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <opencv2/imgproc.hpp>

#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace recognition {

namespace {

bool validDepth(float z) { return std::isfinite(z) && z > 0; }

// Bilinear depth at (u, v) from the four surrounding pixels, all inside the mask, valid and within
// `discontinuity` of each other (else no sample: an edge between layers or the outline).
bool sampleDepth(const cv::Mat& depth, const cv::Mat& mask, double u, double v, double discontinuity, double* z) {
  const int x0 = static_cast<int>(std::floor(u)), y0 = static_cast<int>(std::floor(v));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= depth.cols || y0 + 1 >= depth.rows) return false;
  double zs[4];
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  for (int k = 0; k < 4; ++k) {
    const int x = x0 + (k & 1), y = y0 + (k >> 1);
    const float d = depth.at<float>(y, x);
    if (!mask.at<std::uint8_t>(y, x) || !validDepth(d)) return false;
    zs[k] = d;
    lo = std::min(lo, zs[k]);
    hi = std::max(hi, zs[k]);
  }
  if (hi - lo > discontinuity) return false;
  const double fx = u - x0, fy = v - y0;
  *z = (1 - fy) * ((1 - fx) * zs[0] + fx * zs[1]) + fy * ((1 - fx) * zs[2] + fx * zs[3]);
  return true;
}

Vec3 backProject(const vision::PinholeIntrinsics& k, double u, double v, double z) {
  return Vec3((u - k.cx) * z / k.fx, (v - k.cy) * z / k.fy, z);
}

// The rotation R closest to `a` (maximising tr(R^T a)), refined from the warm start `q` in place: the
// iteration of Mueller, Bender, Chentanez and Macklin, "A robust method to extract the rotational part of
// deformations" (MIG 2016). It needs no SVD, copes with the rank-2 covariance of a flat neighbourhood and
// converges in one or two steps from the previous iteration's rotation.
void extractRotation(const Mat3& a, Eigen::Quaterniond& q, int max_steps = 8) {
  for (int step = 0; step < max_steps; ++step) {
    const Mat3 r = q.toRotationMatrix();
    Vec3 omega = r.col(0).cross(a.col(0)) + r.col(1).cross(a.col(1)) + r.col(2).cross(a.col(2));
    const double align = std::abs(r.col(0).dot(a.col(0)) + r.col(1).dot(a.col(1)) + r.col(2).dot(a.col(2)));
    omega /= align + 1e-12;
    const double w = omega.norm();
    if (w < 1e-9) break;
    q = Eigen::Quaterniond(Eigen::AngleAxisd(w, omega / w)) * q;
    q.normalize();
  }
}

}  // namespace

VecX fitShapeToDepth(const VecX& x0, const std::vector<vision::Triangle>& triangles, Index fixed_vertex,
                     const cv::Mat& depth, const cv::Mat& mask, const vision::PinholeIntrinsics& k,
                     const ShapeFitOptions& o, ShapeFitReport* report) {
  DepthView view;
  view.depth = depth;
  view.mask = mask;
  view.intrinsics = k;
  return fitShapeToDepthViews(x0, triangles, fixed_vertex, {view}, o, report);
}

namespace {

using Edge = std::pair<Index, Index>;

// What a view needs in every iteration: the nearest mask pixel of every pixel (for vertices projecting
// outside the mask).
struct PreparedView {
  const DepthView* v = nullptr;
  cv::Mat dist, labels;
  std::vector<cv::Point> label_pixel;
  cv::Rect mask_box;  // bounding box of the mask's pixels
};

// Correspondence limits of one iteration: from o.reach_m down to max_correspondence_m (geometrically, over
// the first half of the iterations), with the robust scale and the silhouette limit shrinking alike, so a
// part of the shape far from the data is pulled in first and a near one is then fitted without being
// distracted by another layer.
struct IterationLimits {
  double radius = 0, robust_scale = 0, silhouette_limit = 0;
};

IterationLimits iterationLimits(const ShapeFitOptions& o, int it) {
  const double anneal = std::min(1.0, it / std::max(1.0, 0.5 * o.iterations));
  IterationLimits l;
  l.radius = std::max(o.max_correspondence_m,
                      o.reach_m * std::pow(o.max_correspondence_m / std::max(o.reach_m, o.max_correspondence_m), anneal));
  l.robust_scale = o.robust_scale_m * l.radius / o.max_correspondence_m;
  l.silhouette_limit = std::max(3 * o.max_correspondence_m, l.radius);
  return l;
}

// The data terms of one iteration: per vertex the summed weight and the weighted sum of its targets (common
// frame), and the counts for the report.
struct DataTerms {
  std::vector<double> w;
  std::vector<Vec3> target_sum;
  int depth_corr = 0, sil_corr = 0, visible = 0;
  double residual = 0;
  explicit DataTerms(Index n) : w(static_cast<size_t>(n), 0.0), target_sum(static_cast<size_t>(n), Vec3::Zero()) {}
  // A target given in the camera frame of `view`.
  void add(const DepthView& view, Index i, double weight, const Vec3& t_camera) {
    w[static_cast<size_t>(i)] += weight;
    target_sum[static_cast<size_t>(i)] += weight * (view.rotation.transpose() * (t_camera - view.translation));
  }
};

void validateFitInput(const VecX& x0, const std::vector<vision::Triangle>& triangles, Index fixed_vertex,
                      const std::vector<DepthView>& views, const ShapeFitOptions& o) {
  const Index n = static_cast<Index>(x0.size() / 3);
  if (x0.size() % 3 != 0 || n == 0)
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "fitShapeToDepth: positions x0 must be 3 per vertex");
  if (fixed_vertex >= n) throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "fitShapeToDepth: fixed_vertex out of range");
  if (views.empty()) throw RecognitionError(RecognitionErrorCode::kInvalidDepth, "fitShapeToDepth: no view");
  for (const DepthView& v : views) {
    const auto& k = v.intrinsics;
    if (v.depth.type() != CV_32FC1 || v.mask.type() != CV_8UC1 || v.depth.size() != v.mask.size() ||
        v.depth.cols != k.width || v.depth.rows != k.height)
      throw RecognitionError(RecognitionErrorCode::kInvalidDepth,
                             "fitShapeToDepth: depth (CV_32FC1) and mask (CV_8UC1) must have the intrinsics' size");
    if (!v.rotation.allFinite() || !v.translation.allFinite() ||
        !(v.rotation * v.rotation.transpose()).isApprox(Mat3::Identity(), 1e-6))
      throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "fitShapeToDepth: a view's rotation must be finite and orthonormal");
  }
  if (!(o.iterations >= 1) || !(o.edge_weight > 0) || !(o.anchor_weight >= 0) || !(o.silhouette_weight >= 0) ||
      !(o.max_correspondence_m > 0) || !(o.uncovered_step_px >= 1) || !(o.reach_m >= 0) || !std::isfinite(o.reach_m) ||
      !std::isfinite(o.max_correspondence_m))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions,
                           "fitShapeToDepth: invalid options (iterations, edge_weight, anchor_weight, silhouette_weight, "
                           "max_correspondence_m, reach_m or uncovered_step_px)");
  for (const auto& t : triangles)
    for (Index v : t)
      if (v < 0 || v >= n) throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "fitShapeToDepth: triangle index out of range");
}

std::vector<Edge> uniqueEdges(const std::vector<vision::Triangle>& triangles) {
  std::set<Edge> seen;
  for (const auto& t : triangles)
    for (int a = 0; a < 3; ++a) {
      const Index i = t[static_cast<size_t>(a)], j = t[static_cast<size_t>((a + 1) % 3)];
      seen.emplace(std::min(i, j), std::max(i, j));
    }
  return std::vector<Edge>(seen.begin(), seen.end());
}

// The views with a non-empty mask, with the nearest mask pixel of every pixel.
std::vector<PreparedView> prepareViews(const std::vector<DepthView>& views) {
  std::vector<PreparedView> prepared;
  for (const DepthView& v : views) {
    PreparedView pv;
    pv.v = &v;
    cv::Mat not_mask = v.mask == 0;  // 255 outside
    cv::distanceTransform(not_mask, pv.dist, pv.labels, cv::DIST_L2, cv::DIST_MASK_PRECISE, cv::DIST_LABEL_PIXEL);
    // Labels number the zero pixels of not_mask (the mask pixels) in scan order, starting at 1.
    pv.label_pixel.emplace_back(-1, -1);
    for (int y = 0; y < v.mask.rows; ++y)
      for (int x = 0; x < v.mask.cols; ++x)
        if (v.mask.at<std::uint8_t>(y, x)) pv.label_pixel.emplace_back(x, y);
    pv.mask_box = cv::boundingRect(v.mask);
    if (pv.label_pixel.size() >= 2) prepared.push_back(std::move(pv));
  }
  return prepared;
}

// Uncovered mask pixels (every uncovered_step_px-th, farther than the slack from the rendered mesh
// `rendered_mask`, a crop at `box`) pull the nearest visible vertex in the image (through a grid of 8-px
// cells of the projections `proj`, searched up to the reach at the shape's mean distance).
void addUncoveredPixelTerms(const PreparedView& pv, const VecX& xc, const std::vector<Vec2>& proj,
                            const std::vector<char>& visible, const cv::Mat& rendered_mask, const cv::Rect& box,
                            Index fixed_vertex, const ShapeFitOptions& o, const IterationLimits& lim, DataTerms& terms) {
  const DepthView& view = *pv.v;
  const auto& k = view.intrinsics;
  const Index n = static_cast<Index>(visible.size());
  const int cell = 8;
  double z_sum = 0;
  int z_n = 0;
  for (Index i = 0; i < n; ++i)
    if (visible[static_cast<size_t>(i)]) {
      z_sum += xc(3 * i + 2);
      ++z_n;
    }
  const double z_mean = z_n > 0 ? z_sum / z_n : 1.0;
  const int max_ring = std::max(4, static_cast<int>(std::ceil(lim.radius * k.fx / std::max(z_mean, 0.1) / cell)));
  const int gw = (k.width + cell - 1) / cell, gh = (k.height + cell - 1) / cell;
  std::vector<std::vector<Index>> grid(static_cast<size_t>(gw * gh));
  for (Index i = 0; i < n; ++i)
    if (visible[static_cast<size_t>(i)]) {
      const Vec2& q = proj[static_cast<size_t>(i)];
      const int gx = std::clamp(static_cast<int>(q.x()) / cell, 0, gw - 1), gy = std::clamp(static_cast<int>(q.y()) / cell, 0, gh - 1);
      grid[static_cast<size_t>(gy * gw + gx)].push_back(i);
    }
  // Only pixels clearly outside the rendered mesh (beyond silhouette_slack_px): the rasterisation of a
  // correct shape differs from the observation by a pixel along the whole outline.
  cv::Mat rendered_far;  // in `box`; every pixel outside it is farther than the slack
  cv::distanceTransform(rendered_mask == 0, rendered_far, cv::DIST_L2, 3);
  const cv::Rect& mb = pv.mask_box;
  for (int y = mb.y - mb.y % o.uncovered_step_px; y < mb.y + mb.height; y += o.uncovered_step_px)
    for (int xpx = mb.x - mb.x % o.uncovered_step_px; xpx < mb.x + mb.width; xpx += o.uncovered_step_px) {
      if (!view.mask.at<std::uint8_t>(y, xpx)) continue;
      if (box.contains(cv::Point(xpx, y)) && rendered_far.at<float>(y - box.y, xpx - box.x) <= o.silhouette_slack_px)
        continue;
      const float zm = view.depth.at<float>(y, xpx);
      if (!validDepth(zm)) continue;
      const int gx = xpx / cell, gy = y / cell;
      Index best = -1;
      double best_d2 = std::numeric_limits<double>::infinity();
      for (int ring = 0; ring <= max_ring && best < 0; ++ring)  // grow the search until a vertex is found
        for (int yy = std::max(0, gy - ring); yy <= std::min(gh - 1, gy + ring); ++yy)
          for (int xx = std::max(0, gx - ring); xx <= std::min(gw - 1, gx + ring); ++xx)
            for (Index i : grid[static_cast<size_t>(yy * gw + xx)]) {
              const double d2 = (proj[static_cast<size_t>(i)] - Vec2(xpx, y)).squaredNorm();
              if (d2 < best_d2) {
                best_d2 = d2;
                best = i;
              }
            }
      if (best < 0 || best == fixed_vertex) continue;
      const Vec3 t = backProject(k, xpx, y, zm);
      if ((t - xc.segment<3>(3 * best)).norm() > lim.silhouette_limit) continue;
      terms.add(view, best, o.silhouette_weight * o.uncovered_step_px * o.uncovered_step_px / 4.0, t);
      ++terms.sil_corr;
    }
}

// The data terms of one view for the shape `x` (common frame): visibility by a z-buffer render, then for each
// visible vertex its measured point (inside the mask) or the nearest mask pixel (outside), then the
// uncovered mask pixels.
void addViewTerms(const PreparedView& pv, const VecX& x, const std::vector<vision::Triangle>& triangles,
                  Index fixed_vertex, const ShapeFitOptions& o, const IterationLimits& lim, DataTerms& terms) {
  const DepthView& view = *pv.v;
  const auto& k = view.intrinsics;
  const Index n = static_cast<Index>(x.size() / 3);
  VecX xc(x.size());
  for (Index i = 0; i < n; ++i) xc.segment<3>(3 * i) = view.rotation * x.segment<3>(3 * i) + view.translation;
  // Rendered only in the box the mesh projects into (plus a margin wider than the silhouette slack, so the
  // distance to the rendered mesh is that of a full render).
  cv::Rect box = vision::projectedBox(xc, k, static_cast<int>(std::ceil(o.silhouette_slack_px)) + 2);
  if (box.empty()) box = cv::Rect(0, 0, 1, 1);  // nothing in view: a one-pixel render, no vertex visible
  const vision::ShadedImage img = vision::renderDepthCrop(xc, triangles, k, box, true);
  std::vector<Vec2> proj(static_cast<size_t>(n), Vec2(-1, -1));
  std::vector<char> visible(static_cast<size_t>(n), 0);
  int view_visible = 0;
  for (Index i = 0; i < n; ++i) {
    const Vec3 p = xc.segment<3>(3 * i);
    if (!(p.z() > 0.01)) continue;
    const double u = k.fx * p.x() / p.z() + k.cx, v = k.fy * p.y() / p.z() + k.cy;
    const int iu = static_cast<int>(std::lround(u)), iv = static_cast<int>(std::lround(v));
    if (iu < 0 || iv < 0 || iu >= k.width || iv >= k.height) continue;
    const float zr = box.contains(cv::Point(iu, iv)) ? img.depth.at<float>(iv - box.y, iu - box.x)
                                                      : std::numeric_limits<float>::quiet_NaN();
    if (validDepth(zr) && p.z() > zr + o.visibility_slack_m) continue;  // hidden behind the mesh
    visible[static_cast<size_t>(i)] = 1;
    proj[static_cast<size_t>(i)] = Vec2(u, v);
    ++view_visible;
    if (i == fixed_vertex) continue;
    if (view.mask.at<std::uint8_t>(iv, iu)) {
      double zm = 0;
      if (!sampleDepth(view.depth, view.mask, u, v, o.depth_discontinuity_m, &zm)) continue;
      const Vec3 t = backProject(k, u, v, zm);
      const double d = (t - p).norm();
      if (d > lim.radius) continue;
      // Cauchy weight: a wrong layer or a stray pixel pulls little.
      terms.add(view, i, 1.0 / (1.0 + (d / lim.robust_scale) * (d / lim.robust_scale)), t);
      terms.residual += d;
      ++terms.depth_corr;
    } else if (o.silhouette_weight > 0 && pv.dist.at<float>(iv, iu) > o.silhouette_slack_px) {
      const int lbl = pv.labels.at<int>(iv, iu);
      if (lbl <= 0 || lbl >= static_cast<int>(pv.label_pixel.size())) continue;
      const cv::Point q = pv.label_pixel[static_cast<size_t>(lbl)];
      const float zm = view.depth.at<float>(q.y, q.x);
      const double z = validDepth(zm) && std::abs(zm - p.z()) <= lim.radius ? zm : p.z();
      const Vec3 t = backProject(k, q.x, q.y, z);
      if ((t - p).norm() > lim.silhouette_limit) continue;
      terms.add(view, i, o.silhouette_weight, t);
      ++terms.sil_corr;
    }
  }
  terms.visible += view_visible;
  if (o.silhouette_weight > 0 && view_visible > 0)
    addUncoveredPixelTerms(pv, xc, proj, visible, img.mask, box, fixed_vertex, o, lim, terms);
}

// The parts of the normal equations that do not change between iterations: lambda L + mu I (+ the held
// vertex's spring) and its right-hand side (with the edge term's only without rotations).
struct FixedSystem {
  Eigen::SparseMatrix<double> a;
  Eigen::MatrixXd rhs;
};

FixedSystem fixedNormalEquations(const VecX& x0, const std::vector<Edge>& edges, Index fixed_vertex, const ShapeFitOptions& o) {
  const Index n = static_cast<Index>(x0.size() / 3);
  const double lambda = o.edge_weight, mu = o.anchor_weight;
  FixedSystem f{Eigen::SparseMatrix<double>(n, n), Eigen::MatrixXd::Zero(n, 3)};
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<size_t>(n + 4 * static_cast<Index>(edges.size()) + 1));
  for (Index i = 0; i < n; ++i) {
    trip.emplace_back(i, i, mu);
    f.rhs.row(i) = mu * x0.segment<3>(3 * i).transpose();
  }
  for (const auto& [i, j] : edges) {
    trip.emplace_back(i, i, lambda);
    trip.emplace_back(j, j, lambda);
    trip.emplace_back(i, j, -lambda);
    trip.emplace_back(j, i, -lambda);
    if (o.rotations) continue;  // the edge term's right-hand side then turns with the vertices
    const Vec3 e0 = x0.segment<3>(3 * i) - x0.segment<3>(3 * j);
    f.rhs.row(i) += lambda * e0.transpose();
    f.rhs.row(j) -= lambda * e0.transpose();
  }
  if (fixed_vertex >= 0) {  // a stiff spring to its matched position
    trip.emplace_back(fixed_vertex, fixed_vertex, 1e8);
    f.rhs.row(fixed_vertex) += 1e8 * x0.segment<3>(3 * fixed_vertex).transpose();
  }
  f.a.setFromTriplets(trip.begin(), trip.end());
  return f;
}

// As-rigid-as-possible edge term. Local step: each vertex's rotation best maps its rest edges onto its
// current ones, R_i = argmax tr(R^T sum_j (x_i - x_j)(x0_i - x0_j)^T) (warm-started in `rot`); global step:
// the edge targets (R_i + R_j)/2 e0_ij added to `rhs` with weight `lambda`.
void addRotatedEdgeTargets(const VecX& x, const VecX& x0, const std::vector<Edge>& edges, double lambda,
                           std::vector<Eigen::Quaterniond>& rot, Eigen::MatrixXd& rhs) {
  const size_t n = rot.size();
  std::vector<Mat3> cov(n, Mat3::Zero());
  for (const auto& [i, j] : edges) {
    const Mat3 c = (x.segment<3>(3 * i) - x.segment<3>(3 * j)) * (x0.segment<3>(3 * i) - x0.segment<3>(3 * j)).transpose();
    cov[static_cast<size_t>(i)] += c;
    cov[static_cast<size_t>(j)] += c;
  }
  std::vector<Mat3> r(n);
  for (size_t i = 0; i < n; ++i) {
    extractRotation(cov[i], rot[i]);
    r[i] = rot[i].toRotationMatrix();
  }
  for (const auto& [i, j] : edges) {
    const Vec3 e = 0.5 * (r[static_cast<size_t>(i)] + r[static_cast<size_t>(j)]) * (x0.segment<3>(3 * i) - x0.segment<3>(3 * j));
    rhs.row(i) += lambda * e.transpose();
    rhs.row(j) -= lambda * e.transpose();
  }
}

}  // namespace

VecX fitShapeToDepthViews(const VecX& x0, const std::vector<vision::Triangle>& triangles, Index fixed_vertex,
                          const std::vector<DepthView>& views, const ShapeFitOptions& o, ShapeFitReport* report) {
  validateFitInput(x0, triangles, fixed_vertex, views, o);
  ShapeFitReport rep;
  const Index n = static_cast<Index>(x0.size() / 3);
  const std::vector<Edge> edges = uniqueEdges(triangles);
  const std::vector<PreparedView> prepared = prepareViews(views);
  if (prepared.empty()) {
    rep.note = "empty mask";
    if (report) *report = rep;
    return x0;
  }
  const FixedSystem fixed = fixedNormalEquations(x0, edges, fixed_vertex, o);
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  ldlt.analyzePattern(fixed.a);  // only the diagonal weights change between iterations
  std::vector<Eigen::Quaterniond> rot(o.rotations ? static_cast<size_t>(n) : 0, Eigen::Quaterniond::Identity());
  VecX x = x0;
  for (int it = 0; it < o.iterations; ++it) {
    const IterationLimits lim = iterationLimits(o, it);
    DataTerms terms(n);
    for (const PreparedView& pv : prepared) addViewTerms(pv, x, triangles, fixed_vertex, o, lim, terms);
    if (it == 0) {
      rep.mean_depth_residual_before_m = terms.depth_corr > 0 ? terms.residual / terms.depth_corr : -1;
      if (terms.depth_corr < std::max<Index>(10, n / 10)) {
        rep.note = "too few depth correspondences (" + std::to_string(terms.depth_corr) + ")";
        if (report) *report = rep;
        return x0;
      }
    }
    rep.visible_vertices = terms.visible;
    rep.depth_correspondences = terms.depth_corr;
    rep.silhouette_correspondences = terms.sil_corr;
    rep.mean_depth_residual_after_m = terms.depth_corr > 0 ? terms.residual / terms.depth_corr : -1;

    // Solve (W + lambda L + mu I) X = W t + lambda L X0 + mu X0 (edge targets rotated with `rotations`).
    Eigen::SparseMatrix<double> a = fixed.a;
    Eigen::MatrixXd rhs = fixed.rhs;
    if (o.rotations) addRotatedEdgeTargets(x, x0, edges, o.edge_weight, rot, rhs);
    for (Index i = 0; i < n; ++i) {
      a.coeffRef(i, i) += terms.w[static_cast<size_t>(i)];
      rhs.row(i) += terms.target_sum[static_cast<size_t>(i)].transpose();
    }
    ldlt.factorize(a);
    if (ldlt.info() != Eigen::Success) {
      rep.note = "factorisation failed";
      break;
    }
    const Eigen::MatrixXd sol = ldlt.solve(rhs);
    if (!sol.allFinite()) {
      rep.note = "non-finite solution";
      break;
    }
    for (Index i = 0; i < n; ++i) x.segment<3>(3 * i) = sol.row(i).transpose();
    rep.iterations = it + 1;
    rep.applied = true;
  }
  if (!rep.applied) {
    if (report) *report = rep;
    return x0;
  }
  for (Index i = 0; i < n; ++i)
    rep.max_displacement_m = std::max(rep.max_displacement_m, (x.segment<3>(3 * i) - x0.segment<3>(3 * i)).norm());
  if (report) *report = rep;
  return x;
}

}  // namespace recognition
}  // namespace textile_handling
