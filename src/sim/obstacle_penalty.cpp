// Obstacles as penalty forces (obstacle_penalty.h, docs/collision.md "Obstacles as penalty forces").
#include "textile_handling/sim/obstacle_penalty.h"

#include <algorithm>
#include <cmath>

#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {

std::string obstaclePenaltyErrors(const ObstaclePenaltyOptions& o) {
  auto bad = [](const char* field, const char* rule) { return std::string(field) + " must be " + rule; };
  if (!(o.thickness > 0) || !std::isfinite(o.thickness)) return bad("thickness (contact distance)", "finite and > 0");
  if (!(o.stiffness_factor > 0) || !std::isfinite(o.stiffness_factor)) return bad("stiffness_factor", "finite and > 0");
  if (!(o.damping_ratio >= 0) || !std::isfinite(o.damping_ratio)) return bad("damping_ratio", "finite and >= 0");
  if (!(o.friction >= 0) || !std::isfinite(o.friction)) return bad("friction", "finite and >= 0");
  if (!(o.stick_speed > 0) || !std::isfinite(o.stick_speed)) return bad("stick_speed", "finite and > 0");
  return {};
}

ObstacleSurfacePoint nearestSurface(const PlaneObstacle& p, const Vec3& x) {
  ObstacleSurfacePoint s;
  s.distance = (x - p.point).dot(p.normal);
  s.normal = p.normal;
  s.velocity = p.velocity;
  return s;
}

ObstacleSurfacePoint nearestSurface(const BoxObstacle& b, const Vec3& x) {
  ObstacleSurfacePoint s;
  s.velocity = b.velocity;
  const Vec3 l = b.rotation.transpose() * (x - b.centre);
  const Vec3 q = l.cwiseAbs() - b.half_extents;
  if ((q.array() > 0).any()) {  // outside: from the nearest point of the box
    const Vec3 nearest = l.cwiseMax(-b.half_extents).cwiseMin(b.half_extents);
    const Vec3 d = l - nearest;
    s.distance = d.norm();
    s.normal = b.rotation * (d / s.distance);
    return s;
  }
  Index axis = 0;
  s.distance = q.maxCoeff(&axis);  // <= 0: minus the depth below the nearest face
  Vec3 n = Vec3::Zero();
  n[axis] = l[axis] >= 0 ? 1 : -1;
  s.normal = b.rotation * n;
  return s;
}

ObstacleSurfacePoint nearestSurface(const SphereObstacle& sp, const Vec3& x) {
  ObstacleSurfacePoint s;
  s.velocity = sp.velocity;
  const Vec3 r = x - sp.centre;
  const Real len = r.norm();
  s.distance = len - sp.radius;
  s.normal = len > 0 ? Vec3(r / len) : Vec3(Vec3::UnitZ());
  return s;
}

ObstaclePenaltyModel::ObstaclePenaltyModel(std::unique_ptr<ClothModel> base, std::vector<char> node_pinned,
                                           std::vector<PlaneObstacle> planes, std::vector<BoxObstacle> boxes,
                                           std::vector<SphereObstacle> spheres, const ObstaclePenaltyOptions& options)
    : base_(std::move(base)), pinned_(std::move(node_pinned)), planes_(std::move(planes)), boxes_(std::move(boxes)),
      spheres_(std::move(spheres)), options_(options) {
  if (!base_) throw SimError("ObstaclePenaltyModel: no model");
  if (const std::string e = obstaclePenaltyErrors(options_); !e.empty()) throw SimError("obstacle penalty: " + e);
  if (static_cast<Index>(pinned_.size()) != base_->numNodes())
    throw SimError("ObstaclePenaltyModel: the pinned mask has " + std::to_string(pinned_.size()) + " entries for " +
                   std::to_string(base_->numNodes()) + " nodes");
  for (auto& p : planes_) p = validatedPlane(p);
  for (const auto& b : boxes_) validateBox(b);
  for (const auto& s : spheres_) validateSphere(s);
  const Real m = base_->totalMass() / static_cast<Real>(std::max<Index>(1, base_->numNodes()));
  k_ = options_.stiffness_factor * m * kGravity / options_.thickness;
  c_ = options_.damping_ratio * 2 * std::sqrt(k_ * m);
}

ObstacleSurfacePoint ObstaclePenaltyModel::surface(Index obstacle, const Vec3& x) const {
  const auto np = static_cast<Index>(planes_.size()), nb = static_cast<Index>(boxes_.size());
  if (obstacle < np) return nearestSurface(planes_[static_cast<std::size_t>(obstacle)], x);
  if (obstacle < np + nb) return nearestSurface(boxes_[static_cast<std::size_t>(obstacle - np)], x);
  return nearestSurface(spheres_[static_cast<std::size_t>(obstacle - np - nb)], x);
}

ForceReport ObstaclePenaltyModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const ForceReport report = base_->computeForces(x, v, f, jac);
  const int b = dofsPerNode();
  const Index n = numNodes(), obstacles = obstacleCount();
  const BlockPattern& pattern = jacobianPattern();
  const Real mu = options_.friction;
  // Nodes are independent: each thread writes only its own nodes' entries and diagonal blocks.
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (Index i = 0; i < n; ++i) {
    if (pinned_[static_cast<std::size_t>(i)]) continue;
    const Vec3 xi = x.segment<3>(b * i), vi = v.segment<3>(b * i);
    for (Index o = 0; o < obstacles; ++o) {
      const ObstacleSurfacePoint s = surface(o, xi);
      const Real delta = options_.thickness - s.distance;
      if (!(delta > 0)) continue;
      const Vec3& nn = s.normal;
      const Mat3 nnt = nn * nn.transpose();
      const Vec3 vr = vi - s.velocity;
      Vec3 force = k_ * delta * nn - c_ * nn.dot(vr) * nn;
      Mat3 dfdv = -c_ * nnt;
      if (mu > 0) {
        const Mat3 tangential = Mat3::Identity() - nnt;
        const Vec3 u = tangential * vr;
        const Real speed = u.norm(), limit = mu * k_ * delta, eps = options_.stick_speed;
        if (speed < eps) {  // viscous: reaches the Coulomb limit at eps
          force -= (limit / eps) * u;
          dfdv -= (limit / eps) * tangential;
        } else {
          // Coulomb: the secant -(mu F_n / |u|) P, exact across the sliding direction; along it the
          // exact derivative is 0, and a constant force in the linearised step would reverse a
          // slowing node by mu g h per step instead of stopping it.
          force -= (limit / speed) * u;
          dfdv -= (limit / speed) * tangential;
        }
      }
      f.segment<3>(b * i) += force;
      if (!jac) continue;
      Real* kx = jac->dfdx.block(pattern.diagonal(i));
      Real* kv = jac->dfdv.block(pattern.diagonal(i));
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          kx[r * b + c] -= k_ * nnt(r, c);
          kv[r * b + c] += dfdv(r, c);
        }
    }
  }
  return report;
}

Real ObstaclePenaltyModel::penetration(const VecX& x, Index node, Index obstacle) const {
  return options_.thickness - surface(obstacle, x.segment<3>(dofsPerNode() * node)).distance;
}

Real ObstaclePenaltyModel::potentialEnergy(const VecX& x) const {
  Real e = base_->potentialEnergy(x);
  for (Index i = 0; i < numNodes(); ++i) {
    if (pinned_[static_cast<std::size_t>(i)]) continue;
    for (Index o = 0; o < obstacleCount(); ++o) {
      const Real delta = penetration(x, i, o);
      if (delta > 0) e += 0.5 * k_ * delta * delta;
    }
  }
  return e;
}

Index ObstaclePenaltyModel::contactsAt(const VecX& x) const {
  Index count = 0;
  for (Index i = 0; i < numNodes(); ++i) {
    if (pinned_[static_cast<std::size_t>(i)]) continue;
    for (Index o = 0; o < obstacleCount(); ++o)
      if (penetration(x, i, o) > 0) {
        ++count;
        break;
      }
  }
  return count;
}

}  // namespace textile_handling
