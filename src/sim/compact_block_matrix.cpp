// Compact copy of a block-sparse matrix for products (compact_block_matrix.h).
#include "compact_block_matrix.h"

#include <limits>

#include "parallel_size.h"

namespace textile_handling {

namespace {

constexpr int kB = 5;  // the block size that is compacted

// The DOF subsets, narrowest first; a block takes the first that covers its nonzero rows and columns.
struct DofSubset {
  unsigned mask;  // bit d set: DOF d is in the subset
  int size;
  int dof[kB];
};
constexpr DofSubset kSubsets[] = {
    {0b00111u, 3, {0, 1, 2, 0, 0}},  // position only (shear between diagonal neighbours)
    {0b01111u, 4, {0, 1, 2, 3, 0}},  // position and u (along a warp yarn)
    {0b10111u, 4, {0, 1, 2, 4, 0}},  // position and v (along a weft yarn)
    {0b11111u, 5, {0, 1, 2, 3, 4}},
};
constexpr int kNumSubsets = 4;
constexpr std::uint8_t kFull = kNumSubsets - 1;

// Rows and columns of a 5 x 5 row-major block holding a nonzero (or NaN), as one DOF mask.
unsigned nonzeroMask(const Real* blk) {
  unsigned m = 0;
  for (int r = 0; r < kB; ++r)
    for (int c = 0; c < kB; ++c)
      if (!(blk[r * kB + c] == 0)) m |= (1u << r) | (1u << c);
  return m;
}

std::uint8_t narrowestCovering(unsigned mask) {
  for (int s = 0; s < kNumSubsets; ++s)
    if ((mask & ~kSubsets[s].mask) == 0) return static_cast<std::uint8_t>(s);
  return kFull;
}

// acc[dof] += (the block's subset rows) . x_j[subset columns], in column order within each row. The
// subset's DOFs are 0, 1, 2 and then `Fourth` (3 for u, 4 for v) and 4: known at compile time, so
// the loads and the accumulators need no index table.
template <int S, int Fourth>
inline void addSubsetProduct(const Real* a, const Real* xj, Real* acc) {
  constexpr int dof[kB] = {0, 1, 2, Fourth, 4};
  Real xs[S];
  for (int c = 0; c < S; ++c) xs[c] = xj[dof[c]];
  for (int r = 0; r < S; ++r) {
    Real s = 0;
    for (int c = 0; c < S; ++c) s += a[r * S + c] * xs[c];
    acc[dof[r]] += s;
  }
}

}  // namespace

bool CompactBlockMatrix::compacts(const BlockSparseMatrix& a) const {
  return pattern_ == &a.pattern() && !subset_.empty() && subset_.size() == static_cast<std::size_t>(a.pattern().numBlocks());
}

void CompactBlockMatrix::chooseSubsets(const BlockSparseMatrix& a) {
  const Index num_blocks = a.pattern().numBlocks();
  if (!compacts(a)) subset_.assign(static_cast<std::size_t>(num_blocks), 0);
  pattern_ = &a.pattern();
  start_.assign(static_cast<std::size_t>(num_blocks) + 1, 0);
  std::size_t total = 0;
  for (Index k = 0; k < num_blocks; ++k) {
    const std::size_t kk = static_cast<std::size_t>(k);
    // Subsets only widen, so a term that switches on and off does not repack every time.
    subset_[kk] = narrowestCovering(nonzeroMask(a.block(k)) | kSubsets[subset_[kk]].mask);
    const int s = kSubsets[subset_[kk]].size;
    total += static_cast<std::size_t>(s * s);
    if (total > std::numeric_limits<std::uint32_t>::max()) {  // offsets would overflow: no compaction
      subset_.clear();
      start_.clear();
      values_.clear();
      return;
    }
    start_[kk + 1] = static_cast<std::uint32_t>(total);
  }
  values_.resize(total);
}

bool CompactBlockMatrix::pack(const BlockSparseMatrix& a) {
  const BlockPattern& p = a.pattern();
  const Index n = p.numNodes();
  const auto& rs = p.rowStart();
  bool fits = true;
#pragma omp parallel for schedule(static) reduction(&& : fits) if (parallelWorthIt(n, kB))
  for (Index i = 0; i < n; ++i) {
    for (Index k = rs[i]; k < rs[i + 1]; ++k) {
      const Real* blk = a.block(k);
      const DofSubset& sub = kSubsets[subset_[static_cast<std::size_t>(k)]];
      if (sub.size < kB && (nonzeroMask(blk) & ~sub.mask) != 0) fits = false;
      Real* dst = values_.data() + start_[static_cast<std::size_t>(k)];
      for (int r = 0; r < sub.size; ++r)
        for (int c = 0; c < sub.size; ++c) dst[r * sub.size + c] = blk[sub.dof[r] * kB + sub.dof[c]];
    }
  }
  return fits;
}

void CompactBlockMatrix::assign(const BlockSparseMatrix& a) {
  full_ = &a;
  if (a.pattern().blockSize() != kB) {
    subset_.clear();
    start_.clear();
    values_.clear();
    pattern_ = nullptr;
    return;
  }
  if (!compacts(a)) chooseSubsets(a);
  if (subset_.empty()) return;  // too large to compact
  if (!pack(a)) {
    chooseSubsets(a);
    pack(a);
  }
}

void CompactBlockMatrix::multiply(const VecX& x, VecX& y) const {
  if (subset_.empty()) {
    full_->multiply(x, y);
    return;
  }
  const BlockPattern& p = *pattern_;
  const Index n = p.numNodes();
  const auto& rs = p.rowStart();
  const auto& col = p.column();
  y.resize(static_cast<Eigen::Index>(n) * kB);
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, kB))
  for (Index i = 0; i < n; ++i) {
    Real acc[kB] = {0, 0, 0, 0, 0};
    for (Index k = rs[i]; k < rs[i + 1]; ++k) {
      const std::size_t kk = static_cast<std::size_t>(k);
      const Real* a = values_.data() + start_[kk];
      const Real* xj = x.data() + static_cast<std::size_t>(col[kk]) * kB;
      switch (subset_[kk]) {  // kSubsets' order
        case 0: addSubsetProduct<3, 3>(a, xj, acc); break;
        case 1: addSubsetProduct<4, 3>(a, xj, acc); break;
        case 2: addSubsetProduct<4, 4>(a, xj, acc); break;
        default: addSubsetProduct<5, 3>(a, xj, acc); break;
      }
    }
    for (int r = 0; r < kB; ++r) y[static_cast<Eigen::Index>(i) * kB + r] = acc[r];
  }
}

std::size_t CompactBlockMatrix::storedValues() const {
  if (!subset_.empty()) return values_.size();
  return full_ ? full_->values().size() : 0;
}

}  // namespace textile_handling
