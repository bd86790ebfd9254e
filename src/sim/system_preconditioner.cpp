// Preconditioners of the implicit systems (system_preconditioner.h).
#include "system_preconditioner.h"

#include <algorithm>

#include "block_rows_product.h"
#include "parallel_size.h"
#include "parallel_vector_ops.h"

namespace textile_handling {

// Two-level preconditioner: block-Jacobi smoothing on the fine level plus an exact solve of the
// Galerkin coarse system P^T A P, where P is the piecewise-constant (unsmoothed) aggregation
// prolongator. Aggregates are built greedily from the block pattern alone (a root node and its
// not yet aggregated neighbours), once per pattern and pinned set; the coarse pattern and its
// fill-reducing ordering are therefore fixed, and only values change from step to step.
class CoarseLevel {
 public:
  bool matches(const BlockPattern& p, const std::vector<char>& node_pinned) const {
    return pattern_ == &p && num_blocks_ == p.numBlocks() && pinned_ == node_pinned;
  }

  void setup(const BlockPattern& p, const std::vector<char>& node_pinned) {
    pattern_ = &p;
    num_blocks_ = p.numBlocks();
    pinned_ = node_pinned;
    b_ = p.blockSize();
    const Index n = p.numNodes();
    const auto& rs = p.rowStart();
    const auto& col = p.column();
    agg_.assign(n, -1);
    Index na = 0;
    // Neighbour lists of the block pattern (the node itself included).
    std::vector<std::vector<Index>> nb(n);
    for (Index i = 0; i < n; ++i) nb[i].assign(col.begin() + rs[i], col.begin() + rs[i + 1]);
    // Phase 1: a free node whose free neighbours are all unaggregated roots a new aggregate.
    for (Index i = 0; i < n; ++i) {
      if (node_pinned[i] || agg_[i] >= 0) continue;
      bool free_nbhd = true;
      for (Index j : nb[i])
        if (!node_pinned[j] && agg_[j] >= 0) free_nbhd = false;
      if (!free_nbhd) continue;
      for (Index j : nb[i])
        if (!node_pinned[j]) agg_[j] = na;
      ++na;
    }
    // Phase 2: leftovers join the aggregate they share most couplings with (or start their own).
    std::vector<Index> phase1 = agg_;
    for (Index i = 0; i < n; ++i) {
      if (node_pinned[i] || agg_[i] >= 0) continue;
      Index best = -1, best_count = 0;
      for (Index j0 : nb[i]) {
        const Index a = phase1[j0];
        if (a < 0) continue;
        Index count = 0;
        for (Index j1 : nb[i]) count += phase1[j1] == a;
        if (count > best_count || (count == best_count && a < best)) {
          best = a;
          best_count = count;
        }
      }
      agg_[i] = best >= 0 ? best : na++;
    }
    num_agg_ = na;
    members_start_.assign(na + 1, 0);
    for (Index i = 0; i < n; ++i)
      if (agg_[i] >= 0) ++members_start_[agg_[i] + 1];
    for (Index a = 0; a < na; ++a) members_start_[a + 1] += members_start_[a];
    members_.assign(members_start_.back(), 0);
    {
      std::vector<Index> fill(members_start_.begin(), members_start_.end() - 1);
      for (Index i = 0; i < n; ++i)
        if (agg_[i] >= 0) members_[fill[agg_[i]]++] = i;
    }
    // Coarse pattern and the (fine slot -> coarse slot) lists, grouped by coarse row.
    std::vector<std::pair<Index, Index>> couplings;
    for (Index i = 0; i < n; ++i) {
      if (agg_[i] < 0) continue;
      for (Index k = rs[i]; k < rs[i + 1]; ++k) {
        const Index j = col[k];
        if (agg_[j] >= 0 && agg_[j] != agg_[i]) couplings.emplace_back(agg_[i], agg_[j]);
      }
    }
    coarse_pattern_ = std::make_unique<BlockPattern>(na, b_, couplings);
    coarse_ = BlockSparseMatrix(coarse_pattern_.get());
    setupFineTimesProlongator(p);
    // The coarse blocks from the rows of A P: (P^T A P)(a, c) = sum over i in a of (A P)(i, c).
    gather_start_.assign(na + 1, 0);
    gather_.clear();
    for (Index a = 0; a < na; ++a) {
      for (Index m = members_start_[a]; m < members_start_[a + 1]; ++m) {
        const Index i = members_[m];
        for (Index s = ap_start_[i]; s < ap_start_[i + 1]; ++s) gather_.emplace_back(s, coarse_pattern_->find(a, ap_col_[s]));
      }
      gather_start_[a + 1] = static_cast<Index>(gather_.size());
    }
    solver_.analyse(*coarse_pattern_);
  }

  // Assembles A P and the coarse matrix P^T A P = P^T (A P), and factorises the latter.
  bool update(const BlockSparseMatrix& A) {
    if (num_agg_ == 0) return false;
    const int bb = b_ * b_;
    const bool parallel = parallelWorthIt(static_cast<Index>(agg_.size()), b_);
    const auto& fine = A.values();
    const Index n = static_cast<Index>(agg_.size());
#pragma omp parallel for schedule(static) if (parallel)
    for (Index i = 0; i < n; ++i) {
      std::fill(ap_.begin() + ap_start_[i] * bb, ap_.begin() + ap_start_[i + 1] * bb, 0.0);
      for (Index k = ap_fine_start_[i]; k < ap_fine_start_[i + 1]; ++k) {
        const Real* src = fine.data() + static_cast<size_t>(ap_fine_[k].first) * bb;
        Real* dst = ap_.data() + static_cast<size_t>(ap_fine_[k].second) * bb;
        for (int e = 0; e < bb; ++e) dst[e] += src[e];
      }
    }
    const auto& rs = coarse_pattern_->rowStart();
#pragma omp parallel for schedule(static) if (parallel)
    for (Index a = 0; a < num_agg_; ++a) {
      std::fill(coarse_.block(rs[a]), coarse_.block(rs[a + 1]), 0.0);
      for (Index g = gather_start_[a]; g < gather_start_[a + 1]; ++g) {
        const Real* src = ap_.data() + static_cast<size_t>(gather_[g].first) * bb;
        Real* dst = coarse_.block(gather_[g].second);
        for (int e = 0; e < bb; ++e) dst[e] += src[e];
      }
    }
    return solver_.factorize(coarse_);  // false unless positive definite
  }

  // z += P Ac^-1 P^T r.
  void addCoarseCorrection(const VecX& r, VecX& z) {
    rc_.resize(static_cast<Index>(num_agg_) * b_);
    const bool parallel = parallelWorthIt(static_cast<Index>(agg_.size()), b_);
#pragma omp parallel for schedule(static) if (parallel)
    for (Index a = 0; a < num_agg_; ++a) {
      auto acc = rc_.segment(a * b_, b_);
      acc.setZero();
      for (Index m = members_start_[a]; m < members_start_[a + 1]; ++m) acc += r.segment(members_[m] * b_, b_);
    }
    solver_.solve(rc_, zc_);
    const Index n = static_cast<Index>(agg_.size());
#pragma omp parallel for schedule(static) if (parallel)
    for (Index i = 0; i < n; ++i)
      if (agg_[i] >= 0) z.segment(i * b_, b_) += zc_.segment(agg_[i] * b_, b_);
  }

  // t -= (A P) zc for the zc of the last addCoarseCorrection(): the change of the residual r - A z that
  // the correction made, at the cost of A P's few blocks per row instead of a product with A.
  void subtractCoarseProduct(VecX& t) {
    multiplyBlockRows(ap_start_, ap_col_, ap_, b_, zc_, ap_zc_);
    addScaled(t, -1, ap_zc_);
  }

  Index numAggregates() const { return num_agg_; }
  const std::vector<Index>& aggregates() const { return agg_; }

 private:
  // The block pattern of A P (fine rows by aggregates: the distinct aggregates of each free row's
  // neighbours; pinned rows are empty, as A's are in the preconditioned system) and, per fine row, the
  // (fine slot -> A P slot) list that sums A's blocks into it.
  void setupFineTimesProlongator(const BlockPattern& p) {
    const Index n = p.numNodes();
    const auto& rs = p.rowStart();
    const auto& col = p.column();
    ap_start_.assign(n + 1, 0);
    ap_col_.clear();
    ap_fine_start_.assign(n + 1, 0);
    ap_fine_.clear();
    std::vector<Index> row_aggs;
    for (Index i = 0; i < n; ++i) {
      if (!pinned_[static_cast<std::size_t>(i)]) {
        row_aggs.clear();
        for (Index k = rs[i]; k < rs[i + 1]; ++k)
          if (agg_[col[k]] >= 0) row_aggs.push_back(agg_[col[k]]);
        std::sort(row_aggs.begin(), row_aggs.end());
        row_aggs.erase(std::unique(row_aggs.begin(), row_aggs.end()), row_aggs.end());
        const Index first = static_cast<Index>(ap_col_.size());
        ap_col_.insert(ap_col_.end(), row_aggs.begin(), row_aggs.end());
        for (Index k = rs[i]; k < rs[i + 1]; ++k) {
          const Index a = agg_[col[k]];
          if (a < 0) continue;
          const Index s = first + static_cast<Index>(std::lower_bound(row_aggs.begin(), row_aggs.end(), a) - row_aggs.begin());
          ap_fine_.emplace_back(k, s);
        }
      }
      ap_start_[i + 1] = static_cast<Index>(ap_col_.size());
      ap_fine_start_[i + 1] = static_cast<Index>(ap_fine_.size());
    }
    ap_.assign(ap_col_.size() * static_cast<std::size_t>(b_ * b_), 0.0);
  }

  const BlockPattern* pattern_ = nullptr;
  Index num_blocks_ = 0;
  std::vector<char> pinned_;
  int b_ = 3;
  std::vector<Index> agg_;
  Index num_agg_ = 0;
  std::vector<Index> members_start_, members_;
  std::unique_ptr<BlockPattern> coarse_pattern_;
  BlockSparseMatrix coarse_;
  std::vector<Index> ap_start_, ap_col_;                 // A P: blocks of fine row i, their aggregates
  std::vector<Real> ap_;                                 // A P's values, row-major b x b blocks
  std::vector<Index> ap_fine_start_;                     // per fine row: its (A slot, A P slot) pairs
  std::vector<std::pair<Index, Index>> ap_fine_;
  std::vector<Index> gather_start_;                      // per aggregate: its (A P slot, coarse slot) pairs
  std::vector<std::pair<Index, Index>> gather_;
  BlockLdlt solver_;
  VecX rc_, zc_, ap_zc_;
};

SystemPreconditioner::SystemPreconditioner() : coarse_(std::make_unique<CoarseLevel>()) {}
SystemPreconditioner::~SystemPreconditioner() = default;

bool SystemPreconditioner::update(const BlockSparseMatrix& a, const std::vector<char>& node_pinned,
                                  PreconditionerKind kind, int smoothing_steps, Real smoothing_weight,
                                  BlockJacobi::Inverse inverse) {
  block_ = a.pattern().blockSize();
  pinned_ = node_pinned;
  pinned_.resize(static_cast<std::size_t>(a.pattern().numNodes()), 0);
  smoothing_steps_ = std::max(0, smoothing_steps);
  smoothing_weight_ = smoothing_weight;
  use_coarse_ = false;
  system_copy_.assign(a);
  if (!jacobi_.update(a, pinned_, inverse)) return false;
  if (kind == PreconditionerKind::kTwoLevel) {
    if (!coarse_->matches(a.pattern(), pinned_)) coarse_->setup(a.pattern(), pinned_);
    use_coarse_ = coarse_->update(a);
  }
  return true;
}

std::vector<Index> SystemPreconditioner::aggregateOfNode() const {
  return use_coarse_ ? coarse_->aggregates() : std::vector<Index>();
}

bool SystemPreconditioner::dropSmoothing() {
  if (!use_coarse_ || smoothing_steps_ == 0) return false;
  smoothing_steps_ = 0;
  return true;
}

void SystemPreconditioner::applySystem(const VecX& in, VecX& out) const {
  system_copy_.multiply(in, out);
  const Index n = static_cast<Index>(pinned_.size());
  for (Index i = 0; i < n; ++i)
    if (pinned_[static_cast<std::size_t>(i)]) out.segment(i * block_, block_).setZero();
}

void SystemPreconditioner::apply(const VecX& r, VecX& z) {
  if (!use_coarse_) {
    jacobi_.apply(r, z, 1.0, false);
    return;
  }
  const int nu = smoothing_steps_;
  const Real w = smoothing_weight_;
  if (nu <= 0) {  // additive: D^-1 r + P Ac^-1 P^T r
    jacobi_.apply(r, z, 1.0, false);
    coarse_->addCoarseCorrection(r, z);
    return;
  }
  // Symmetric V(nu, nu) cycle with damped block-Jacobi smoothing.
  jacobi_.apply(r, z, w, false);
  for (int s = 1; s < nu; ++s) {
    applySystem(z, t_);
    subtractFrom(t_, r);  // t = r - t
    jacobi_.apply(t_, z, w, true);
  }
  applySystem(z, t_);
  subtractFrom(t_, r);  // t = r - t
  coarse_->addCoarseCorrection(t_, z);
  // The first post-smoothing residual r - A (z + P zc) = t - (A P) zc, without a product with A.
  coarse_->subtractCoarseProduct(t_);
  jacobi_.apply(t_, z, w, true);
  for (int s = 1; s < nu; ++s) {
    applySystem(z, t_);
    subtractFrom(t_, r);  // t = r - t
    jacobi_.apply(t_, z, w, true);
  }
}

}  // namespace textile_handling
