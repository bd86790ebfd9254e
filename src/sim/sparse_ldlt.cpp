#include "sparse_ldlt.h"
#include "parallel_size.h"

namespace textile_handling {

void BlockSparseLdlt::setPattern(const BlockPattern& p) {
  const int b = p.blockSize();
  const Index dofs = p.numNodes() * b;
  std::vector<Eigen::Triplet<Real, int>> tr;
  const auto& rs = p.rowStart();
  const auto& col = p.column();
  // Each scalar entry carries (its index in the BSR values + 1), read back below as the value map.
  for (Index i = 0; i < p.numNodes(); ++i)
    for (Index k = rs[i]; k < rs[i + 1]; ++k)
      for (int r = 0; r < b; ++r)
        for (int c = 0; c < b; ++c) {
          const Index R = i * b + r, C = col[k] * b + c;
          if (R >= C) tr.emplace_back(R, C, static_cast<Real>(static_cast<std::size_t>(k) * b * b + r * b + c + 1));
        }
  lower_.resize(dofs, dofs);
  lower_.setFromTriplets(tr.begin(), tr.end());
  lower_.makeCompressed();
  map_.resize(lower_.nonZeros());
  row_of_.resize(lower_.nonZeros());
  col_of_.resize(lower_.nonZeros());
  for (Index c = 0; c < dofs; ++c)
    for (int k = lower_.outerIndexPtr()[c]; k < lower_.outerIndexPtr()[c + 1]; ++k) {
      map_[k] = static_cast<std::size_t>(lower_.valuePtr()[k]) - 1;
      row_of_[k] = lower_.innerIndexPtr()[k];
      col_of_[k] = c;
    }
  analysed_ = false;
}

bool BlockSparseLdlt::factorize(const BlockSparseMatrix& a, const std::vector<char>& dof_pinned) {
  const auto& v = a.values();
  Real* out = lower_.valuePtr();
  const Index nnz = static_cast<Index>(map_.size());
  const bool any_pinned = !dof_pinned.empty();
  const bool parallel = parallelWorthIt(a.pattern().numNodes(), a.pattern().blockSize());
#pragma omp parallel for schedule(static) if (parallel)
  for (Index k = 0; k < nnz; ++k) {
    const Index r = row_of_[k], c = col_of_[k];
    if (any_pinned && (dof_pinned[r] || dof_pinned[c])) out[k] = r == c ? 1.0 : 0.0;
    else out[k] = v[map_[k]];
  }
  if (!analysed_) {
    ldlt_.analyzePattern(lower_);
    analysed_ = true;
  }
  ldlt_.factorize(lower_);
  if (ldlt_.info() != Eigen::Success || !ldlt_.vectorD().allFinite()) return false;
  negative_pivots_ = static_cast<Index>((ldlt_.vectorD().array() <= 0).count());
  return true;
}

}  // namespace textile_handling
