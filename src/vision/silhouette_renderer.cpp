#include "textile_handling/vision/silhouette_renderer.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <stdexcept>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace vision {

namespace {

constexpr double kDegToRad = kPi / 180.0;

void validateMesh(const VecX& positions, const std::vector<Triangle>& triangles) {
  if (positions.size() == 0 || positions.size() % 3 != 0) {
    std::ostringstream os;
    os << "positions must hold 3 values per vertex (got " << positions.size() << ")";
    throw InvalidArgumentError("silhouette renderer", "positions", os.str());
  }
  const Index n = static_cast<Index>(positions.size() / 3);
  for (Index i = 0; i < positions.size(); ++i) {
    if (!std::isfinite(positions[i])) {
      std::ostringstream os;
      os << "position of vertex " << i / 3 << " is not finite";
      throw InvalidArgumentError("silhouette renderer", "positions", os.str());
    }
  }
  if (triangles.empty()) throw InvalidArgumentError("silhouette renderer", "triangles", "mesh has no triangles");
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (Index v : triangles[t])
      if (v < 0 || v >= n) {
        std::ostringstream os;
        os << "triangle " << t << " has vertex index " << v << " outside [0, " << n << ")";
        throw InvalidArgumentError("silhouette renderer", "triangles", os.str());
      }
}

void validateProjection(const SilhouetteProjection& p) {
  if (p.type != ProjectionType::kPinhole) return;
  if (!(p.camera_distance > 0) || !std::isfinite(p.camera_distance))
    throw InvalidArgumentError("silhouette renderer", "projection.camera_distance", "pinhole camera_distance must be finite and > 0");
  if (!std::isfinite(p.camera_height))
    throw InvalidArgumentError("silhouette renderer", "projection.camera_height", "pinhole camera_height must be finite");
  const auto& k = p.intrinsics;
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) ||
      !std::isfinite(k.cy))
    throw InvalidArgumentError("silhouette renderer", "projection.intrinsics",
                               "pinhole intrinsics need finite fx, fy > 0 and finite cx, cy");
}

// Maps world points of one view to canonical continuous pixel coordinates.
struct ViewMapper {
  Vec3 hold, dir, right;
  bool pinhole = false;
  double distance = 0, height = 0;
  double inv_mpp = 0, cx = 0, top = 0;
  double hold_xz = 0, hold_yz = 0;  // hold point's normalised image coordinates (pinhole)

  ViewMapper(const Vec3& h, double azimuth_deg, const SilhouetteProjection& p, const CanonicalFrame& f)
      : hold(h), dir(viewDirection(azimuth_deg)), right(viewRight(azimuth_deg)) {
    pinhole = p.type == ProjectionType::kPinhole;
    distance = p.camera_distance;
    height = p.camera_height;
    inv_mpp = 1.0 / f.metres_per_pixel;
    cx = 0.5 * f.width_px;
    top = f.top_margin_px;
    if (pinhole) {
      // Camera centre c = h - D d + height z; hold point at depth D, camera y axis = -z.
      hold_xz = 0.0;
      hold_yz = height / distance;  // Yc = -(h - c).z = height
    }
  }

  // Returns false if the point is not in front of the camera (pinhole).
  bool map(const Vec3& p, Vec2* out) const {
    const Vec3 q = p - hold;  // relative to the hold point
    if (!pinhole) {
      *out = Vec2(cx + q.dot(right) * inv_mpp, top - q.z() * inv_mpp);
      return true;
    }
    const double zc = q.dot(dir) + distance;
    if (!(zc > 1e-2 * distance)) return false;
    const double xc = q.dot(right);
    const double yc = -q.z() + height;
    const double s = distance * inv_mpp;
    *out = Vec2(cx + s * (xc / zc - hold_xz), top + s * (yc / zc - hold_yz));
    return true;
  }
};

}  // namespace

std::vector<Triangle> trianglesFromTopology(const ParticleTopology& topo) {
  std::vector<Triangle> tris;
  const Index n = topo.size();
  tris.reserve(static_cast<std::size_t>(2 * n));
  auto valid = [n](Index i) { return i >= 0 && i < n; };
  for (Index p = 0; p < n; ++p) {
    const Index right = topo.neighbour[p][0];
    const Index up = topo.neighbour[p][1];
    if (!valid(right) || !valid(up)) continue;
    const Index right_up = topo.neighbour[right][1];
    if (!valid(right_up) || topo.neighbour[up][0] != right_up) continue;
    tris.push_back({p, right, right_up});
    tris.push_back({p, right_up, up});
  }
  return tris;
}

std::vector<Triangle> coarseGridTriangles(const ParticleGrid& grid, int stride) {
  if (stride < 1) throw InvalidArgumentError("coarseGridTriangles", "stride", "stride must be >= 1");
  std::vector<Triangle> tris;
  const Index rows = grid.rows(), cols = grid.cols();
  if (rows < 2 || cols < 2) return tris;
  // covered[i * (cols - 1) + j]: grid cell (i, j) (nodes i..i+1, j..j+1) lies in a coarse block.
  std::vector<char> covered(static_cast<std::size_t>((rows - 1) * (cols - 1)), 0);
  const auto cell = [&](Index a, Index b, Index c, Index d) {  // p, right, right-up, up
    tris.push_back({a, b, c});
    tris.push_back({a, c, d});
  };
  if (stride > 1) {
    for (Index i = 0; i + stride < rows; i += stride)
      for (Index j = 0; j + stride < cols; j += stride) {
        bool full = true;
        for (Index a = 0; a <= stride && full; ++a)
          for (Index b = 0; b <= stride && full; ++b) full = grid.active(i + a, j + b);
        if (!full) continue;
        cell(grid.activeIndex(i, j), grid.activeIndex(i, j + stride), grid.activeIndex(i + stride, j + stride),
             grid.activeIndex(i + stride, j));
        for (Index a = 0; a < stride; ++a)
          for (Index b = 0; b < stride; ++b) covered[static_cast<std::size_t>((i + a) * (cols - 1) + j + b)] = 1;
      }
  }
  for (Index i = 0; i + 1 < rows; ++i)
    for (Index j = 0; j + 1 < cols; ++j) {
      if (covered[static_cast<std::size_t>(i * (cols - 1) + j)]) continue;
      const Index p = grid.activeIndex(i, j), r = grid.activeIndex(i, j + 1), ru = grid.activeIndex(i + 1, j + 1),
                  u = grid.activeIndex(i + 1, j);
      if (p >= 0 && r >= 0 && ru >= 0 && u >= 0) cell(p, r, ru, u);
    }
  return tris;
}

CanonicalFrame CanonicalFrame::fromMetric(double width_m, double height_m, int width_px) {
  if (!(width_m > 0) || !(height_m > 0) || !std::isfinite(width_m) || !std::isfinite(height_m) || width_px < 1)
    throw InvalidArgumentError("CanonicalFrame::fromMetric", "width_m/height_m/width_px",
                               "sizes width_m, height_m and width_px must be finite and > 0");
  CanonicalFrame f;
  f.width_px = width_px;
  f.metres_per_pixel = width_m / width_px;
  f.height_px = std::max(1, static_cast<int>(std::lround(height_m / f.metres_per_pixel)));
  return f;
}

void CanonicalFrame::validate() const {
  if (width_px < 1 || height_px < 1 || width_px > 8192 || height_px > 8192)
    throw InvalidArgumentError("CanonicalFrame", "width_px/height_px", "size (width_px, height_px) must be 1..8192 px per side");
  if (!(metres_per_pixel > 0) || !std::isfinite(metres_per_pixel))
    throw InvalidArgumentError("CanonicalFrame", "metres_per_pixel", "metres_per_pixel must be finite and > 0");
  if (!std::isfinite(top_margin_px) || top_margin_px < 0 || top_margin_px >= height_px)
    throw InvalidArgumentError("CanonicalFrame", "top_margin_px", "top_margin_px must be in [0, height_px)");
  if (supersample < 1 || supersample > 16) throw InvalidArgumentError("CanonicalFrame", "supersample", "supersample must be 1..16");
  if (!(coverage_threshold > 0) || coverage_threshold > 1)
    throw InvalidArgumentError("CanonicalFrame", "coverage_threshold", "coverage_threshold must be in (0, 1]");
}

std::vector<double> ViewSet::angles() const {
  if (count < 1) throw InvalidArgumentError("ViewSet", "count", "count must be >= 1 (got " + std::to_string(count) + ")");
  if (!std::isfinite(start_deg) || !std::isfinite(step_deg))
    throw InvalidArgumentError("ViewSet", "start_deg/step_deg", "start_deg and step_deg must be finite");
  std::vector<double> a(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) a[static_cast<std::size_t>(i)] = start_deg + i * step_deg;
  return a;
}

Vec3 viewDirection(double azimuth_deg) {
  const double t = azimuth_deg * kDegToRad;
  return Vec3(-std::sin(t), std::cos(t), 0.0);
}

Vec3 viewRight(double azimuth_deg) {
  const double t = azimuth_deg * kDegToRad;
  return Vec3(std::cos(t), std::sin(t), 0.0);
}

namespace detail {

namespace {

// floor / ceil of a value already clamped to a few canvas sizes (no std::floor call, no overflow).
inline int floorInt(double v) {
  const int i = static_cast<int>(v);
  return i - (v < i);
}
inline int ceilInt(double v) {
  const int i = static_cast<int>(v);
  return i + (v > i);
}

// x where the segment p-q crosses the line y = yc (p.y != q.y).
inline double crossingX(const Vec2& p, const Vec2& q, double yc) {
  return p.x() + (q.x() - p.x()) * (yc - p.y()) / (q.y() - p.y());
}

}  // namespace

void rasterTriangleRows(const std::vector<Vec2>& pts, const std::vector<Triangle>& tris, int w, int h, int row0,
                        int row1, std::uint8_t* canvas) {
  const double lo_clamp = -2.0, hi_x = w + 2.0, hi_y = h + 2.0;
  for (const Triangle& t : tris) {
    // Vertices sorted by y: the long edge v0-v2 bounds one side of every row, v0-v1 or v1-v2 the other.
    const Vec2* v0 = &pts[static_cast<std::size_t>(t[0])];
    const Vec2* v1 = &pts[static_cast<std::size_t>(t[1])];
    const Vec2* v2 = &pts[static_cast<std::size_t>(t[2])];
    if (v1->y() < v0->y()) std::swap(v0, v1);
    if (v2->y() < v1->y()) std::swap(v1, v2);
    if (v1->y() < v0->y()) std::swap(v0, v1);
    const double ymin = v0->y(), ymax = v2->y();
    if (ymax < row0 || ymin > row1) continue;
    const double xmin = std::min({v0->x(), v1->x(), v2->x()}), xmax = std::max({v0->x(), v1->x(), v2->x()});
    if (xmax < 0 || xmin > w) continue;
    // Rows whose centre line y = r + 0.5 lies in [ymin, ymax].
    const int r0 = std::max(row0, ceilInt(std::max(ymin - 0.5, lo_clamp)));
    const int r1 = std::min(row1 - 1, floorInt(std::min(ymax - 0.5, hi_y)));
    const bool flat = ymax - ymin < 1e-12;
    for (int r = r0; r <= r1; ++r) {
      const double yc = r + 0.5;
      double xl, xr;
      if (flat) {  // the whole triangle on the centre line
        xl = xmin;
        xr = xmax;
      } else {
        const double xa = crossingX(*v0, *v2, yc);
        double xb;
        if (yc <= v1->y())
          xb = v1->y() - v0->y() < 1e-12 ? (std::abs(v0->x() - xa) > std::abs(v1->x() - xa) ? v0->x() : v1->x())
                                         : crossingX(*v0, *v1, yc);
        else
          xb = v2->y() - v1->y() < 1e-12 ? (std::abs(v1->x() - xa) > std::abs(v2->x() - xa) ? v1->x() : v2->x())
                                         : crossingX(*v1, *v2, yc);
        xl = std::min(xa, xb);
        xr = std::max(xa, xb);
      }
      int c0 = ceilInt(std::clamp(xl - 0.5, lo_clamp, hi_x));
      int c1 = floorInt(std::clamp(xr - 0.5, lo_clamp, hi_x));
      if (c0 > c1) c0 = c1 = floorInt(std::clamp(0.5 * (xl + xr), lo_clamp, hi_x));
      c0 = std::max(c0, 0);
      c1 = std::min(c1, w - 1);
      if (c0 > c1) continue;
      std::uint8_t* rowp = canvas + static_cast<std::size_t>(r - row0) * static_cast<std::size_t>(w);
      std::fill(rowp + c0, rowp + c1 + 1, std::uint8_t{1});
    }
  }
}

void rasterTriangles(const std::vector<Vec2>& pts, const std::vector<Triangle>& tris, int w, int h,
                     std::vector<std::uint8_t>& canvas) {
  canvas.assign(static_cast<std::size_t>(w) * static_cast<std::size_t>(h), 0);
  rasterTriangleRows(pts, tris, w, h, 0, h, canvas.data());
}

void downsampleCoverageRows(const std::uint8_t* canvas, int width, int y0, int y1, int x0, int x1, int s,
                            double threshold, BitMask& m) {
  const int cw = width * s;
  const int need = std::max(1, static_cast<int>(std::ceil(threshold * s * s - 1e-9)));
  for (int y = y0; y < y1; ++y) {
    const std::uint8_t* band = canvas + static_cast<std::size_t>(y - y0) * static_cast<std::size_t>(s) * static_cast<std::size_t>(cw);
    for (int x = x0; x < x1; ++x) {
      int n = 0;
      if (s == 4) {  // four 0/1 bytes per row: add the rows as words, then the bytes by a multiply
        std::uint32_t sum = 0;
        for (int sy = 0; sy < 4; ++sy) {
          std::uint32_t word;
          std::memcpy(&word, band + static_cast<std::size_t>(sy) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(x) * 4, 4);
          sum += word;
        }
        n = static_cast<int>((sum * 0x01010101u) >> 24);
      } else {
        for (int sy = 0; sy < s; ++sy) {
          const std::uint8_t* rowp = band + static_cast<std::size_t>(sy) * static_cast<std::size_t>(cw);
          for (int sx = 0; sx < s; ++sx) n += rowp[x * s + sx];
        }
      }
      if (n >= need) m.set(x, y);
    }
  }
}

BitMask downsampleCoverage(const std::vector<std::uint8_t>& canvas, int width, int height, int s, double threshold) {
  BitMask m(width, height);
  downsampleCoverageRows(canvas.data(), width, 0, height, 0, width, s, threshold, m);
  return m;
}

}  // namespace detail

Vec2 canonicalPixel(const Vec3& point, const Vec3& hold, double azimuth_deg, const SilhouetteProjection& projection,
                    const CanonicalFrame& frame) {
  frame.validate();
  validateProjection(projection);
  const ViewMapper vm(hold, azimuth_deg, projection, frame);
  Vec2 out;
  if (!vm.map(point, &out)) throw InvalidArgumentError("canonicalPixel", "point", "point is not in front of the camera");
  return out;
}

BitMask renderSilhouette(const VecX& positions, const std::vector<Triangle>& triangles, const Vec3& hold,
                         double azimuth_deg, const SilhouetteProjection& projection, const CanonicalFrame& frame) {
  frame.validate();
  validateProjection(projection);
  validateMesh(positions, triangles);
  if (!hold.allFinite()) throw InvalidArgumentError("silhouette renderer", "hold", "hold point is not finite");
  if (!std::isfinite(azimuth_deg)) throw InvalidArgumentError("silhouette renderer", "azimuth_deg", "view angle (azimuth_deg) is not finite");

  const ViewMapper vm(hold, azimuth_deg, projection, frame);
  const Index n = static_cast<Index>(positions.size() / 3);
  const int s = frame.supersample;
  std::vector<Vec2> pts(static_cast<std::size_t>(n));
  for (Index i = 0; i < n; ++i) {
    Vec2 p;
    if (!vm.map(node3(positions, i), &p)) {
      std::ostringstream os;
      os << "vertex " << i << " of positions is behind or too close to the pinhole camera (camera distance "
         << projection.camera_distance << " m)";
      throw InvalidArgumentError("silhouette renderer", "positions", os.str());
    }
    pts[static_cast<std::size_t>(i)] = p * static_cast<double>(s);
  }
  // Only the band of canonical rows and columns the mesh can cover is cleared, rasterised and filtered.
  double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300;
  for (const Vec2& p : pts) {
    x_lo = std::min(x_lo, p.x());
    x_hi = std::max(x_hi, p.x());
    y_lo = std::min(y_lo, p.y());
    y_hi = std::max(y_hi, p.y());
  }
  BitMask out(frame.width_px, frame.height_px);
  const auto clampPx = [](double v, int hi) { return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi))); };
  const int py0 = clampPx(std::floor(y_lo / s) - 1, frame.height_px), py1 = clampPx(std::ceil(y_hi / s) + 1, frame.height_px);
  const int px0 = clampPx(std::floor(x_lo / s) - 1, frame.width_px), px1 = clampPx(std::ceil(x_hi / s) + 1, frame.width_px);
  if (py0 >= py1 || px0 >= px1) return out;
  const int cw = frame.width_px * s;
  std::vector<std::uint8_t> canvas(static_cast<std::size_t>(py1 - py0) * static_cast<std::size_t>(s) * static_cast<std::size_t>(cw), 0);
  detail::rasterTriangleRows(pts, triangles, cw, frame.height_px * s, py0 * s, py1 * s, canvas.data());
  detail::downsampleCoverageRows(canvas.data(), frame.width_px, py0, py1, px0, px1, s, frame.coverage_threshold, out);
  return out;
}

BitMask renderSilhouette(const VecX& positions, const std::vector<Triangle>& triangles, Index hold_particle,
                         double azimuth_deg, const SilhouetteProjection& projection, const CanonicalFrame& frame) {
  if (hold_particle < 0 || 3 * static_cast<Eigen::Index>(hold_particle) + 2 >= positions.size())
    throw InvalidArgumentError("silhouette renderer", "hold_particle",
                               "hold particle index " + std::to_string(hold_particle) + " out of range");
  return renderSilhouette(positions, triangles, Vec3(node3(positions, hold_particle)), azimuth_deg, projection, frame);
}

std::vector<SilhouetteView> renderViews(const VecX& positions, const std::vector<Triangle>& triangles, const Vec3& hold,
                                        const ViewSet& views, const SilhouetteProjection& projection,
                                        const CanonicalFrame& frame) {
  const std::vector<double> angles = views.angles();
  std::vector<SilhouetteView> out;
  out.reserve(angles.size());
  for (double a : angles) out.push_back(SilhouetteView{a, renderSilhouette(positions, triangles, hold, a, projection, frame)});
  return out;
}

}  // namespace vision
}  // namespace textile_handling
