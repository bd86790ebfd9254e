#include "textile_handling/sim/rest_shape_picture.h"

#include "png_output.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <utility>
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

// The cells around each node (a node is a corner of up to four), -1 for none.
std::vector<std::array<int, 4>> cellsAroundNodes(Index nodes, const std::vector<Cell>& cells) {
  std::vector<std::array<int, 4>> around(static_cast<size_t>(nodes), {-1, -1, -1, -1});
  for (size_t k = 0; k < cells.size(); ++k) {
    for (Index i : cells[k].corner) {
      auto& slots = around[static_cast<size_t>(i)];
      const auto free = std::find(slots.begin(), slots.end(), -1);
      if (free != slots.end()) *free = static_cast<int>(k);
    }
  }
  return around;
}

// One segment of a drawn yarn, between two consecutive nodes.
struct YarnSegment {
  Index a = 0, b = 0;
  bool warp = true;
};

// The segments of the yarns to draw: of a direction with more than `max_lines` lines, every k-th line.
std::vector<YarnSegment> yarnSegments(const std::vector<DrawnYarn>& yarns, int max_lines) {
  std::array<std::size_t, 2> lines{0, 0};  // per direction (weft, warp): highest line + 1
  for (const DrawnYarn& y : yarns) lines[y.warp] = std::max(lines[y.warp], y.line + 1);
  std::array<std::size_t, 2> stride{};
  const auto max = static_cast<std::size_t>(max_lines);
  for (int dir = 0; dir < 2; ++dir) stride[dir] = std::max<std::size_t>(1, (lines[dir] + max - 1) / max);
  std::vector<YarnSegment> segments;
  for (const DrawnYarn& y : yarns) {
    if (y.line % stride[y.warp] != 0) continue;
    for (size_t k = 0; k + 1 < y.nodes.size(); ++k) segments.push_back({y.nodes[k], y.nodes[k + 1], y.warp});
  }
  return segments;
}

cv::Scalar bgr(const std::array<unsigned char, 3>& rgb) { return cv::Scalar(rgb[2], rgb[1], rgb[0]); }

// What both views draw: the shape's cells, the cells around each node and the yarn segments.
struct PictureShape {
  const ParticleTopology& topology;
  const VecX& x;
  std::vector<Cell> cells;
  std::vector<std::array<int, 4>> around;
  std::vector<YarnSegment> segments;
};

// A view's projection: `axis_u`, `axis_v` span the image plane (v up), `depth` points away from the
// viewer; the shape is centred horizontally.
struct ViewProjection {
  Vec3 axis_u, axis_v, depth, lo;
  Real scale = 1, u_shift = 0;
  int height = 0;
  cv::Point operator()(const VecX& x, Index i) const {
    const Vec3 p = node3(x, i) - lo;
    return cv::Point(static_cast<int>(std::lround(u_shift + p.dot(axis_u) * scale)),
                     static_cast<int>(std::lround(height - 10 - p.dot(axis_v) * scale)));
  }
};

// Paints the cells far to near (painter's algorithm), shaded by their normal, and records in `rank` (per
// pixel, -1 where no cell) the place in that order of the cell seen there. Returns each cell's place.
std::vector<int> paintCells(cv::Mat& view, cv::Mat& rank, const PictureShape& s, const ViewProjection& proj) {
  std::vector<std::pair<Real, size_t>> order;
  order.reserve(s.cells.size());
  for (size_t k = 0; k < s.cells.size(); ++k) {
    Vec3 c = Vec3::Zero();
    for (Index i : s.cells[k].corner) c += node3(s.x, i);
    order.emplace_back(-c.dot(proj.depth), k);
  }
  std::sort(order.begin(), order.end());
  const Vec3 light = (-proj.depth + 0.5 * proj.axis_v).normalized();
  std::vector<int> place(s.cells.size());
  for (size_t p = 0; p < order.size(); ++p) {
    const auto& c = s.cells[order[p].second].corner;
    place[order[p].second] = static_cast<int>(p);
    const Vec3 n = (node3(s.x, c[2]) - node3(s.x, c[0])).cross(node3(s.x, c[3]) - node3(s.x, c[1]));
    const Real shade = n.norm() > 0 ? std::abs(n.normalized().dot(light)) : 0.5;
    const int g = static_cast<int>(60 + 170 * shade);
    std::vector<cv::Point> poly{proj(s.x, c[0]), proj(s.x, c[1]), proj(s.x, c[2]), proj(s.x, c[3])};
    cv::fillConvexPoly(view, poly, cv::Scalar(g * 0.55, g * 0.75, g), cv::LINE_AA);
    cv::fillConvexPoly(rank, poly, cv::Scalar(static_cast<double>(p)));
  }
  return place;
}

// Draws the yarn segments over the painted cells, 1 px antialiased. A segment shows where the cell seen
// is painted no later than the last cell around its nodes (so a cell nearer than its surroundings hides
// it, the cells beside it do not); a segment with no cell around its nodes shows everywhere.
void paintYarns(cv::Mat& view, const cv::Mat& rank, const PictureShape& s, const ViewProjection& proj,
                const std::vector<int>& place) {
  std::vector<std::pair<int, size_t>> order;  // (last place around the segment, segment): near last
  order.reserve(s.segments.size());
  for (size_t k = 0; k < s.segments.size(); ++k) {
    int last = -1;
    bool has_cells = false;
    for (Index i : {s.segments[k].a, s.segments[k].b})
      for (int c : s.around[static_cast<size_t>(i)])
        if (c >= 0) last = std::max(last, place[static_cast<size_t>(c)]), has_cells = true;
    order.emplace_back(has_cells ? last : std::numeric_limits<int>::max(), k);
  }
  std::sort(order.begin(), order.end());
  const cv::Rect bounds(0, 0, view.cols, view.rows);
  cv::Mat coverage;
  for (const auto& [last, k] : order) {
    const YarnSegment& seg = s.segments[k];
    const cv::Point a = proj(s.x, seg.a), b = proj(s.x, seg.b);
    const cv::Rect box = cv::Rect(cv::Point(std::min(a.x, b.x) - 2, std::min(a.y, b.y) - 2),
                                  cv::Point(std::max(a.x, b.x) + 3, std::max(a.y, b.y) + 3)) & bounds;
    if (box.empty()) continue;
    coverage.create(box.size(), CV_8UC1);
    coverage.setTo(0);
    cv::line(coverage, a - box.tl(), b - box.tl(), cv::Scalar(255), 1, cv::LINE_AA);
    const cv::Scalar colour = bgr(seg.warp ? kPictureWarpRgb : kPictureWeftRgb);
    for (int r = 0; r < box.height; ++r) {
      for (int c = 0; c < box.width; ++c) {
        const int cover = coverage.at<unsigned char>(r, c);
        if (cover == 0 || rank.at<int>(box.y + r, box.x + c) > last) continue;
        cv::Vec3b& px = view.at<cv::Vec3b>(box.y + r, box.x + c);
        for (int ch = 0; ch < 3; ++ch)
          px[ch] = cv::saturate_cast<unsigned char>(px[ch] + (colour[ch] - px[ch]) * cover / 255.0);
      }
    }
  }
}

// Draws one view into `roi` of the canvas.
void drawView(cv::Mat& canvas, const cv::Rect& roi, const PictureShape& s, const Vec3& axis_u, const Vec3& axis_v,
              const Vec3& depth, const Vec3& lo, Real scale, const std::vector<Index>& highlight) {
  cv::Mat view = canvas(roi);
  ViewProjection proj{axis_u, axis_v, depth, lo, scale, 0, roi.height};
  Real umin = 1e300, umax = -1e300;
  for (Index i = 0; i < s.topology.size(); ++i) {
    const Real u = (node3(s.x, i) - lo).dot(axis_u);
    umin = std::min(umin, u);
    umax = std::max(umax, u);
  }
  proj.u_shift = 0.5 * roi.width - 0.5 * (umin + umax) * scale;
  cv::Mat rank(roi.size(), CV_32SC1, cv::Scalar(-1));
  const std::vector<int> place = paintCells(view, rank, s, proj);
  paintYarns(view, rank, s, proj, place);
  if (s.cells.empty()) {
    for (Index i = 0; i < s.topology.size(); ++i) cv::circle(view, proj(s.x, i), 1, cv::Scalar(60, 90, 200), -1);
  }
  for (Index h : highlight) cv::circle(view, proj(s.x, h), 4, cv::Scalar(0, 0, 255), -1, cv::LINE_AA);
}

}  // namespace

bool writeRestShapePicture(const std::string& path, const ParticleTopology& t, const VecX& x,
                           const std::vector<Index>& highlight, const std::vector<DrawnYarn>& yarns, int view_px,
                           std::string* error) {
  if (t.size() == 0 || x.size() != 3 * t.size() || !x.allFinite()) {
    if (error) *error = "picture: empty or non-finite shape";
    return false;
  }
  for (const DrawnYarn& y : yarns) {
    for (Index i : y.nodes) {
      if (i < 0 || i >= t.size()) {
        if (error)
          *error = "picture: yarn node " + std::to_string(i) + " outside the shape's " + std::to_string(t.size()) + " nodes";
        return false;
      }
    }
  }
  Vec3 lo = Vec3::Constant(1e300), hi = Vec3::Constant(-1e300);
  for (Index i = 0; i < t.size(); ++i) {
    lo = lo.cwiseMin(Vec3(node3(x, i)));
    hi = hi.cwiseMax(Vec3(node3(x, i)));
  }
  const Real extent = std::max((hi - lo).maxCoeff(), 1e-6);
  const Real scale = (view_px - 20) / extent;
  cv::Mat canvas(view_px, 2 * view_px, CV_8UC3, cv::Scalar(255, 255, 255));
  PictureShape shape{t, x, cellsOf(t), {}, yarnSegments(yarns, maxPictureYarnLines(view_px))};
  shape.around = cellsAroundNodes(t.size(), shape.cells);
  drawView(canvas, cv::Rect(0, 0, view_px, view_px), shape, Vec3::UnitX(), Vec3::UnitZ(), Vec3::UnitY(), lo, scale,
           highlight);
  drawView(canvas, cv::Rect(view_px, 0, view_px, view_px), shape, Vec3::UnitY(), Vec3::UnitZ(), -Vec3::UnitX(), lo,
           scale, highlight);
  cv::line(canvas, cv::Point(view_px, 0), cv::Point(view_px, view_px), cv::Scalar(180, 180, 180));
  return writePngFile(path, canvas, "picture", error);
}

}  // namespace textile_handling
