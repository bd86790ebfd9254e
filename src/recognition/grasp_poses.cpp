#include "textile_handling/recognition/grasp_poses.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

namespace {

Vec3 particle(const VecX& x, Index i) { return x.segment<3>(3 * static_cast<Eigen::Index>(i)); }

// Unit vector orthogonal to n (for degenerate fallbacks).
Vec3 anyPerpendicular(const Vec3& n) {
  const Vec3 a = std::abs(n.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY();
  return (a - a.dot(n) * n).normalized();
}

struct OutlineInfo {
  bool on_vertex = false, on_edge = false;
  Vec2 outward = Vec2::UnitX();
  Vec2 tangent = Vec2::UnitX();
};

Vec2 outwardNormal(const Vec2& a, const Vec2& b) {  // of edge a -> b of a counter-clockwise polygon
  const Vec2 e = (b - a).normalized();
  return Vec2(e.y(), -e.x());
}

OutlineInfo classify(const std::vector<Vec2>& ccw, const Vec2& p, double tol) {
  OutlineInfo info;
  const std::size_t n = ccw.size();
  double best_vertex = tol;
  for (std::size_t i = 0; i < n; ++i) {
    const double d = (ccw[i] - p).norm();
    if (d <= best_vertex) {
      best_vertex = d;
      const Vec2& prev = ccw[(i + n - 1) % n];
      const Vec2& next = ccw[(i + 1) % n];
      const Vec2 o = outwardNormal(prev, ccw[i]) + outwardNormal(ccw[i], next);
      info.on_vertex = true;
      info.outward = o.norm() > 1e-9 ? Vec2(o.normalized()) : outwardNormal(ccw[i], next);
      info.tangent = (next - ccw[i]).normalized();
    }
  }
  if (info.on_vertex) return info;
  double best_edge = tol;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& a = ccw[i];
    const Vec2& b = ccw[(i + 1) % n];
    const double d = pointSegmentDistance(p, a, b);
    if (d <= best_edge) {
      best_edge = d;
      info.on_edge = true;
      info.outward = outwardNormal(a, b);
      info.tangent = (b - a).normalized();
    }
  }
  return info;
}

}  // namespace

RestShapeSample sampleRestShape(const ParticleGrid& grid, const VecX& x, const Vec2& p) {
  if (grid.empty() || grid.numActive() == 0) throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "sampleRestShape: grid is empty");
  if (x.size() != 3 * static_cast<Eigen::Index>(grid.numActive()))
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "sampleRestShape: x has " + std::to_string(x.size() / 3) +
                                                                    " positions for a grid of " +
                                                                    std::to_string(grid.numActive()) + " particles");
  if (!p.allFinite()) throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "sampleRestShape: point p is not finite");
  const double d = grid.spacing();
  const Vec2 a = (p - grid.origin()) / d;
  RestShapeSample s;
  if (grid.rows() >= 2 && grid.cols() >= 2) {
    const Index j0 = static_cast<Index>(std::clamp<double>(std::floor(a.x()), 0, static_cast<double>(grid.cols() - 2)));
    const Index i0 = static_cast<Index>(std::clamp<double>(std::floor(a.y()), 0, static_cast<double>(grid.rows() - 2)));
    const double u = a.x() - j0, v = a.y() - i0;
    const Index c00 = grid.activeIndex(i0, j0), c01 = grid.activeIndex(i0, j0 + 1);
    const Index c10 = grid.activeIndex(i0 + 1, j0), c11 = grid.activeIndex(i0 + 1, j0 + 1);
    const double eps = 1e-6;
    if (c00 >= 0 && c01 >= 0 && c10 >= 0 && c11 >= 0 && u >= -eps && u <= 1 + eps && v >= -eps && v <= 1 + eps) {
      const Vec3 x00 = particle(x, c00), x01 = particle(x, c01), x10 = particle(x, c10), x11 = particle(x, c11);
      s.position = (1 - u) * (1 - v) * x00 + u * (1 - v) * x01 + (1 - u) * v * x10 + u * v * x11;
      s.du = ((1 - v) * (x01 - x00) + v * (x11 - x10)) / d;
      s.dv = ((1 - u) * (x10 - x00) + u * (x11 - x01)) / d;
      s.interpolated = true;
      return s;
    }
  }
  // Nearest particle, finite differences to its grid neighbours.
  const Index c = grid.nearestActive(p);
  s.position = particle(x, c);
  s.interpolated = false;
  auto diff = [&](int plus, int minus, const Vec3& fallback) {
    const Index a1 = grid.neighbour(c, plus), a0 = grid.neighbour(c, minus);
    if (a1 >= 0 && a0 >= 0) return Vec3((particle(x, a1) - particle(x, a0)) / (2 * d));
    if (a1 >= 0) return Vec3((particle(x, a1) - particle(x, c)) / d);
    if (a0 >= 0) return Vec3((particle(x, c) - particle(x, a0)) / d);
    return fallback;
  };
  s.du = diff(ParticleGrid::kRight, ParticleGrid::kLeft, Vec3::UnitX());
  s.dv = diff(ParticleGrid::kUp, ParticleGrid::kDown, Vec3::UnitY());
  return s;
}

VecX placeInHoldFrame(const VecX& x, Index held, double rotation_deg) {
  if (x.size() == 0 || x.size() % 3 != 0) 
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "placeInHoldFrame: positions x must be 3 per particle");
  if (held < 0 || 3 * static_cast<Eigen::Index>(held) >= x.size())
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "placeInHoldFrame: held particle out of range");
  const Mat3 r = rotationZ(rotation_deg);
  const Vec3 h = particle(x, held);
  VecX out(x.size());
  for (Eigen::Index k = 0; k < x.size() / 3; ++k) out.segment<3>(3 * k) = r * (x.segment<3>(3 * k) - h);
  return out;
}

VecX reflectAcrossView(const VecX& x, Index held, double view_deg) {
  if (x.size() == 0 || x.size() % 3 != 0) 
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "reflectAcrossView: positions x must be 3 per particle");
  if (held < 0 || 3 * static_cast<Eigen::Index>(held) >= x.size())
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "reflectAcrossView: held particle out of range");
  const double a = view_deg * kPi / 180.0;
  const Vec3 d(-std::sin(a), std::cos(a), 0.0);
  const Vec3 h = particle(x, held);
  VecX out(x.size());
  for (Eigen::Index k = 0; k < x.size() / 3; ++k) {
    const Vec3 p = x.segment<3>(3 * k);
    out.segment<3>(3 * k) = p - 2.0 * (p - h).dot(d) * d;
  }
  return out;
}

std::vector<GraspPose> computeGraspPoses(const TextileOutline& textile, const ParticleGrid& grid, const VecX& x,
                                         Index held, double rotation_deg, const HoldGeometry& geometry,
                                         const GraspPoseOptions& o) {
  if (grid.empty() || x.size() != 3 * static_cast<Eigen::Index>(grid.numActive()))
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "computeGraspPoses: positions x do not match the particle grid");
  if (held < 0 || held >= grid.numActive()) 
    throw RecognitionError(RecognitionErrorCode::kInvalidGeometry, "computeGraspPoses: held particle out of range");
  if (!(o.boundary_tolerance_m >= 0) || !std::isfinite(o.boundary_tolerance_m))
    throw RecognitionError(RecognitionErrorCode::kInvalidOptions, "computeGraspPoses: boundary_tolerance_m must be finite and >= 0");
  std::vector<Vec2> ccw = fullOutline(textile);
  if (polygonSignedArea(ccw) < 0) std::reverse(ccw.begin(), ccw.end());

  std::vector<NamedPoint> points = textile.named_points;
  if (o.include_outline_vertices) {
    const std::vector<Vec2> full = fullOutline(textile);
    for (std::size_t k = 0; k < full.size(); ++k) {
      bool covered = false;
      for (const auto& np : textile.named_points) covered = covered || (np.position - full[k]).norm() <= o.boundary_tolerance_m;
      if (!covered) points.push_back({"vertex_" + std::to_string(k), "corner", full[k]});
    }
  }

  const Mat3 r = rotationZ(rotation_deg);
  const Vec3 hold = particle(x, held);
  const Vec3 camera_h = geometry.cameraPositionHold();
  std::vector<GraspPose> out;
  out.reserve(points.size());
  for (const NamedPoint& np : points) {
    GraspPose g;
    g.name = np.name;
    g.kind = np.kind;
    g.textile_position = np.position;
    const OutlineInfo info = classify(ccw, np.position, o.boundary_tolerance_m);
    g.on_outline_vertex = info.on_vertex;
    g.on_outline_edge = info.on_edge;
    const RestShapeSample s = sampleRestShape(grid, x, np.position);
    g.position = r * (s.position - hold);
    const Vec3 du = r * s.du, dv = r * s.dv;
    Vec3 n = du.cross(dv);
    n = n.norm() > 1e-12 ? Vec3(n.normalized()) : Vec3(-geometry.view_direction_hold);
    if (o.normal == NormalConvention::kTowardsCamera && n.dot(camera_h - g.position) < 0) n = -n;
    const Vec3 out3 = du * info.outward.x() + dv * info.outward.y();
    const Vec3 tan3 = du * info.tangent.x() + dv * info.tangent.y();
    Vec3 xa = out3 - out3.dot(n) * n;
    if (xa.norm() < 1e-9) xa = tan3 - tan3.dot(n) * n;
    xa = xa.norm() < 1e-9 ? anyPerpendicular(n) : Vec3(xa.normalized());
    g.rotation.col(0) = xa;
    g.rotation.col(1) = n.cross(xa).normalized();
    g.rotation.col(2) = n;
    g.edge_direction = tan3.norm() > 1e-12 ? Vec3(tan3.normalized()) : xa;
    g.position_camera = geometry.holdToCamera(g.position);
    g.rotation_camera = geometry.rotation_camera_hold * g.rotation;
    out.push_back(std::move(g));
  }
  return out;
}

}  // namespace recognition
}  // namespace textile_handling
