// Scenes shared by the simulation tests.
#pragma once

#include <Eigen/Core>
#include <random>

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

}  // namespace sim_test_support
}  // namespace textile_handling
