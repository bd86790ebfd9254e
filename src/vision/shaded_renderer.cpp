#include "textile_handling/vision/shaded_renderer.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "textile_handling/vision/vision_errors.h"
namespace textile_handling {
namespace vision {

CameraPose CameraPose::lookAt(const Vec3& eye, const Vec3& target, const Vec3& up) {
  if (!eye.allFinite() || !target.allFinite() || !up.allFinite())
    throw InvalidArgumentError("CameraPose::lookAt", "eye/target/up", "eye, target and up must be finite");
  const Vec3 fwd = target - eye;
  if (fwd.norm() < 1e-12) throw InvalidArgumentError("CameraPose::lookAt", "target", "eye and target coincide");
  const Vec3 z = fwd.normalized();
  const Vec3 xr = z.cross(up);
  if (xr.norm() < 1e-9 * std::max(1.0, up.norm()))
    throw InvalidArgumentError("CameraPose::lookAt", "up", "line of sight is parallel to the up vector");
  const Vec3 x = xr.normalized();
  const Vec3 y = z.cross(x);
  CameraPose p;
  p.rotation.col(0) = x;
  p.rotation.col(1) = y;
  p.rotation.col(2) = z;
  p.position = eye;
  return p;
}

CameraPose cameraPoseForView(const Vec3& hold, double azimuth_deg, double distance, double height) {
  if (!hold.allFinite() || !std::isfinite(azimuth_deg) || !std::isfinite(height) || !(distance > 0) ||
      !std::isfinite(distance))
    throw InvalidArgumentError("cameraPoseForView", "hold/azimuth_deg/height/distance",
                               "need a finite hold point, azimuth_deg, height and distance > 0");
  const Vec3 d = viewDirection(azimuth_deg);
  CameraPose p;
  p.rotation.col(0) = viewRight(azimuth_deg);
  p.rotation.col(1) = -Vec3::UnitZ();
  p.rotation.col(2) = d;
  p.position = hold - distance * d + height * Vec3::UnitZ();
  return p;
}

bool projectPoint(const PinholeIntrinsics& k, const CameraPose& pose, const Vec3& p_world, Vec2* pixel,
                  double* depth) {
  const Vec3 pc = pose.toCamera(p_world);
  if (!(pc.z() > 1e-9)) return false;
  if (pixel) *pixel = Vec2(k.fx * pc.x() / pc.z() + k.cx, k.fy * pc.y() / pc.z() + k.cy);
  if (depth) *depth = pc.z();
  return true;
}

namespace {

void validateOptions(const ShadedRenderOptions& o) {
  const auto& k = o.intrinsics;
  if (k.width <= 0 || k.height <= 0 || k.width > 16384 || k.height > 16384)
    throw InvalidArgumentError("renderShaded", "intrinsics.width/height", "intrinsics.width/height must be in 1..16384");
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy) || !std::isfinite(k.cx) ||
      !std::isfinite(k.cy))
    throw InvalidArgumentError("renderShaded", "intrinsics", "intrinsics need finite fx, fy > 0 and finite cx, cy");
  if (!o.camera.rotation.allFinite() || !o.camera.position.allFinite())
    throw InvalidArgumentError("renderShaded", "camera", "camera pose is not finite");
  if (!(o.light_direction.norm() > 0) || !o.light_direction.allFinite())
    throw InvalidArgumentError("renderShaded", "light_direction", "light_direction must be finite and non-zero");
  if (!(o.ambient >= 0) || !(o.diffuse >= 0) || !std::isfinite(o.ambient) || !std::isfinite(o.diffuse))
    throw InvalidArgumentError("renderShaded", "ambient/diffuse", "ambient and diffuse must be finite and >= 0");
  if (!(o.noise_sigma >= 0) || !std::isfinite(o.noise_sigma))
    throw InvalidArgumentError("renderShaded", "noise_sigma", "noise_sigma must be finite and >= 0");
  if (o.checker_px < 1 || o.texture_blob_px < 1)
    throw InvalidArgumentError("renderShaded", "checker_px/texture_blob_px", "checker_px and texture_blob_px must be >= 1");
}

void validateMeshShaded(const VecX& positions, const std::vector<Triangle>& triangles) {
  if (positions.size() == 0 || positions.size() % 3 != 0)
    throw InvalidArgumentError("renderShaded", "positions",
                               "positions must hold 3 values per vertex (got " + std::to_string(positions.size()) + ")");
  for (Eigen::Index i = 0; i < positions.size(); ++i)
    if (!std::isfinite(positions[i]))
      throw InvalidArgumentError("renderShaded", "positions", "position of vertex " + std::to_string(i / 3) + " is not finite");
  if (triangles.empty()) throw InvalidArgumentError("renderShaded", "triangles", "mesh has no triangles");
  const Index n = static_cast<Index>(positions.size() / 3);
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (Index v : triangles[t])
      if (v < 0 || v >= n)
        throw InvalidArgumentError("renderShaded", "triangles",
                                   "triangle " + std::to_string(t) + " has vertex index " + std::to_string(v) +
                                       " outside [0, " + std::to_string(n) + ")");
}

cv::Mat3f makeBackground(const ShadedRenderOptions& o, cv::RNG& rng) {
  const int w = o.intrinsics.width, h = o.intrinsics.height;
  const cv::Vec3f c1(o.background_bgr[0], o.background_bgr[1], o.background_bgr[2]);
  const cv::Vec3f c2(o.background2_bgr[0], o.background2_bgr[1], o.background2_bgr[2]);
  cv::Mat3f bg(h, w, c1);
  if (o.background == BackgroundType::kCheckerboard) {
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x)
        if (((x / o.checker_px) + (y / o.checker_px)) % 2) bg(y, x) = c2;
  } else if (o.background == BackgroundType::kNoiseTexture) {
    const int gw = w / o.texture_blob_px + 3, gh = h / o.texture_blob_px + 3;
    cv::Mat1f grid(gh, gw);
    rng.fill(grid, cv::RNG::UNIFORM, 0.0, 1.0);
    cv::Mat1f t;
    cv::resize(grid, t, cv::Size(gw * o.texture_blob_px, gh * o.texture_blob_px), 0, 0, cv::INTER_CUBIC);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float a = std::min(1.f, std::max(0.f, t(y + o.texture_blob_px, x + o.texture_blob_px)));
        bg(y, x) = c1 * (1.f - a) + c2 * a;
      }
  }
  return bg;
}

}  // namespace

ShadedImage renderShaded(const VecX& positions, const std::vector<Triangle>& triangles,
                         const ShadedRenderOptions& o) {
  validateOptions(o);
  validateMeshShaded(positions, triangles);
  const int w = o.intrinsics.width, h = o.intrinsics.height;
  const auto& k = o.intrinsics;
  const Index n = static_cast<Index>(positions.size() / 3);
  constexpr double kNear = 0.01;

  // Camera-frame vertices and area-weighted vertex normals (world frame).
  std::vector<Vec3> pc(static_cast<std::size_t>(n));
  std::vector<Vec3> nrm(o.render_colour ? static_cast<std::size_t>(n) : 0, Vec3::Zero());
  for (Index i = 0; i < n; ++i) pc[static_cast<std::size_t>(i)] = o.camera.toCamera(node3(positions, i));
  // Pixel position and inverse depth of every vertex, once (a vertex is shared by about six triangles).
  std::vector<Vec2> px(static_cast<std::size_t>(n));
  std::vector<double> inv_z(static_cast<std::size_t>(n));
  for (std::size_t i = 0; i < pc.size(); ++i) {
    const Vec3& p = pc[i];
    px[i] = Vec2(k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy);
    inv_z[i] = 1.0 / p.z();
  }
  if (o.render_colour)
    for (const Triangle& t : triangles) {
      const Vec3 a = node3(positions, t[0]), b = node3(positions, t[1]), c = node3(positions, t[2]);
      const Vec3 fn = (b - a).cross(c - a);
      for (Index v : t) nrm[static_cast<std::size_t>(v)] += fn;
    }
  for (auto& v : nrm) {
    const double len = v.norm();
    v = len > 0 ? Vec3(v / len) : Vec3::Zero();
  }
  const Vec3 light = o.light_direction.normalized();

  cv::RNG rng(o.seed);
  cv::Mat3f img = o.render_colour ? makeBackground(o, rng) : cv::Mat3f();
  cv::Mat1f zbuf(h, w, std::numeric_limits<float>::infinity());
  const cv::Vec3f cloth(o.cloth_bgr[0], o.cloth_bgr[1], o.cloth_bgr[2]);

  for (const Triangle& t : triangles) {
    const Vec3& A = pc[static_cast<std::size_t>(t[0])];
    const Vec3& B = pc[static_cast<std::size_t>(t[1])];
    const Vec3& C = pc[static_cast<std::size_t>(t[2])];
    if (A.z() <= kNear || B.z() <= kNear || C.z() <= kNear) continue;
    const Vec2& a = px[static_cast<std::size_t>(t[0])];
    const Vec2& b = px[static_cast<std::size_t>(t[1])];
    const Vec2& c = px[static_cast<std::size_t>(t[2])];
    const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
    if (std::abs(area) < 1e-12) continue;
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(w - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(h - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
    if (x0 > x1 || y0 > y1) continue;
    const Vec3 fnw = o.render_colour ? Vec3((Vec3(node3(positions, t[1])) - Vec3(node3(positions, t[0])))
                                                .cross(Vec3(node3(positions, t[2])) - Vec3(node3(positions, t[0])))
                                                .normalized())
                                     : Vec3::Zero();
    const double iz[3] = {inv_z[static_cast<std::size_t>(t[0])], inv_z[static_cast<std::size_t>(t[1])],
                          inv_z[static_cast<std::size_t>(t[2])]};
    const Vec3* vn[3] = {nullptr, nullptr, nullptr};  // vertex normals, colour only
    if (o.render_colour)
      for (int v = 0; v < 3; ++v) vn[v] = &nrm[static_cast<std::size_t>(t[v])];
    const double inv_area = 1.0 / area;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double px = x, py = y;
        const double l0 = ((b.x() - px) * (c.y() - py) - (b.y() - py) * (c.x() - px)) * inv_area;
        const double l1 = ((c.x() - px) * (a.y() - py) - (c.y() - py) * (a.x() - px)) * inv_area;
        const double l2 = 1.0 - l0 - l1;
        if (l0 < -1e-9 || l1 < -1e-9 || l2 < -1e-9) continue;
        const double w0 = l0 * iz[0], w1 = l1 * iz[1], w2 = l2 * iz[2];
        const double sum = w0 + w1 + w2;
        const float z = static_cast<float>(1.0 / sum);
        if (!(z < zbuf(y, x))) continue;
        zbuf(y, x) = z;
        if (!o.render_colour) continue;
        Vec3 nn = (w0 * *vn[0] + w1 * *vn[1] + w2 * *vn[2]) / sum;
        if (nn.norm() < 1e-9) nn = fnw;
        nn.normalize();
        const double inten = o.ambient + o.diffuse * std::abs(nn.dot(light));
        img(y, x) = cloth * static_cast<float>(inten);
      }
    }
  }

  ShadedImage out;
  if (o.render_colour) {
    if (o.noise_sigma > 0) {
      cv::Mat3f noise(h, w);
      rng.fill(noise, cv::RNG::NORMAL, 0.0, o.noise_sigma);
      img += noise;
    }
    img.convertTo(out.bgr, CV_8UC3);  // rounds and saturates
  }
  if (o.render_depth) {
    out.depth = cv::Mat1f(h, w);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        const float z = zbuf(y, x);
        out.depth.at<float>(y, x) = std::isfinite(z) ? z : std::numeric_limits<float>::quiet_NaN();
      }
  }
  if (o.render_mask) {
    out.mask = cv::Mat1b(h, w);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) out.mask.at<std::uint8_t>(y, x) = std::isfinite(zbuf(y, x)) ? 255 : 0;
  }
  return out;
}

cv::Rect projectedBox(const VecX& camera_points, const PinholeIntrinsics& k, int margin) {
  double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
  for (Eigen::Index v = 0; v < camera_points.size() / 3; ++v) {
    const Vec3 p = camera_points.segment<3>(3 * v);
    if (!(p.z() > 0.01)) continue;
    const double u = k.fx * p.x() / p.z() + k.cx, w = k.fy * p.y() / p.z() + k.cy;
    x0 = std::min(x0, u);
    x1 = std::max(x1, u);
    y0 = std::min(y0, w);
    y1 = std::max(y1, w);
  }
  if (!(x1 >= x0)) return cv::Rect();
  const auto clampPx = [](double v) { return static_cast<int>(std::clamp(v, -1e6, 1e6)); };
  const cv::Rect r(cv::Point(clampPx(std::floor(x0)) - margin, clampPx(std::floor(y0)) - margin),
                   cv::Point(clampPx(std::ceil(x1)) + margin + 1, clampPx(std::ceil(y1)) + margin + 1));
  return r & cv::Rect(0, 0, k.width, k.height);
}

PinholeIntrinsics cropIntrinsics(const PinholeIntrinsics& k, const cv::Rect& box) {
  return PinholeIntrinsics{k.fx, k.fy, k.cx - box.x, k.cy - box.y, box.width, box.height};
}

ShadedImage renderDepthCrop(const VecX& camera_points, const std::vector<Triangle>& triangles,
                            const PinholeIntrinsics& k, const cv::Rect& box, bool with_mask) {
  ShadedRenderOptions rop;
  rop.intrinsics = cropIntrinsics(k, box);
  rop.noise_sigma = 0;
  rop.render_mask = with_mask;
  rop.render_depth = true;
  rop.render_colour = false;
  return renderShaded(camera_points, triangles, rop);
}

}  // namespace vision
}  // namespace textile_handling
