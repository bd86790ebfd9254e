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

template <int B>
using BlockOf = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;  // the storage of a block
// The matrix a block is inverted in (3x3 blocks column-major, as the closed form has always used).
template <int B>
struct WorkBlock {
  using type = BlockOf<B>;
};
template <>
struct WorkBlock<3> {
  using type = Mat3;
};

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
bool plainInverse(const Mat3& a, Mat3& inv) {
  const Real det = a.determinant();
  if (!(std::abs(det) > 1e-300) || !std::isfinite(det)) return false;
  inv = a.inverse();
  return true;
}

template <typename Mat>
bool plainInverse(const Mat& a, Mat& inv) {
  Eigen::FullPivLU<Mat> lu(a);
  if (!lu.isInvertible()) return false;
  inv = lu.inverse();
  return true;
}

// Fixed-size blocks (B > 0) keep the per-node work free of heap allocations; B = Eigen::Dynamic serves
// the other block sizes.
template <int B>
bool invertBlocks(const BlockSparseMatrix& A, const std::vector<char>& node_pinned, bool plain, std::vector<Real>& inv_out) {
  const BlockPattern& p = A.pattern();
  const Index n = p.numNodes();
  const int b = p.blockSize();
  const std::size_t bb = static_cast<std::size_t>(b) * b;
  bool ok = true;
#pragma omp parallel for schedule(static) reduction(&& : ok) if (parallelWorthIt(n, b))
  for (Index i = 0; i < n; ++i) {
    if (node_pinned[i]) continue;
    using Work = typename WorkBlock<B>::type;
    const Work a = Eigen::Map<const BlockOf<B>>(A.block(p.diagonal(i)), b, b);
    Work inv(b, b);
    if (!(plain ? plainInverse(a, inv) : positiveDefiniteInverse(a, inv))) {
      ok = false;
      continue;
    }
    Eigen::Map<BlockOf<B>>(inv_out.data() + static_cast<std::size_t>(i) * bb, b, b) = inv;
  }
  return ok;
}

template <int B>
void applyBlocks(const std::vector<Real>& inv, const std::vector<char>& pinned, int b, const VecX& r, VecX& z, Real weight) {
  using Vec = Eigen::Matrix<Real, B, 1>;
  const Index n = static_cast<Index>(pinned.size());
  const std::size_t bb = static_cast<std::size_t>(b) * b;
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, b))
  for (Index i = 0; i < n; ++i) {
    if (pinned[i]) continue;
    Eigen::Map<Vec>(z.data() + i * b, b) +=
        weight * (Eigen::Map<const BlockOf<B>>(inv.data() + static_cast<std::size_t>(i) * bb, b, b) *
                  Eigen::Map<const Vec>(r.data() + i * b, b));
  }
}

}  // namespace

bool BlockJacobi::update(const BlockSparseMatrix& A, const std::vector<char>& node_pinned, Inverse kind) {
  b_ = A.pattern().blockSize();
  inv_.assign(static_cast<size_t>(A.pattern().numNodes()) * b_ * b_, 0.0);
  pinned_ = &node_pinned;
  const bool plain = kind == Inverse::kPlain;
  switch (b_) {
    case 3: return invertBlocks<3>(A, node_pinned, plain, inv_);
    case 5: return invertBlocks<5>(A, node_pinned, plain, inv_);
    default: return invertBlocks<Eigen::Dynamic>(A, node_pinned, plain, inv_);
  }
}

void BlockJacobi::apply(const VecX& r, VecX& z, Real weight, bool add) const {
  if (!add) z.setZero(r.size());
  switch (b_) {
    case 3: applyBlocks<3>(inv_, *pinned_, b_, r, z, weight); return;
    case 5: applyBlocks<5>(inv_, *pinned_, b_, r, z, weight); return;
    default: applyBlocks<Eigen::Dynamic>(inv_, *pinned_, b_, r, z, weight); return;
  }
}

}  // namespace textile_handling
