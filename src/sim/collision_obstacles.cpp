// Obstacle pass (planes, boxes, spheres) and the pass chain. See docs/collision.md.
#include "textile_handling/sim/collision_obstacles.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "textile_handling/sim/cloth_triangles.h"  // pinnedMask

namespace textile_handling {

BoxObstacle BoxObstacle::axisAligned(const Vec3& lo, const Vec3& hi) {
  if (!lo.allFinite() || !hi.allFinite() || !(lo.array() <= hi.array()).all())
    throw SimError("BoxObstacle: need finite corners with lo <= hi");
  BoxObstacle b;
  b.centre = 0.5 * (lo + hi);
  b.half_extents = 0.5 * (hi - lo);
  return b;
}

bool BoxObstacle::contains(const Vec3& p, Real margin) const {
  const Vec3 l = rotation.transpose() * (p - centre);
  return (l.cwiseAbs().array() <= (half_extents.array() + margin)).all();
}

ObstaclePass::ObstaclePass(std::vector<char> pinned_mask, ObstacleOptions options)
    : pinned_(std::move(pinned_mask)), options_(options) {
  if (!(options_.contact_distance >= 0) || !std::isfinite(options_.contact_distance) || !(options_.friction >= 0))
    throw SimError("ObstaclePass: contact distance and friction must be finite and >= 0");
}

ObstaclePass::ObstaclePass(Index num_particles, const PinnedNodes& pins, ObstacleOptions options)
    : ObstaclePass(pinnedMask(num_particles, pins), options) {}

PlaneObstacle validatedPlane(const PlaneObstacle& p) {
  if (!(p.normal.norm() > 0) || !p.normal.allFinite() || !p.point.allFinite() || !p.velocity.allFinite())
    throw SimError("PlaneObstacle: bad plane");
  PlaneObstacle q = p;
  q.normal.normalize();
  return q;
}

void validateBox(const BoxObstacle& b) {
  if (!b.centre.allFinite() || !(b.half_extents.array() >= 0).all() || !b.half_extents.allFinite() ||
      !b.rotation.allFinite() || !b.velocity.allFinite())
    throw SimError("BoxObstacle: bad box");
  if (!(b.rotation.transpose() * b.rotation).isApprox(Mat3::Identity(), 1e-9))
    throw SimError("BoxObstacle: rotation is not orthonormal");
}

void validateSphere(const SphereObstacle& s) {
  if (!s.centre.allFinite() || !(s.radius > 0) || !std::isfinite(s.radius) || !s.velocity.allFinite())
    throw SimError("SphereObstacle: bad sphere");
}

void ObstaclePass::addPlane(const PlaneObstacle& p) { planes_.push_back(validatedPlane(p)); }

void ObstaclePass::addBox(const BoxObstacle& b) {
  validateBox(b);
  boxes_.push_back(b);
}

void ObstaclePass::addSphere(const SphereObstacle& s) {
  validateSphere(s);
  spheres_.push_back(s);
}

namespace {

// Removes the velocity (relative to the obstacle) into the surface and applies Coulomb-like friction.
void contactVelocity(Eigen::Map<Vec3> v, const Vec3& n, const Vec3& v_obstacle, Real mu) {
  Vec3 vr = v - v_obstacle;
  const Real vn = vr.dot(n);
  if (vn >= 0) return;  // already separating
  Vec3 vt = vr - vn * n;
  const Real t = vt.norm();
  if (mu > 0 && t > 0) vt *= std::max(0.0, 1.0 - mu * (-vn) / t);
  v = v_obstacle + vt;
}

}  // namespace

long ObstaclePass::apply(const VecX& x_old, VecX& x, VecX& v) {
  const Index n = static_cast<Index>(x.size() / 3);
  if (x_old.size() != x.size() || v.size() != x.size() || static_cast<Index>(pinned_.size()) != n)
    throw SimError("ObstaclePass: state size does not match the pinned mask");
  const Real cd = options_.contact_distance, mu = options_.friction;
  long events = 0;
#pragma omp parallel for schedule(static) reduction(+ : events) if (n >= 4096)
  for (Index p = 0; p < n; ++p) {
    if (pinned_[static_cast<size_t>(p)]) continue;
    auto xp = node3(x, p);
    auto vp = node3(v, p);
    const Vec3 xo = node3(x_old, p);
    for (const auto& pl : planes_) {
      const Real phi = (xp - pl.point).dot(pl.normal);
      if (phi >= cd) continue;
      xp += (cd - phi) * pl.normal;
      contactVelocity(vp, pl.normal, pl.velocity, mu);
      ++events;
    }
    for (const auto& b : boxes_) {
      const Vec3 H = b.half_extents.array() + cd;
      Vec3 l = b.rotation.transpose() * (Vec3(xp) - b.centre);
      if (!(l.cwiseAbs().array() < H.array()).all()) continue;
      // Face to leave by: the one the particle entered through during the step (from x_old), or
      // the nearest one when it was already inside at x_old.
      const Vec3 lo = b.rotation.transpose() * (xo - b.centre);
      int axis = -1;
      Real side = 1;
      if (!(lo.cwiseAbs().array() < H.array()).all()) {
        Real best = -std::numeric_limits<Real>::infinity();
        const Vec3 d = l - lo;
        for (int k = 0; k < 3; ++k) {
          if (std::abs(lo[k]) < H[k] || d[k] == 0) continue;  // inside this slab already
          const Real s = lo[k] > 0 ? 1.0 : -1.0;
          const Real t = (s * H[k] - lo[k]) / d[k];
          if (t > best) {
            best = t;
            axis = k;
            side = s;
          }
        }
      }
      if (axis < 0) {
        Real best = std::numeric_limits<Real>::infinity();
        for (int k = 0; k < 3; ++k) {
          const Real depth = H[k] - std::abs(l[k]);
          if (depth < best) {
            best = depth;
            axis = k;
            side = l[k] >= 0 ? 1.0 : -1.0;
          }
        }
      }
      l[axis] = side * H[axis];
      xp = b.centre + b.rotation * l;
      const Vec3 nrm = side * b.rotation.col(axis);
      contactVelocity(vp, nrm, b.velocity, mu);
      ++events;
    }
    for (const auto& s : spheres_) {
      const Vec3 r = Vec3(xp) - s.centre;
      const Real dist = r.norm();
      if (dist >= s.radius + cd) continue;
      Vec3 nrm;
      if (dist > 0) {
        nrm = r / dist;
      } else {
        const Vec3 ro = xo - s.centre;
        nrm = ro.norm() > 0 ? Vec3(ro.normalized()) : Vec3(Vec3::UnitZ());
      }
      xp = s.centre + (s.radius + cd) * nrm;
      contactVelocity(vp, nrm, s.velocity, mu);
      ++events;
    }
  }
  return events;
}

long ObstaclePass::countInside(const VecX& x, Real margin) const {
  const Index n = static_cast<Index>(x.size() / 3);
  long count = 0;
  for (Index p = 0; p < n; ++p) {
    if (static_cast<size_t>(p) < pinned_.size() && pinned_[static_cast<size_t>(p)]) continue;
    const Vec3 xp = node3(x, p);
    bool inside = false;
    for (const auto& pl : planes_) inside = inside || (xp - pl.point).dot(pl.normal) < -margin;
    for (const auto& b : boxes_) {
      const Vec3 l = b.rotation.transpose() * (xp - b.centre);
      inside = inside || (l.cwiseAbs().array() < (b.half_extents.array() - margin)).all();
    }
    for (const auto& s : spheres_) inside = inside || (xp - s.centre).norm() < s.radius - margin;
    count += inside ? 1 : 0;
  }
  return count;
}

long PostStepPassChain::apply(const VecX& x_old, VecX& x, VecX& v) {
  long events = 0;
  for (PostStepPass* p : passes_)
    if (p) events += p->apply(x_old, x, v);
  return events;
}

}  // namespace textile_handling
