// Block LDL^T (block_ldlt.h).
#include "block_ldlt.h"

#include <omp.h>

#include <Eigen/Cholesky>
#include <Eigen/SparseCore>
#include <Eigen/OrderingMethods>
#include <algorithm>
#include <queue>

#include "textile_handling/sim/sim_errors.h"
#include "parallel_size.h"

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
  for (auto& r : reach_) r.assign(n_, 0);
  l_fill_.assign(n_, 0);
  splitTree(count);
}

Index BlockLdlt::factorBlocks() const { return l_start_.empty() ? 0 : l_start_.back(); }

std::array<Index, 3> BlockLdlt::partSizes() const {
  return {static_cast<Index>(part_[0].size()), static_cast<Index>(part_[1].size()), static_cast<Index>(part_[2].size())};
}

void BlockLdlt::splitTree(const std::vector<Index>& column_count) {
  // Work of a row: itself and its column of L; of a subtree: the sum. Children precede their parents.
  std::vector<Index> own(n_), weight(n_);
  for (Index k = 0; k < n_; ++k) own[k] = weight[k] = 1 + column_count[k];
  for (Index k = 0; k < n_; ++k)
    if (parent_[k] >= 0) weight[parent_[k]] += weight[k];
  std::vector<Index> child_start(n_ + 1, 0), children(n_);
  for (Index k = 0; k < n_; ++k)
    if (parent_[k] >= 0) ++child_start[parent_[k] + 1];
  for (Index k = 0; k < n_; ++k) child_start[k + 1] += child_start[k];
  {
    std::vector<Index> fill(child_start.begin(), child_start.end() - 1);
    for (Index k = 0; k < n_; ++k)
      if (parent_[k] >= 0) children[fill[parent_[k]]++] = k;
  }
  // A frontier of disjoint subtrees (first the trees' roots) whose roots' ancestors form the rest:
  // repeatedly move the heaviest subtree's root to the rest and its children to the frontier, and keep
  // the frontier with the least estimated time rest + max(heaviest subtree, frontier / 2).
  std::priority_queue<std::pair<Index, Index>> heap;  // (weight, -row): ties to the lower row
  Index frontier = 0, rest = 0;
  for (Index k = 0; k < n_; ++k)
    if (parent_[k] < 0) {
      heap.emplace(weight[k], -k);
      frontier += weight[k];
    }
  std::vector<Index> expanded;
  std::size_t best_count = 0;
  Index best_cost = frontier;
  while (!heap.empty()) {
    const Index cost = rest + std::max(heap.top().first, (frontier + 1) / 2);
    if (cost < best_cost) {
      best_cost = cost;
      best_count = expanded.size();
    }
    const Index k = -heap.top().second;
    if (child_start[k] == child_start[k + 1]) break;  // a leaf: the rest could only grow
    heap.pop();
    expanded.push_back(k);
    rest += own[k];
    frontier -= weight[k];
    for (Index c = child_start[k]; c < child_start[k + 1]; ++c) {
      heap.emplace(weight[children[c]], -children[c]);
      frontier += weight[children[c]];
    }
  }
  // The chosen frontier's subtrees dealt to two groups, heaviest first to the lighter group.
  member_.assign(n_, 2);
  std::vector<char> in_rest(n_, 0);
  for (std::size_t e = 0; e < best_count; ++e) in_rest[expanded[e]] = 1;
  std::vector<std::pair<Index, Index>> roots;  // (weight, -row)
  for (Index k = 0; k < n_; ++k)
    if (!in_rest[k] && (parent_[k] < 0 || in_rest[parent_[k]])) roots.emplace_back(weight[k], -k);
  std::sort(roots.rbegin(), roots.rend());
  Index load[2] = {0, 0};
  for (const auto& [w, negative_row] : roots) {
    const int g = load[1] < load[0] ? 1 : 0;
    member_[-negative_row] = static_cast<char>(g);
    load[g] += w;
  }
  for (Index k = n_; k-- > 0;)  // parents first: a row below a frontier root joins its group
    if (!in_rest[k] && member_[k] == 2 && parent_[k] >= 0) member_[k] = member_[parent_[k]];
  for (auto& p : part_) p.clear();
  for (Index k = 0; k < n_; ++k) part_[static_cast<std::size_t>(member_[k])].push_back(k);
  for (auto& o : outside_) o.setZero(n_ * b_);
}

bool BlockLdlt::partsInParallel() const { return parallelWorthIt(n_, b_) && !part_[0].empty() && !part_[1].empty(); }

template <int B>
bool BlockLdlt::factorizeFixed(const BlockSparseMatrix& a) {
  std::fill(flag_.begin(), flag_.end(), -1);
  std::fill(l_fill_.begin(), l_fill_.end(), 0);
  std::fill(column_.begin(), column_.end(), 0.0);  // a failed factorisation may have left entries
  // The subtrees (their rows reach only rows of their own subtree, and their columns of L receive
  // entries from their own rows first), then the rest; each row's arithmetic is that of the plain
  // row order, so the factor does not depend on the thread count.
  bool ok[2] = {true, true};
#pragma omp parallel for schedule(static, 1) num_threads(std::min(2, omp_get_max_threads())) if (partsInParallel())
  for (int s = 0; s < 2; ++s)
    for (Index k : part_[static_cast<std::size_t>(s)])
      if (!(ok[s] = factorizeRow<B>(a, k, reach_[static_cast<std::size_t>(s)]))) break;
  if (!ok[0] || !ok[1]) return false;
  for (Index k : part_[2])
    if (!factorizeRow<B>(a, k, reach_[0])) return false;
  return true;
}

template <int B>
bool BlockLdlt::factorizeRow(const BlockSparseMatrix& a, Index k, std::vector<Index>& reach) {
  using Block = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;
  using BlockMap = Eigen::Map<Block>;
  using ConstBlockMap = Eigen::Map<const Block>;
  constexpr std::size_t bb = static_cast<std::size_t>(B) * B;
  Real* y = column_.data();
  // Scatter column k's upper blocks (j, k) = A(order k, order j)^T and find the reach of row k.
  flag_[k] = k;
  Index top = n_;
  for (Index q = upper_start_[k]; q < upper_start_[k + 1]; ++q) {
    Index i = upper_row_[q];
    BlockMap(y + static_cast<std::size_t>(i) * bb) = ConstBlockMap(a.block(upper_slot_[q])).transpose();
    Index len = 0;
    for (; flag_[i] != k; i = parent_[i]) {
      reach[len++] = i;
      flag_[i] = k;
    }
    while (len > 0) reach[--top] = reach[--len];
  }
  Block d = ConstBlockMap(a.block(pattern_->diagonal(order_[k])));
  // Sparse triangular solve in topological order: row k of L and the Schur update of D(k).
  for (Index t = top; t < n_; ++t) {
    const Index i = reach[t];
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
  return true;
}

template <int B>
void BlockLdlt::solveFixed(const VecX& b, VecX& x) const {
  using Block = Eigen::Matrix<Real, B, B, Eigen::RowMajor>;
  using ConstBlockMap = Eigen::Map<const Block>;
  using Vec = Eigen::Matrix<Real, B, 1>;
  constexpr std::size_t bb = static_cast<std::size_t>(B) * B;
  auto lBlock = [&](Index p) { return ConstBlockMap(l_values_.data() + static_cast<std::size_t>(p) * bb); };
  work_.resize(n_ * B);
  for (Index k = 0; k < n_; ++k) work_.segment<B>(k * B) = b.segment<B>(order_[k] * B);
  // L c = P b (column-oriented). A subtree's columns update rows of their own subtree and rows of the
  // rest (their ancestors); the latter go to the subtree's own buffer, added to the rest's rows in a
  // fixed order before the rest's columns: the same arithmetic on any thread count.
  for (Index k : part_[2])
    for (auto& o : outside_) o.segment<B>(k * B).setZero();
#pragma omp parallel for schedule(static, 1) num_threads(std::min(2, omp_get_max_threads())) if (partsInParallel())
  for (int s = 0; s < 2; ++s) {
    VecX& outside = outside_[static_cast<std::size_t>(s)];
    for (Index i : part_[static_cast<std::size_t>(s)]) {
      const Vec ci = work_.segment<B>(i * B);
      for (Index p = l_start_[i]; p < l_start_[i + 1]; ++p) {
        const Index r = l_row_[p];
        VecX& target = member_[r] == s ? work_ : outside;
        target.segment<B>(r * B).noalias() -= lBlock(p) * ci;
      }
    }
  }
  for (Index k : part_[2]) work_.segment<B>(k * B) += outside_[0].segment<B>(k * B) + outside_[1].segment<B>(k * B);
  for (Index i : part_[2]) {
    const Vec ci = work_.segment<B>(i * B);
    for (Index p = l_start_[i]; p < l_start_[i + 1]; ++p) work_.segment<B>(l_row_[p] * B).noalias() -= lBlock(p) * ci;
  }
  for (Index i = 0; i < n_; ++i) {
    const Vec ci = work_.segment<B>(i * B);
    work_.segment<B>(i * B).noalias() = ConstBlockMap(d_inverse_.data() + static_cast<std::size_t>(i) * bb) * ci;
  }
  // L^T: the rest first (it reads only its own rows), then the subtrees side by side (each reads its
  // own rows and the rest's).
  auto backward = [&](Index i) {
    Vec ci = work_.segment<B>(i * B);
    for (Index p = l_start_[i]; p < l_start_[i + 1]; ++p) ci.noalias() -= lBlock(p).transpose() * work_.segment<B>(l_row_[p] * B);
    work_.segment<B>(i * B) = ci;
  };
  for (auto it = part_[2].rbegin(); it != part_[2].rend(); ++it) backward(*it);
#pragma omp parallel for schedule(static, 1) num_threads(std::min(2, omp_get_max_threads())) if (partsInParallel())
  for (int s = 0; s < 2; ++s)
    for (auto it = part_[static_cast<std::size_t>(s)].rbegin(); it != part_[static_cast<std::size_t>(s)].rend(); ++it) backward(*it);
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
