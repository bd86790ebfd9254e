#include "textile_handling/sim/rest_shape_picture.h"

#include "png_output.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace textile_handling {

namespace {

struct Cell {
  std::array<Index, 4> corner;
};

// Cells = quads (r, right, right-up, up) whose four corners are active.
std::vector<Cell> cellsOf(const ParticleTopology& t) {
  std::vector<Cell> cells;
  for (Index r = 0; r < t.size(); ++r) {
    const Index right = t.neighbour[r][0], up = t.neighbour[r][1];
    if (right < 0 || up < 0) continue;
    const Index diag = t.neighbour[right][1];
    if (diag < 0) continue;
    cells.push_back({{r, right, diag, up}});
  }
  return cells;
}

// Draws one view. `axis_u`, `axis_v` span the image plane (v up), `depth` points away from the viewer.
void drawView(cv::Mat& canvas, const cv::Rect& roi, const ParticleTopology& t, const VecX& x,
              const std::vector<Cell>& cells, const Vec3& axis_u, const Vec3& axis_v, const Vec3& depth,
              const Vec3& lo, Real scale, const std::vector<Index>& highlight) {
  cv::Mat view = canvas(roi);
  // Centre the shape horizontally in its view.
  Real umin = 1e300, umax = -1e300;
  for (Index i = 0; i < t.size(); ++i) {
    const Real u = (node3(x, i) - lo).dot(axis_u);
    umin = std::min(umin, u);
    umax = std::max(umax, u);
  }
  const Real u_shift = 0.5 * roi.width - 0.5 * (umin + umax) * scale;
  auto project = [&](Index i) {
    const Vec3 p = node3(x, i) - lo;
    return cv::Point(static_cast<int>(std::lround(u_shift + p.dot(axis_u) * scale)),
                     static_cast<int>(std::lround(roi.height - 10 - p.dot(axis_v) * scale)));
  };
  std::vector<std::pair<Real, size_t>> order;
  order.reserve(cells.size());
  for (size_t k = 0; k < cells.size(); ++k) {
    Vec3 c = Vec3::Zero();
    for (Index i : cells[k].corner) c += node3(x, i);
    order.emplace_back(-c.dot(depth), k);  // painter's algorithm: far cells first
  }
  std::sort(order.begin(), order.end());
  const Vec3 light = (-depth + 0.5 * axis_v).normalized();
  for (const auto& [unused, k] : order) {
    const auto& c = cells[k].corner;
    const Vec3 n = (node3(x, c[2]) - node3(x, c[0])).cross(node3(x, c[3]) - node3(x, c[1]));
    const Real shade = n.norm() > 0 ? std::abs(n.normalized().dot(light)) : 0.5;
    const int g = static_cast<int>(60 + 170 * shade);
    std::vector<cv::Point> poly{project(c[0]), project(c[1]), project(c[2]), project(c[3])};
    cv::fillConvexPoly(view, poly, cv::Scalar(g * 0.55, g * 0.75, g), cv::LINE_AA);
  }
  if (cells.empty()) {
    for (Index i = 0; i < t.size(); ++i) cv::circle(view, project(i), 1, cv::Scalar(60, 90, 200), -1);
  }
  for (Index h : highlight) cv::circle(view, project(h), 4, cv::Scalar(0, 0, 255), -1, cv::LINE_AA);
}

}  // namespace

bool writeRestShapePicture(const std::string& path, const ParticleTopology& t, const VecX& x,
                           const std::vector<Index>& highlight, int view_px, std::string* error) {
  if (t.size() == 0 || x.size() != 3 * t.size() || !x.allFinite()) {
    if (error) *error = "picture: empty or non-finite shape";
    return false;
  }
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (Index i = 0; i < t.size(); ++i) {
    lo = lo.cwiseMin(Vec3(node3(x, i)));
    hi = hi.cwiseMax(Vec3(node3(x, i)));
  }
  const Real extent = std::max((hi - lo).maxCoeff(), 1e-6);
  const Real scale = (view_px - 20) / extent;
  cv::Mat canvas(view_px, 2 * view_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const auto cells = cellsOf(t);
  drawView(canvas, cv::Rect(0, 0, view_px, view_px), t, x, cells, Vec3::UnitX(), Vec3::UnitZ(), Vec3::UnitY(), lo,
           scale, highlight);
  drawView(canvas, cv::Rect(view_px, 0, view_px, view_px), t, x, cells, Vec3::UnitY(), Vec3::UnitZ(),
           -Vec3::UnitX(), lo, scale, highlight);
  cv::line(canvas, cv::Point(view_px, 0), cv::Point(view_px, view_px), cv::Scalar(180, 180, 180));
  return writePngFile(path, canvas, "picture", error);
}

}  // namespace textile_handling
