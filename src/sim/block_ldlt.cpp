// Block LDL^T (block_ldlt.h).
#include "block_ldlt.h"

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>
#include <Eigen/OrderingMethods>
#include <algorithm>

#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {

void BlockLdlt::analyse(const BlockPattern& p) {
  if (p.blockSize() < 1 || p.blockSize() > 6) throw SimError("BlockLdlt: block size must be 1 to 6");
  pattern_ = &p;
  b_ = p.blockSize();
  n_ = p.numNodes();
  factorized_ = false;
  const auto& rs = p.rowStart();
  const auto& col = p.column();

  // Fill-reducing order of the block graph (AMD on the symmetric pattern).
  {
    std::vector<Eigen::Triplet<double, int>> t;
    t.reserve(col.size());
    for (Index i = 0; i < n_; ++i)
      for (Index k = rs[i]; k < rs[i + 1]; ++k) t.emplace_back(static_cast<int>(i), static_cast<int>(col[k]), 1.0);
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> g(static_cast<int>(n_), static_cast<int>(n_));
    g.setFromTriplets(t.begin(), t.end());
    Eigen::PermutationMatrix<Eigen::Dynamic, Eigen::Dynamic, int> perm;
    Eigen::AMDOrdering<int>()(g, perm);
    // AMD returns the inverse permutation: entry k is the original row placed at position k.
    order_.assign(perm.indices().data(), perm.indices().data() + n_);
  }
  position_.assign(n_, 0);
  for (Index k = 0; k < n_; ++k) position_[order_[k]] = k;

  // Upper triangle of the permuted matrix, column by column, rows sorted.
  upper_start_.assign(n_ + 1, 0);
  upper_row_.clear();
  upper_slot_.clear();
  std::vector<std::pair<Index, Index>> entries;
  for (Index k = 0; k < n_; ++k) {
    const Index ok = order_[k];
    entries.clear();
    for (Index s = rs[ok]; s < rs[ok + 1]; ++s) {
      const Index j = position_[col[s]];
      if (j < k) entries.emplace_back(j, s);
    }
    std::sort(entries.begin(), entries.end());
    for (const auto& [j, s] : entries) {
      upper_row_.push_back(j);
      upper_slot_.push_back(s);
    }
    upper_start_[k + 1] = static_cast<Index>(upper_row_.size());
  }

  // Elimination tree (with path compression through `ancestor`).
  parent_.assign(n_, -1);
  std::vector<Index> ancestor(n_, -1);
  for (Index k = 0; k < n_; ++k)
    for (Index q = upper_start_[k]; q < upper_start_[k + 1]; ++q)
      for (Index i = upper_row_[q]; i != -1 && i < k;) {
        const Index next = ancestor[i];
        ancestor[i] = k;
        if (next == -1) parent_[i] = k;
        i = next;
      }

  // Column counts of L: row k of L is the reach of column k's upper entries in the tree.
  std::vector<Index> count(n_, 0);
  flag_.assign(n_, -1);
  for (Index k = 0; k < n_; ++k) {
    flag_[k] = k;
    for (Index q = upper_start_[k]; q < upper_start_[k + 1]; ++q)
      for (Index i = upper_row_[q]; flag_[i] != k; i = parent_[i]) {
        ++count[i];
        flag_[i] = k;
      }
  }
  l_start_.assign(n_ + 1, 0);
  for (Index i = 0; i < n_; ++i) l_start_[i + 1] = l_start_[i] + count[i];
  const std::size_t bb = static_cast<std::size_t>(b_) * b_;
  l_row_.assign(static_cast<std::size_t>(l_start_[n_]), 0);
  l_values_.assign(static_cast<std::size_t>(l_start_[n_]) * bb, 0.0);
  d_inverse_.assign(static_cast<std::size_t>(n_) * bb, 0.0);
  column_.assign(static_cast<std::size_t>(n_) * bb, 0.0);
  reach_.assign(n_, 0);
  l_fill_.assign(n_, 0);
}

Index BlockLdlt::factorBlocks() const { return l_start_.empty() ? 0 : l_start_.back(); }

template <int B>
bool BlockLdlt::factorizeFixed(const BlockSparseMatrix& a) {
  using Block = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;
  using BlockMap = Eigen::Map<Block>;
  using ConstBlockMap = Eigen::Map<const Block>;
  constexpr std::size_t bb = static_cast<std::size_t>(B) * B;
  std::fill(flag_.begin(), flag_.end(), -1);
  std::fill(l_fill_.begin(), l_fill_.end(), 0);
  std::fill(column_.begin(), column_.end(), 0.0);  // a failed factorisation may have left entries
  Real* y = column_.data();
  for (Index k = 0; k < n_; ++k) {
    // Scatter column k's upper blocks (j, k) = A(order k, order j)^T and find the reach of row k.
    flag_[k] = k;
    Index top = n_;
    for (Index q = upper_start_[k]; q < upper_start_[k + 1]; ++q) {
      Index i = upper_row_[q];
      BlockMap(y + static_cast<std::size_t>(i) * bb) = ConstBlockMap(a.block(upper_slot_[q])).transpose();
      Index len = 0;
      for (; flag_[i] != k; i = parent_[i]) {
        reach_[len++] = i;
        flag_[i] = k;
      }
      while (len > 0) reach_[--top] = reach_[--len];
    }
    Block d = ConstBlockMap(a.block(pattern_->diagonal(order_[k])));
    // Sparse triangular solve in topological order: row k of L and the Schur update of D(k).
    for (Index t = top; t < n_; ++t) {
      const Index i = reach_[t];
      BlockMap yi_map(y + static_cast<std::size_t>(i) * bb);
      const Block yi = yi_map;  // D(i) L(k, i)^T
      yi_map.setZero();
      const Index end = l_start_[i] + l_fill_[i];
      for (Index p = l_start_[i]; p < end; ++p)
        BlockMap(y + static_cast<std::size_t>(l_row_[p]) * bb).noalias() -=
            ConstBlockMap(l_values_.data() + static_cast<std::size_t>(p) * bb) * yi;
      const Block lki = yi.transpose() * ConstBlockMap(d_inverse_.data() + static_cast<std::size_t>(i) * bb);
      d.noalias() -= lki * yi;
      l_row_[end] = k;
      BlockMap(l_values_.data() + static_cast<std::size_t>(end) * bb) = lki;
      ++l_fill_[i];
    }
    if (!d.allFinite()) return false;
    const Block sym = 0.5 * (d + d.transpose());
    Eigen::LLT<Block> llt(sym);
    if (llt.info() != Eigen::Success) return false;
    BlockMap(d_inverse_.data() + static_cast<std::size_t>(k) * bb) = llt.solve(Block::Identity());
  }
  return true;
}

template <int B>
void BlockLdlt::solveFixed(const VecX& b, VecX& x) const {
  using Block = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;
  using ConstBlockMap = Eigen::Map<const Block>;
  using Vec = Eigen::Matrix<Real, B, 1>;
  constexpr std::size_t bb = static_cast<std::size_t>(B) * B;
  work_.resize(n_ * B);
  for (Index k = 0; k < n_; ++k) work_.segment<B>(k * B) = b.segment<B>(order_[k] * B);
  // L c = P b (column-oriented), then D, then L^T.
  for (Index i = 0; i < n_; ++i) {
    const Vec ci = work_.segment<B>(i * B);
    for (Index p = l_start_[i]; p < l_start_[i + 1]; ++p)
      work_.segment<B>(l_row_[p] * B).noalias() -= ConstBlockMap(l_values_.data() + static_cast<std::size_t>(p) * bb) * ci;
  }
  for (Index i = 0; i < n_; ++i) {
    const Vec ci = work_.segment<B>(i * B);
    work_.segment<B>(i * B).noalias() = ConstBlockMap(d_inverse_.data() + static_cast<std::size_t>(i) * bb) * ci;
  }
  for (Index i = n_; i-- > 0;) {
    Vec ci = work_.segment<B>(i * B);
    for (Index p = l_start_[i]; p < l_start_[i + 1]; ++p)
      ci.noalias() -= ConstBlockMap(l_values_.data() + static_cast<std::size_t>(p) * bb).transpose() *
                      work_.segment<B>(l_row_[p] * B);
    work_.segment<B>(i * B) = ci;
  }
  x.resize(n_ * B);
  for (Index k = 0; k < n_; ++k) x.segment<B>(order_[k] * B) = work_.segment<B>(k * B);
}

bool BlockLdlt::factorize(const BlockSparseMatrix& a) {
  if (pattern_ == nullptr || &a.pattern() != pattern_) throw SimError("BlockLdlt: matrix not on the analysed pattern");
  factorized_ = false;
  bool ok = false;
  switch (b_) {
    case 1: ok = factorizeFixed<1>(a); break;
    case 2: ok = factorizeFixed<2>(a); break;
    case 3: ok = factorizeFixed<3>(a); break;
    case 4: ok = factorizeFixed<4>(a); break;
    case 5: ok = factorizeFixed<5>(a); break;
    case 6: ok = factorizeFixed<6>(a); break;
    default: break;
  }
  factorized_ = ok;
  return ok;
}

void BlockLdlt::solve(const VecX& b, VecX& x) const {
  if (!factorized_) throw SimError("BlockLdlt: solve without a successful factorisation");
  if (b.size() != n_ * b_) throw SimError("BlockLdlt: right-hand side of the wrong size");
  switch (b_) {
    case 1: solveFixed<1>(b, x); return;
    case 2: solveFixed<2>(b, x); return;
    case 3: solveFixed<3>(b, x); return;
    case 4: solveFixed<4>(b, x); return;
    case 5: solveFixed<5>(b, x); return;
    case 6: solveFixed<6>(b, x); return;
    default: return;
  }
}

}  // namespace textile_handling
