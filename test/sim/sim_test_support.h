// Scenes shared by the simulation tests.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <random>
#include <utility>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/drape_scene.h"

namespace textile_handling {
namespace sim_test_support {

/// A cotton square of side `side` [m] at spacing d, held at its upper-left corner ("corner") at
/// (0, 0, 1), released flat and at rest; the default model (particle_kes with its defaults).
inline DrapeSceneSpec heldSquareSpec(Real side, Real d) {
  TextileOutline t;
  t.name = "test_square";
  t.outline = {Vec2(0, 0), Vec2(side, 0), Vec2(side, side), Vec2(0, side)};
  t.named_points = {NamedPoint{"corner", "corner", Vec2(0, side)}};
  DrapeSceneSpec s;
  s.textile = t;
  s.material = Material::cotton();
  s.spacing = d;
  s.hold = {HoldPoint{"corner", Vec2::Zero()}};
  s.hold_position = Vec3(0, 0, 1);
  return s;
}

/// n values uniform in [-scale, scale] from a fixed seed.
inline VecX randomVector(Index n, unsigned seed, Real scale = 1) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> unit(-1.0, 1.0);
  VecX v(n);
  for (Index i = 0; i < n; ++i) v[i] = scale * unit(rng);
  return v;
}

/// The dense matrix of a block-sparse one (column by column, products with unit vectors).
inline Eigen::MatrixXd denseMatrix(const BlockSparseMatrix& a) {
  const Index n = a.pattern().numNodes() * a.pattern().blockSize();
  Eigen::MatrixXd m(n, n);
  VecX e = VecX::Zero(n), col;
  for (Index k = 0; k < n; ++k) {
    e[k] = 1;
    a.multiply(e, col);
    m.col(k) = col;
    e[k] = 0;
  }
  return m;
}

/// Couplings of a w x h grid with the yarn sheet's reach: neighbours one and two apart along rows and
/// columns, and diagonal neighbours.
inline std::vector<std::pair<Index, Index>> gridCouplings(Index w, Index h) {
  std::vector<std::pair<Index, Index>> c;
  auto id = [w](Index x, Index y) { return y * w + x; };
  for (Index y = 0; y < h; ++y)
    for (Index x = 0; x < w; ++x)
      for (const auto& [dx, dy] : std::vector<std::pair<Index, Index>>{{1, 0}, {2, 0}, {0, 1}, {0, 2}, {1, 1}, {1, -1}})
        if (x + dx >= 0 && x + dx < w && y + dy >= 0 && y + dy < h) c.emplace_back(id(x, y), id(x + dx, y + dy));
  return c;
}

/// Symmetric values on the pattern: random off-diagonal blocks (the transpose mirrored) and diagonal
/// blocks that make the matrix positive definite when `definite`, or give it a negative eigenvalue.
inline void fillSymmetric(std::mt19937& gen, BlockSparseMatrix& a, bool definite) {
  const BlockPattern& p = a.pattern();
  const int b = p.blockSize();
  std::uniform_real_distribution<Real> val(-1, 1);
  a.setZero();
  std::vector<Real> row_sum(static_cast<std::size_t>(p.numNodes()), 0.0);
  for (Index i = 0; i < p.numNodes(); ++i)
    for (Index k = p.rowStart()[i]; k < p.rowStart()[i + 1]; ++k) {
      const Index j = p.column()[k];
      if (j <= i) continue;
      Real* upper = a.block(k);
      Real* lower = a.block(p.find(j, i));
      for (int r = 0; r < b; ++r)
        for (int c = 0; c < b; ++c) {
          const Real v = val(gen);
          upper[r * b + c] = v;
          lower[c * b + r] = v;
          row_sum[static_cast<std::size_t>(i)] += std::abs(v);
          row_sum[static_cast<std::size_t>(j)] += std::abs(v);
        }
    }
  for (Index i = 0; i < p.numNodes(); ++i) {
    Real* d = a.block(p.diagonal(i));
    for (int r = 0; r < b; ++r)
      for (int c = r; c < b; ++c) {
        const Real v = 0.1 * val(gen);
        d[r * b + c] = v;
        d[c * b + r] = v;
      }
    for (int r = 0; r < b; ++r) d[r * b + r] += row_sum[static_cast<std::size_t>(i)] + 1.0 + b;
  }
  if (!definite) {
    const Index i = p.numNodes() / 2;
    a.block(p.diagonal(i))[0] = -1.0 - row_sum[static_cast<std::size_t>(i)];
  }
}

}  // namespace sim_test_support
}  // namespace textile_handling
