#include "textile_handling/sim/grid_prolongation.h"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {

namespace {

// Affine interpolation (or extrapolation) at textile point p from coarse particles near it: the
// nearest, then the next distinct one, then the nearest one that makes a triangle of fair area.
bool affineFromNeighbours(const ParticleGrid& g, const VecX& X, const Vec2& p, Index i0, Index j0, Index reach,
                          Vec3* out) {
  std::vector<std::pair<Real, Index>> near;
  for (Index i = i0 - reach; i <= i0 + 1 + reach; ++i)
    for (Index j = j0 - reach; j <= j0 + 1 + reach; ++j) {
      const Index c = g.activeIndex(i, j);
      if (c >= 0) near.emplace_back((g.activePosition(c) - p).squaredNorm(), c);
    }
  if (near.size() < 3) return false;
  std::sort(near.begin(), near.end());
  const Index a = near[0].second, b = near[1].second;
  const Vec2 pa = g.activePosition(a), pb = g.activePosition(b);
  const Real d2 = g.spacing() * g.spacing();
  for (std::size_t k = 2; k < near.size(); ++k) {
    const Index c = near[k].second;
    const Vec2 pc = g.activePosition(c);
    Eigen::Matrix<Real, 2, 2> B;
    B.col(0) = pb - pa;
    B.col(1) = pc - pa;
    if (std::abs(B.determinant()) < 0.25 * d2) continue;
    const Eigen::Matrix<Real, 2, 1> w = B.inverse() * (p - pa);
    const Vec3 xa = X.segment<3>(3 * a), xb = X.segment<3>(3 * b), xc = X.segment<3>(3 * c);
    *out = xa + w[0] * (xb - xa) + w[1] * (xc - xa);
    return true;
  }
  return false;
}

}  // namespace

VecX prolongPositions(const ParticleGrid& coarse, const VecX& coarse_positions, const ParticleGrid& fine) {
  if (coarse.empty() || fine.empty()) throw SimError("prolongPositions: empty particle grid");
  if (coarse_positions.size() != 3 * coarse.numActive())
    throw SimError("prolongPositions: coarse positions have " + std::to_string(coarse_positions.size()) +
                   " values, the coarse grid needs " + std::to_string(3 * coarse.numActive()));
  const Index nf = fine.numActive();
  const Real dc = coarse.spacing();
  VecX out(3 * nf);
#pragma omp parallel for schedule(static)
  for (Index f = 0; f < nf; ++f) {
    const Vec2 p = fine.activePosition(f);
    const Vec2 u = (p - coarse.origin()) / dc;
    const Index j0 = static_cast<Index>(std::floor(u.x())), i0 = static_cast<Index>(std::floor(u.y()));
    const Real a = u.x() - static_cast<Real>(j0), b = u.y() - static_cast<Real>(i0);
    const Index c00 = coarse.activeIndex(i0, j0), c01 = coarse.activeIndex(i0, j0 + 1);
    const Index c10 = coarse.activeIndex(i0 + 1, j0), c11 = coarse.activeIndex(i0 + 1, j0 + 1);
    Vec3 x = Vec3::Zero();
    if (c00 >= 0 && c01 >= 0 && c10 >= 0 && c11 >= 0) {
      auto X = [&](Index c) { return Vec3(coarse_positions.segment<3>(3 * c)); };
      x = (1 - a) * (1 - b) * X(c00) + a * (1 - b) * X(c01) + (1 - a) * b * X(c10) + a * b * X(c11);
    } else {
      bool found = false;
      for (Index reach = 1; reach <= 3 && !found; ++reach)
        found = affineFromNeighbours(coarse, coarse_positions, p, i0, j0, reach, &x);
      if (!found) x = coarse_positions.segment<3>(3 * coarse.nearestActive(p));
    }
    out.segment<3>(3 * f) = x;
  }
  return out;
}

}  // namespace textile_handling
