#include "textile_handling/sim/heap_start.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <utility>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace textile_handling {

namespace {

// One fold of the stack (q: in-plane positions, z: heights) over the line {p : n.(p - a) = 0}; the
// particles with n.(q - a) > 0 are wrapped. Isometric for every layer: a particle at height z travels
// around a half-cylinder of radius (top - z) + r0 and continues flat on top of the stack.
void foldOver(const Vec2& a, const Vec2& n, Real r0, std::vector<Vec2>& q, std::vector<Real>& z) {
  const Real top = *std::max_element(z.begin(), z.end());
  for (std::size_t i = 0; i < q.size(); ++i) {
    const Real s = n.dot(q[i] - a);
    if (s <= 0) continue;
    const Real r = (top - z[i]) + r0;
    const Real angle = s / r;
    const Vec2 foot = q[i] - s * n;
    if (angle <= kPi) {
      q[i] = foot + r * std::sin(angle) * n;
      z[i] += r * (1 - std::cos(angle));
    } else {
      q[i] = foot - (s - kPi * r) * n;
      z[i] += 2 * r;
    }
  }
}

// Strain limiting (Provot 1995): grid edges are brought back towards their rest length by moving both
// ends, the held particle fixed: structural edges into [0.98, 1.002] x rest, diagonal ones to at most
// 1.002 x rest (a bend shortens a diagonal legitimately). A fold of a stack wraps its layers around one
// axis, so a crease from an earlier fold crossed by a later one is stretched or squeezed; a heap's cloth
// is slack but not compressed, and the particle model's stretch and compression laws are stiff enough
// that either would blow the first step up.
void limitStrain(const ParticleGrid& grid, Index held, std::vector<Vec3>& x) {
  struct Edge {
    Index a, b;
    Real rest;
    bool structural;
  };
  std::vector<Edge> edges;
  const Real d = grid.spacing();
  for (Index i = 0; i < grid.rows(); ++i)
    for (Index j = 0; j < grid.cols(); ++j) {
      const Index a = grid.activeIndex(i, j);
      if (a < 0) continue;
      const std::pair<Index, Index> steps[] = {{0, 1}, {1, 0}, {1, 1}, {1, -1}};
      for (const auto& [di, dj] : steps) {
        const Index b = grid.activeIndex(i + di, j + dj);
        if (b >= 0) edges.push_back({a, b, d * std::sqrt(static_cast<Real>(di * di + dj * dj)), di * dj == 0});
      }
    }
  for (int sweep = 0; sweep < 1000; ++sweep) {
    Real worst = 0;
    for (const Edge& e : edges) {
      const Vec3 ab = x[e.b] - x[e.a];
      const Real len = ab.norm();
      const Real lo = e.structural ? 0.98 * e.rest : 0, hi = 1.002 * e.rest;
      if (len >= lo && len <= hi) continue;
      const Real target = len > hi ? e.rest : 0.99 * e.rest;
      worst = std::max(worst, std::abs(len - target) / e.rest);
      const Real wa = e.a == held ? 0 : 1, wb = e.b == held ? 0 : 1;
      if (wa + wb == 0 || len < 1e-12) continue;
      const Vec3 fix = (len - target) / len * ab;
      x[e.a] += wa / (wa + wb) * fix;
      x[e.b] -= wb / (wa + wb) * fix;
    }
    if (worst < 1e-3) break;
  }
}

}  // namespace

VecX heapStartPositions(const ParticleGrid& grid, Index hold_particle, const HeapStart& heap, Real layer_gap) {
  const Index n = grid.numActive();
  if (heap.folds < 0 || heap.folds > kMaxHeapFolds)
    throw std::invalid_argument("start.heap_folds must be in [0, " + std::to_string(kMaxHeapFolds) + "], got " +
                                std::to_string(heap.folds));
  if (!(heap.lift_deg > 0 && heap.lift_deg < 180))
    throw std::invalid_argument("start.heap_lift_deg must be in (0, 180), got " + std::to_string(heap.lift_deg));
  if (!(layer_gap > 0) || !std::isfinite(layer_gap))
    throw std::invalid_argument("heap start: layer gap must be finite and > 0, got " + std::to_string(layer_gap));
  if (hold_particle < 0 || hold_particle >= n)
    throw std::invalid_argument("heap start: held particle " + std::to_string(hold_particle) + " is not one of " +
                                std::to_string(n) + " particles");
  std::vector<Vec2> q(n);
  std::vector<Real> z(n, 0);
  for (Index i = 0; i < n; ++i) q[i] = grid.activePosition(i);

  std::mt19937_64 rng(heap.seed);
  std::uniform_int_distribution<Index> pick(0, n - 1);
  std::uniform_real_distribution<Real> angle(0, 2 * kPi);
  const Real clearance = 2 * grid.spacing();
  for (int f = 0; f < heap.folds; ++f) {
    for (int attempt = 0; attempt < 200; ++attempt) {
      const Vec2 a = q[pick(rng)];
      const Real t = angle(rng);
      Vec2 dir(std::cos(t), std::sin(t));
      if (dir.dot(q[hold_particle] - a) > 0) dir = -dir;  // the held side stays
      if (dir.dot(q[hold_particle] - a) > -clearance) continue;
      Index folding = 0;
      for (Index i = 0; i < n; ++i) folding += dir.dot(q[i] - a) > 0;
      const Real share = static_cast<Real>(folding) / n;
      if (share < 0.15 || share > 0.6) continue;
      foldOver(a, dir, 0.5 * layer_gap, q, z);
      break;
    }
  }

  // Lift: the bundle turns down about the held particle, its centroid going below it, as a gripper
  // pulling a point up out of a heap leaves the rest hanging underneath.
  const Vec3 hold(q[hold_particle].x(), q[hold_particle].y(), z[hold_particle]);
  Vec3 centroid = Vec3::Zero();
  for (Index i = 0; i < n; ++i) centroid += Vec3(q[i].x(), q[i].y(), z[i]);
  centroid /= static_cast<Real>(n);
  Vec2 away = (centroid - hold).head<2>();
  if (away.norm() < 1e-9) away = Vec2(1, 0);
  away.normalize();
  const Eigen::AngleAxis<Real> lift(heap.lift_deg * kPi / 180, Vec3(-away.y(), away.x(), 0));
  std::vector<Vec3> x(n);
  for (Index i = 0; i < n; ++i) x[i] = hold + lift * (Vec3(q[i].x(), q[i].y(), z[i]) - hold);
  limitStrain(grid, hold_particle, x);
  VecX out(3 * n);
  for (Index i = 0; i < n; ++i) out.segment<3>(3 * i) = x[i];
  return out;
}

}  // namespace textile_handling
