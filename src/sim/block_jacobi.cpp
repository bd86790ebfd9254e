// Block-Jacobi preconditioner (block_jacobi.h).
// GCC 12 reports a -Wmaybe-uninitialized false positive inside Eigen's SelfAdjointEigenSolver
// (tridiagonalisation); silence it for this file only (it must precede the first Eigen include).
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif

#include "block_jacobi.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <cmath>

#include "parallel_size.h"

namespace textile_handling {

namespace {

using RowMajor3 = Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>;
using RowMajorX = Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// D^-1 by Cholesky when the (symmetrised) block is positive definite, else V |Lambda|^-1 V^T.
template <typename Mat>
bool positiveDefiniteInverse(const Mat& block, Mat& inv) {
  const Mat a = 0.5 * (block + block.transpose());
  if (!a.allFinite()) return false;
  const Eigen::LLT<Mat> llt(a);
  if (llt.info() == Eigen::Success) {
    inv = llt.solve(Mat::Identity(a.rows(), a.cols()));
    return inv.allFinite();
  }
  const Eigen::SelfAdjointEigenSolver<Mat> eig(a);
  if (eig.info() != Eigen::Success) return false;
  const auto magnitude = eig.eigenvalues().cwiseAbs().eval();
  const Real top = magnitude.maxCoeff();
  if (!(top > 0) || !(magnitude.minCoeff() > 1e-12 * top)) return false;
  inv = eig.eigenvectors() * magnitude.cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  return inv.allFinite();
}

// The plain inverse: closed form for 3x3 blocks, full-pivot LU otherwise.
bool plainInverse3(const Mat3& a, Mat3& inv) {
  const Real det = a.determinant();
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) return false;
  inv = a.inverse();
  return true;
}

bool plainInverseX(const RowMajorX& a, RowMajorX& inv) {
  Eigen::FullPivLU<Eigen::MatrixXd> lu(a);
  if (!lu.isInvertible()) return false;
  inv = lu.inverse();
  return true;
}

}  // namespace

bool BlockJacobi::update(const BlockSparseMatrix& A, const std::vector<char>& node_pinned, Inverse kind) {
  const BlockPattern& p = A.pattern();
  const Index n = p.numNodes();
  b_ = p.blockSize();
  const int bb = b_ * b_;
  inv_.assign(static_cast<size_t>(n) * bb, 0.0);
  pinned_ = &node_pinned;
  const bool plain = kind == Inverse::kPlain;
  bool ok = true;
#pragma omp parallel for schedule(static) reduction(&& : ok) if (parallelWorthIt(n, b_))
  for (Index i = 0; i < n; ++i) {
    if (node_pinned[i]) continue;
    const Real* blk = A.block(p.diagonal(i));
    Real* out = inv_.data() + static_cast<size_t>(i) * bb;
    if (b_ == 3) {
      const Mat3 a = Eigen::Map<const RowMajor3>(blk);
      Mat3 inv;
      if (!(plain ? plainInverse3(a, inv) : positiveDefiniteInverse(a, inv))) {
        ok = false;
        continue;
      }
      Eigen::Map<RowMajor3> o(out);
      o = inv;
    } else {
      const RowMajorX a = Eigen::Map<const RowMajorX>(blk, b_, b_);
      RowMajorX inv;
      if (!(plain ? plainInverseX(a, inv) : positiveDefiniteInverse(a, inv))) {
        ok = false;
        continue;
      }
      Eigen::Map<RowMajorX> o(out, b_, b_);
      o = inv;
    }
  }
  return ok;
}

void BlockJacobi::apply(const VecX& r, VecX& z, Real weight, bool add) const {
  const Index n = static_cast<Index>((*pinned_).size());
  const int bb = b_ * b_;
  if (!add) z.setZero(r.size());
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, b_))
  for (Index i = 0; i < n; ++i) {
    if ((*pinned_)[i]) continue;
    const Real* m = inv_.data() + static_cast<size_t>(i) * bb;
    if (b_ == 3) {
      Eigen::Map<Vec3>(z.data() + 3 * i) +=
          weight * (Eigen::Map<const RowMajor3>(m) * Eigen::Map<const Vec3>(r.data() + 3 * i));
    } else {
      z.segment(i * b_, b_) += weight * (Eigen::Map<const RowMajorX>(m, b_, b_) * r.segment(i * b_, b_));
    }
  }
}

}  // namespace textile_handling
