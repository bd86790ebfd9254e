#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <stdexcept>

#include "block_rows_product.h"
#include "parallel_size.h"

namespace textile_handling {

BlockPattern::BlockPattern(Index num_nodes, int block,
                           const std::vector<std::pair<Index, Index>>& couplings)
    : num_nodes_(num_nodes), block_(block) {
  if (num_nodes < 0 || block < 1) throw SimError("BlockPattern: bad size");
  std::vector<std::vector<Index>> rows(num_nodes);
  for (Index i = 0; i < num_nodes; ++i) rows[i].push_back(i);
  for (const auto& [i, j] : couplings) {
    if (i < 0 || j < 0 || i >= num_nodes || j >= num_nodes)
      throw std::out_of_range("BlockPattern: coupling outside node range");
    rows[i].push_back(j);
    rows[j].push_back(i);
  }
  row_start_.assign(num_nodes + 1, 0);
  for (Index i = 0; i < num_nodes; ++i) {
    auto& r = rows[i];
    std::sort(r.begin(), r.end());
    r.erase(std::unique(r.begin(), r.end()), r.end());
    row_start_[i + 1] = row_start_[i] + static_cast<Index>(r.size());
  }
  col_.reserve(row_start_.back());
  diag_.resize(num_nodes);
  for (Index i = 0; i < num_nodes; ++i) {
    for (Index j : rows[i]) {
      if (j == i) diag_[i] = static_cast<Index>(col_.size());
      col_.push_back(j);
    }
  }
}

Index BlockPattern::find(Index i, Index j) const {
  const auto begin = col_.begin() + row_start_[i];
  const auto end = col_.begin() + row_start_[i + 1];
  const auto it = std::lower_bound(begin, end, j);
  if (it == end || *it != j) return -1;
  return static_cast<Index>(it - col_.begin());
}

BlockSparseMatrix::BlockSparseMatrix(const BlockPattern* pattern)
    : pattern_(pattern),
      bb_(pattern->blockSize() * pattern->blockSize()),
      values_(static_cast<size_t>(pattern->numBlocks()) * bb_, 0.0) {}

void BlockSparseMatrix::setZero() { std::fill(values_.begin(), values_.end(), 0.0); }

namespace {
template <int B>
void multiplyFixed(const std::vector<Index>& rs, const std::vector<Index>& col, const std::vector<Real>& values,
                   const VecX& x, VecX& y) {
  using BlockMat = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;
  using BlockVec = Eigen::Matrix<Real, B, 1>;
  const Index n = static_cast<Index>(rs.size()) - 1;
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, B))
  for (Index i = 0; i < n; ++i) {
    BlockVec acc = BlockVec::Zero();
    for (Index k = rs[i]; k < rs[i + 1]; ++k) {
      acc.noalias() += Eigen::Map<const BlockMat>(values.data() + static_cast<size_t>(k) * B * B) *
                       Eigen::Map<const BlockVec>(x.data() + static_cast<size_t>(col[k]) * B);
    }
    Eigen::Map<BlockVec>(y.data() + static_cast<size_t>(i) * B) = acc;
  }
}
}  // namespace

void multiplyBlockRows(const std::vector<Index>& rs, const std::vector<Index>& col, const std::vector<Real>& values,
                       int b, const VecX& x, VecX& y) {
  const Index n = static_cast<Index>(rs.size()) - 1;
  y.resize(n * b);
  switch (b) {
    case 3: multiplyFixed<3>(rs, col, values, x, y); return;
    case 5: multiplyFixed<5>(rs, col, values, x, y); return;
    default: break;
  }
  const Index bb = static_cast<Index>(b) * b;
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, b))
  for (Index i = 0; i < n; ++i) {
    for (int r = 0; r < b; ++r) {
      Real acc = 0;
      for (Index k = rs[i]; k < rs[i + 1]; ++k) {
        const Real* blk = values.data() + static_cast<size_t>(k) * bb + r * b;
        for (int c = 0; c < b; ++c) acc += blk[c] * x[col[k] * b + c];
      }
      y[i * b + r] = acc;
    }
  }
}

void BlockSparseMatrix::multiply(const VecX& x, VecX& y) const {
  multiplyBlockRows(pattern_->rowStart(), pattern_->column(), values_, pattern_->blockSize(), x, y);
}

}  // namespace textile_handling
