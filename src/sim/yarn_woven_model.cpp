// The yarn-level woven cloth model (yarn_woven_model.h).
#include "textile_handling/sim/yarn_woven_model.h"

#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <limits>
#include <utility>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/yarn_kernels.h"
#include "ordered_parallel.h"
#include "parallel_size.h"
#include "yarn_stencils.h"

namespace textile_handling {

namespace {

constexpr int kB = kYarnDofsPerNode;

}  // namespace

// The first 4 n DOFs of a stencil of n nodes, in the kernels' order.
template <int Nodes>
yarn_stencil::Dofs<Nodes> YarnWovenModel::dofsOf(const Stencil& s) {
  yarn_stencil::Dofs<Nodes> d;
  std::copy(s.dof.begin(), s.dof.begin() + 4 * Nodes, d.begin());
  return d;
}

namespace {

std::vector<std::pair<Index, Index>> runsOf(const ParticleTopology& t, int forward, int backward) {
  // (first particle, length) of every maximal run of `forward` neighbours.
  std::vector<std::pair<Index, Index>> runs;
  for (Index p = 0; p < t.size(); ++p) {
    if (t.neighbour[p][backward] >= 0) continue;  // not a run's start
    Index len = 1;
    for (Index q = t.neighbour[p][forward]; q >= 0; q = t.neighbour[q][forward]) ++len;
    runs.emplace_back(p, len);
  }
  return runs;
}

}  // namespace

YarnGrid yarnGridOnParticles(const ParticleTopology& topology, const WeavePattern& weave) {
  if (topology.size() == 0) throw SimError("yarn grid: the particle grid is empty");
  YarnGrid g;
  g.warp_spacing_m = g.weft_spacing_m = topology.spacing;
  int min_row = topology.grid[0][0], min_col = topology.grid[0][1], max_row = min_row, max_col = min_col;
  for (const auto& rc : topology.grid) {
    min_row = std::min(min_row, rc[0]), max_row = std::max(max_row, rc[0]);
    min_col = std::min(min_col, rc[1]), max_col = std::max(max_col, rc[1]);
  }
  g.warp_lines = static_cast<std::size_t>(max_row - min_row + 1);
  g.weft_lines = static_cast<std::size_t>(max_col - min_col + 1);
  g.crossings.resize(static_cast<std::size_t>(topology.size()));
  for (Index p = 0; p < topology.size(); ++p) {
    YarnCrossing& c = g.crossings[static_cast<std::size_t>(p)];
    c.warp = static_cast<std::size_t>(topology.grid[p][0] - min_row);
    c.weft = static_cast<std::size_t>(topology.grid[p][1] - min_col);
    c.position = Vec2(topology.grid[p][1], topology.grid[p][0]) * topology.spacing;
    c.warp_on_top = weave.warpOnTop(c.warp, c.weft);
  }
  for (int dir = 0; dir < 2; ++dir) {  // warp along right (0), weft along up (1)
    for (const auto& [first, len] : runsOf(topology, dir, dir + 2)) {
      YarnPiece piece;
      piece.warp = dir == 0;
      Index p = first;
      piece.line = piece.warp ? g.crossings[static_cast<std::size_t>(p)].warp : g.crossings[static_cast<std::size_t>(p)].weft;
      for (Index k = 0; k < len; ++k, p = topology.neighbour[p][dir]) {
        const Vec2& pos = g.crossings[static_cast<std::size_t>(p)].position;
        piece.nodes.push_back(static_cast<std::size_t>(p));
        piece.arc_length_m.push_back(piece.warp ? pos.x() : pos.y());
      }
      g.pieces.push_back(std::move(piece));
    }
  }
  return g;
}

Real yarnBundleSize(const WovenFabric& fabric, Real spacing) {
  return spacing * 0.5 * (fabric.warp_density_per_m + fabric.weft_density_per_m);
}

WovenFabric yarnBundleFabric(const WovenFabric& fabric, Real spacing) {
  validateWovenFabric(fabric);
  if (!(spacing > 0) || !std::isfinite(spacing))
    throw SimError("yarn bundle: spacing " + std::to_string(spacing) + " m must be finite and > 0");
  const Real n = yarnBundleSize(fabric, spacing);
  WovenFabric b = fabric;
  b.warp_density_per_m = b.weft_density_per_m = 1 / spacing;
  b.yarn_radius_m = n * fabric.yarn_radius_m;
  // k_s = Y pi R^2, k_b = B pi R^2, k_x = S R^2 scale with R^2 = n^2 R0^2: divide the moduli by n so the
  // stiffnesses are n times the real yarn's.
  b.young_modulus_pa = fabric.young_modulus_pa / n;
  b.bending_modulus = fabric.bending_modulus / n;
  b.shear_modulus_pa = fabric.shear_modulus_pa / n;
  b.linear_density_kg_per_m = n * fabric.linear_density_kg_per_m;
  return b;
}

struct YarnWovenModel::StencilSchedules {
  RowRangeSchedule segments, bends, shear_pairs;
};

YarnWovenModel::YarnWovenModel(YarnWovenModel&&) noexcept = default;
YarnWovenModel& YarnWovenModel::operator=(YarnWovenModel&&) noexcept = default;
YarnWovenModel::~YarnWovenModel() = default;

RowRangeSchedule& YarnWovenModel::schedule(const std::vector<Stencil>& list) const {
  return &list == &bends_ ? schedules_->bends : schedules_->segments;
}

RowRangeSchedule& YarnWovenModel::shearPairSchedule() const { return schedules_->shear_pairs; }

YarnWovenModel::YarnWovenModel(YarnSheet sheet, WovenFabric fabric, YarnWovenOptions options)
    : sheet_(std::move(sheet)), fabric_(std::move(fabric)), options_(std::move(options)),
      gravity_(0, 0, options_.gravity ? -kGravity : 0), schedules_(std::make_unique<StencilSchedules>()) {
  validateWovenFabric(fabric_);
  validateTearTension(options_.tear_tension_n);
  const std::size_t n = sheet_.nodeCount(), dofs = sheet_.dofCount();
  if (n == 0) throw SimError("yarn_woven: the yarn sheet has no node");
  held_.assign(dofs, 0);
  for (std::size_t d : sheet_.held_dofs) held_[d] = 1;
  arc_offset_ = sheet_.rest;
  for (std::size_t k = 0; k < n; ++k) arc_offset_.segment<3>(static_cast<Eigen::Index>(kB * k)).setZero();

  // Stencils, the couplings of the block pattern (segments, bending's outer pair) and the crossing's
  // diagonal neighbours (reserved for the shear terms, which couple a warp and a weft neighbour).
  std::vector<std::pair<Index, Index>> couplings;
  std::vector<std::array<Index, 4>> around(n, {-1, -1, -1, -1});  // warp prev, next, weft prev, next
  auto make = [&](const YarnPiece& p, std::size_t first, int nodes) {
    Stencil s;
    s.nodes = nodes;
    for (int k = 0; k < nodes; ++k) s.node[static_cast<std::size_t>(k)] = static_cast<Index>(p.nodes[first + static_cast<std::size_t>(k)]);
    if (nodes == 2) {
      const auto d = yarn_stencil::dofsOf<2>(p, first);
      std::copy(d.begin(), d.end(), s.dof.begin());
    } else {
      const auto d = yarn_stencil::dofsOf<3>(p, first);
      std::copy(d.begin(), d.end(), s.dof.begin());
    }
    return s;
  };
  yarn_stencil::forEachTerm(
      sheet_.grid,
      [&](const YarnPiece& p, std::size_t k) {
        segments_.push_back(make(p, k, 2));
        const Index a = static_cast<Index>(p.nodes[k]), b = static_cast<Index>(p.nodes[k + 1]);
        couplings.emplace_back(a, b);
        if (p.seam) return;  // a seam has no crossing terms, so no shear pairs through its neighbours
        const int o = p.warp ? 0 : 2;
        around[static_cast<std::size_t>(a)][o + 1] = b;
        around[static_cast<std::size_t>(b)][o] = a;
      },
      [&](const YarnPiece& p, std::size_t k) {
        bends_.push_back(make(p, k, 3));
        couplings.emplace_back(static_cast<Index>(p.nodes[k]), static_cast<Index>(p.nodes[k + 2]));
      });
  if (segments_.empty()) throw SimError("yarn_woven: the yarn sheet has no segment");
  for (const auto& a : around)
    for (int i : {0, 1})
      for (int j : {2, 3})
        if (a[i] >= 0 && a[j] >= 0) couplings.emplace_back(a[i], a[j]);
  pattern_ = BlockPattern(static_cast<Index>(n), kB, couplings);
  for (auto* list : {&segments_, &bends_})
    for (Stencil& s : *list)
      for (int i = 0; i < s.nodes; ++i)
        for (int j = 0; j < s.nodes; ++j) s.slot[static_cast<std::size_t>(i * s.nodes + j)] = pattern_.find(s.node[i], s.node[j]);
  stiffness_ = BlockSparseMatrix(&pattern_);
  if (fabric_.damping_stiffness_s > 0) damping_stiffness_ = BlockSparseMatrix(&pattern_);
  buildCrossingTerms(around);

  // Lumped estimate: half of each segment's rest mass to each of its nodes, on all five DOFs.
  const Real rho = fabric_.linear_density_kg_per_m;
  lumped_ = VecX::Zero(static_cast<Eigen::Index>(dofs));
  for (const Stencil& s : segments_) {
    const Real m = 0.5 * rho * (sheet_.rest[static_cast<Eigen::Index>(s.dof[7])] - sheet_.rest[static_cast<Eigen::Index>(s.dof[3])]);
    for (int k = 0; k < 2; ++k) lumped_.segment<kB>(kB * s.node[static_cast<std::size_t>(k)]).array() += m;
    total_mass_ += 2 * m;
  }
  for (std::size_t k = 0; k < n; ++k)
    if (!(lumped_[static_cast<Eigen::Index>(kB * k)] > 0))
      throw SimError("yarn_woven: node " + std::to_string(k) + " lies on no yarn segment (a crossing without yarns)");
  buildSelfContact();
}

template <int Nodes, class Matrix>
void YarnWovenModel::scatterBlocks(const Matrix& m, const Stencil& s, Real scale, BlockSparseMatrix& a,
                                   const RowShare& rows) const {
  bool any_held = false;
  for (int r = 0; r < 4 * Nodes; ++r) any_held |= held_[s.dof[static_cast<std::size_t>(r)]] != 0;
  if (!any_held) {  // the common case: node i's DOFs are x, y, z and one sliding DOF (3 or 4) in its block
    for (int i = 0; i < Nodes; ++i) {
      if (!rows.owns(s.node[static_cast<std::size_t>(i)])) continue;
      const auto si = static_cast<int>(s.dof[static_cast<std::size_t>(4 * i + 3)] % kB);
      for (int j = 0; j < Nodes; ++j) {
        const auto sj = static_cast<int>(s.dof[static_cast<std::size_t>(4 * j + 3)] % kB);
        Real* blk = a.block(s.slot[static_cast<std::size_t>(i * Nodes + j)]);
        for (int r = 0; r < 4; ++r) {
          Real* row = blk + (r < 3 ? r : si) * kB;
          for (int c = 0; c < 3; ++c) row[c] += scale * m(4 * i + r, 4 * j + c);
          row[sj] += scale * m(4 * i + r, 4 * j + 3);
        }
      }
    }
    return;
  }
  for (int r = 0; r < 4 * Nodes; ++r) {
    const Index row_node = s.node[static_cast<std::size_t>(r / 4)];
    if (!rows.owns(row_node) || held_[s.dof[static_cast<std::size_t>(r)]]) continue;
    const int lr = static_cast<int>(s.dof[static_cast<std::size_t>(r)] % kB);  // node-local coordinate
    for (int c = 0; c < 4 * Nodes; ++c) {
      if (m(r, c) == 0 || held_[s.dof[static_cast<std::size_t>(c)]]) continue;
      const int lc = static_cast<int>(s.dof[static_cast<std::size_t>(c)] % kB);
      a.block(s.slot[static_cast<std::size_t>((r / 4) * Nodes + c / 4)])[lr * kB + lc] += scale * m(r, c);
    }
  }
}

template <int Nodes, class Kernel>
void YarnWovenModel::addStencilMatrices(const std::vector<Stencil>& list, Real scale, bool skip_non_finite,
                                        BlockSparseMatrix& a, Kernel&& kernel) const {
  using Matrix = Eigen::Matrix<Real, 4 * Nodes, 4 * Nodes>;
  computeInParallelApplyByRowRanges<Matrix>(
      schedule(list), list.size(), static_cast<Index>(sheet_.nodeCount()),
      [&](std::size_t k, auto&& visit) {
        for (int i = 0; i < Nodes; ++i) visit(list[k].node[static_cast<std::size_t>(i)]);
      },
      [&](std::size_t k, Matrix& m) {
        if (!list[k].torn) m = kernel(list[k]);
      },
      [&](std::size_t k, const Matrix& m, const RowShare& rows) {
        if (!list[k].torn && (!skip_non_finite || m.allFinite())) scatterBlocks<Nodes>(m, list[k], scale, a, rows);
      });
}

template <int Nodes, class Kernel>
void YarnWovenModel::addStencilVectors(const std::vector<Stencil>& list, VecX& out, std::atomic<Index>* degenerate,
                                       Kernel&& kernel) const {
  using Vector = Eigen::Matrix<Real, 4 * Nodes, 1>;
  computeInParallelApplyByRowRanges<Vector>(
      schedule(list), list.size(), static_cast<Index>(sheet_.nodeCount()),
      [&](std::size_t k, auto&& visit) {
        for (int i = 0; i < Nodes; ++i) visit(list[k].node[static_cast<std::size_t>(i)]);
      },
      [&](std::size_t k, Vector& g) { g = kernel(list[k]); },
      [&](std::size_t k, const Vector& g, const RowShare& rows) {
        const Stencil& s = list[k];
        if (degenerate && !g.allFinite()) {
          if (rows.owns(s.node[0])) ++*degenerate;  // counted once, by the first node's thread
          return;
        }
        for (int i = 0; i < Nodes; ++i)
          if (rows.owns(s.node[static_cast<std::size_t>(i)]))
            for (int c = 0; c < 4; ++c) out[static_cast<Eigen::Index>(s.dof[static_cast<std::size_t>(4 * i + c)])] += g[4 * i + c];
      });
}

void YarnWovenModel::assembleHessian(const VecX& q, bool clamped, Real scale, BlockSparseMatrix& a) const {
  const Real k_s = fabric_.stretchStiffness(), k_b = fabric_.bendingStiffness();
  addStencilMatrices<2>(segments_, scale, true, a, [&](const Stencil& s) {
    const yarn::SegmentVector e = yarn_stencil::gather<2>(q, dofsOf<2>(s));
    return clamped ? yarn::stretchHessianClamped(e, k_s) : yarn::stretchHessian(e, k_s);
  });
  addStencilMatrices<3>(bends_, scale, true, a, [&](const Stencil& s) {
    const yarn::BendVector e = yarn_stencil::gather<3>(q, dofsOf<3>(s));
    return clamped ? yarn::bendHessianClamped(e, k_b) : yarn::bendHessian(e, k_b);
  });
}

namespace {

// to = factor * from, entry by entry on all threads (factor 0 zeroes `to`, also over NaNs in `from`).
void scaleInto(const BlockSparseMatrix& from, Real factor, BlockSparseMatrix& to) {
  const Real* src = from.values().data();
  Real* dst = to.values().data();
  const auto count = static_cast<std::ptrdiff_t>(to.values().size());
#pragma omp parallel for schedule(static)
  for (std::ptrdiff_t i = 0; i < count; ++i) dst[i] = factor == 0 ? 0 : factor * src[i];
}

}  // namespace

Real& YarnWovenModel::diagonalEntry(BlockSparseMatrix& a, std::size_t dof) const {
  const int c = static_cast<int>(dof % kB);
  return a.block(pattern_.diagonal(static_cast<Index>(dof / kB)))[c * kB + c];
}

void YarnWovenModel::addGravityHessian(Real scale, BlockSparseMatrix& a) const {
  if (!options_.gravity) return;
  const yarn::SegmentMatrix h = yarn::gravityHessian(fabric_.linear_density_kg_per_m, gravity_);
  // The same for all segments, torn ones included (their weight stays).
  computeInParallelApplyByRowRanges<char>(
      schedule(segments_), segments_.size(), static_cast<Index>(sheet_.nodeCount()),
      [&](std::size_t k, auto&& visit) {
        for (int i = 0; i < 2; ++i) visit(segments_[k].node[static_cast<std::size_t>(i)]);
      },
      [](std::size_t, char&) {}, [&](std::size_t k, const char&, const RowShare& rows) { scatterBlocks<2>(h, segments_[k], scale, a, rows); });
}

ForceReport YarnWovenModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  ForceReport report;
  report.torn_segments = static_cast<Index>(tornSegmentCount());
  const VecX q = kernelCoordinates(x);
  VecX grad = VecX::Zero(q.size());
  const Real k_s = fabric_.stretchStiffness(), k_b = fabric_.bendingStiffness(), rho = fabric_.linear_density_kg_per_m;
  // A gradient with a NaN marks a degenerate term: material slid out of the segment, or zero length.
  std::atomic<Index> degenerate{0};
  addStencilVectors<2>(segments_, grad, &degenerate, [&](const Stencil& s) {
    const yarn::SegmentVector e = yarn_stencil::gather<2>(q, dofsOf<2>(s));
    // A torn segment keeps only its gravity: the weight of its two halves (yarn_woven_tearing.cpp).
    yarn::SegmentVector g = s.torn ? yarn::SegmentVector(yarn::SegmentVector::Zero()) : yarn::stretchGradient(e, k_s);
    if (options_.gravity) g += yarn::gravityGradient(e, rho, gravity_);
    if (!(e[7] - e[3] > 0)) g[0] = std::numeric_limits<Real>::quiet_NaN();
    return g;
  });
  addStencilVectors<3>(bends_, grad, &degenerate, [&](const Stencil& s) {
    if (s.torn) return yarn::BendVector(yarn::BendVector::Zero());
    const yarn::BendVector e = yarn_stencil::gather<3>(q, dofsOf<3>(s));
    yarn::BendVector g = yarn::bendGradient(e, k_b);
    if (!(e[11] - e[3] > 0)) g[0] = std::numeric_limits<Real>::quiet_NaN();
    return g;
  });
  report.degenerate_terms += degenerate.load();
  f = -grad;
  // The normal compression is lagged: evaluated at the first state the model sees and then once per
  // accepted step (acceptStep), never inside a step.
  if (compression_.empty()) updateCompression(q);
  const bool clamped = !options_.exact_hessian;

  // The clamped Hessian K of the elastic terms (stretch, bending, shear, contact): minus the clamped
  // df/dx (with gravity's Hessian), and the stiffness of the Rayleigh damping
  // F_d = -(alpha M + beta K) v (notes 2.5). The damping's K and M are those of the step's start state
  // x_n, held over the step: F_d is then linear in v and independent of x within a step, so Newton's
  // Jacobian is exact for it (K(x) is only piecewise smooth, being clamped, and its derivative is not
  // assembled). The semi-implicit step, which evaluates forces at x_n only, is unchanged by this.
  // The Jacobians are set up before the crossing forces so that, when clamped, one pass over the
  // crossings adds their forces and their friction Jacobians; every entry of f, df/dx and df/dv still
  // receives its terms in the same order as in separate passes.
  const Real alpha = fabric_.damping_mass_per_s, beta = fabric_.damping_stiffness_s;
  const bool refresh_damping = damping_stale_;
  if (refresh_damping) damping_positions_ = x;
  damping_stale_ = false;
  const BlockSparseMatrix* k_now = nullptr;  // K(x), if assembled in this call
  if ((beta > 0 && refresh_damping) || (jac && clamped)) {
    BlockSparseMatrix& target = beta > 0 && refresh_damping ? damping_stiffness_ : stiffness_;
    scaleInto(target, 0, target);
    assembleHessian(q, true, 1, target);
    addCrossingForces(q, v, nullptr, &target, nullptr, true, kConservativeTerms, -1);
    k_now = &target;
  }
  if (jac) {
    if (clamped) {
      scaleInto(*k_now, -1, jac->dfdx);
      addGravityHessian(-1, jac->dfdx);
    } else {
      jac->dfdx.setZero();
      assembleHessian(q, false, -1, jac->dfdx);
      addGravityHessian(-1, jac->dfdx);
      addCrossingForces(q, v, nullptr, &jac->dfdx, nullptr, false, kConservativeTerms, 1);
    }
    // df/dv = -(alpha M(x_n) + beta K(x_n)).
    if (beta > 0) scaleInto(damping_stiffness_, -beta, jac->dfdv);
    else jac->dfdv.setZero();
    if (alpha > 0) addMassMatrix(damping_positions_, -alpha, jac->dfdv);
    // The held DOFs' mass entries are not damping: a held DOF has no force.
    for (std::size_t d : sheet_.held_dofs) diagonalEntry(jac->dfdv, d) = 0;
  }
  const bool one_crossing_pass = jac && clamped;
  if (one_crossing_pass)
    addCrossingForces(q, v, &f, &jac->dfdx, &jac->dfdv, clamped, kConservativeForceTerms | kFrictionTerms, 1);
  else
    addCrossingForces(q, v, &f, nullptr, nullptr, clamped, kAllCrossingTerms, 1);
  if (!self_contacts_detected_) detectSelfContacts(x);  // lagged like F_n
  addSelfContactForces(x, v, &f, nullptr, nullptr);
  // Damping as two products (beta K v + alpha M v): no third matrix is formed.
  if (beta > 0) {
    damping_stiffness_.multiply(v, damping_);
    f -= beta * damping_;
  }
  if (alpha > 0) {
    multiplyMass(damping_positions_, v, damping_);
    f -= alpha * damping_;
  }
  for (std::size_t d : sheet_.held_dofs) f[static_cast<Eigen::Index>(d)] = 0;
  if (jac) {
    if (!one_crossing_pass) addCrossingForces(q, v, nullptr, &jac->dfdx, &jac->dfdv, clamped, kFrictionTerms, 1);
    addSelfContactForces(x, v, nullptr, &jac->dfdx, &jac->dfdv);
  }
  return report;
}

Real YarnWovenModel::potentialEnergy(const VecX& x) const {
  const VecX q = kernelCoordinates(x);
  return yarnSheetEnergy(sheet_, fabric_, q, gravity_) + tornSegmentWeightEnergy(q) + crossingEnergy(q) + selfContactEnergy(x);
}

Real YarnWovenModel::gravitationalEnergy(const VecX& x) const {
  const VecX q = kernelCoordinates(x);
  Real e = 0;
  for (const Stencil& s : segments_)
    e += yarn::gravityEnergy(yarn_stencil::gather<2>(q, dofsOf<2>(s)),
                             fabric_.linear_density_kg_per_m, gravity_);
  return e;
}

Real YarnWovenModel::maxEdgeStretch(const VecX& x) const {
  const VecX q = kernelCoordinates(x);
  Real worst = 0;
  const auto count = static_cast<std::ptrdiff_t>(segments_.size());
  // A maximum does not depend on the order: the same value on any thread count.
#pragma omp parallel for schedule(static) reduction(max : worst) if (count >= kParallelMinStencils)
  for (std::ptrdiff_t k = 0; k < count; ++k) {
    const Stencil& s = segments_[static_cast<std::size_t>(k)];
    if (s.torn) continue;
    const yarn::SegmentVector e = yarn_stencil::gather<2>(q, dofsOf<2>(s));
    const Real ratio = (e.segment<3>(4) - e.segment<3>(0)).norm() / (e[7] - e[3]);
    worst = std::max(worst, std::isfinite(ratio) && ratio >= 0 ? ratio : std::numeric_limits<Real>::infinity());
  }
  return worst;
}

std::vector<DrawnYarn> YarnWovenModel::drawnYarns() const {
  std::vector<DrawnYarn> yarns;
  yarns.reserve(sheet_.grid.pieces.size());
  for (const YarnPiece& p : sheet_.grid.pieces) {
    DrawnYarn y;
    y.warp = p.warp;
    y.line = p.line;
    y.nodes.assign(p.nodes.begin(), p.nodes.end());
    yarns.push_back(std::move(y));
  }
  return yarns;
}

void YarnWovenModel::addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const {
  const VecX q = kernelCoordinates(x);
  addStencilMatrices<2>(segments_, scale, false, a, [&](const Stencil& s) {
    return yarn::segmentMass(yarn_stencil::gather<2>(q, dofsOf<2>(s)), fabric_.linear_density_kg_per_m);
  });
  addTornSegmentMass(q, scale, a);
  for (std::size_t d : sheet_.held_dofs) diagonalEntry(a, d) += scale * lumped_[static_cast<Eigen::Index>(d)];
}

void YarnWovenModel::multiplyMass(const VecX& x, const VecX& v, VecX& mv) const {
  const VecX q = kernelCoordinates(x);
  mv = VecX::Zero(v.size());
  // No degenerate count: a non-finite product is added, not skipped, so a NaN velocity reaches the force.
  addStencilVectors<2>(segments_, mv, nullptr, [&](const Stencil& s) {
    yarn::SegmentVector out = yarn::SegmentVector::Zero();
    if (s.torn) return out;
    const auto dofs = dofsOf<2>(s);
    yarn::SegmentVector local = yarn_stencil::gather<2>(v, dofs);
    for (int c = 0; c < 8; ++c)
      if (held_[s.dof[static_cast<std::size_t>(c)]]) local[c] = 0;
    out = yarn::segmentMass(yarn_stencil::gather<2>(q, dofs), fabric_.linear_density_kg_per_m) * local;
    for (int c = 0; c < 8; ++c)
      if (held_[s.dof[static_cast<std::size_t>(c)]]) out[c] = 0;
    return out;
  });
  addTornSegmentMassProduct(q, v, mv);
  for (std::size_t d : sheet_.held_dofs)
    mv[static_cast<Eigen::Index>(d)] += lumped_[static_cast<Eigen::Index>(d)] * v[static_cast<Eigen::Index>(d)];
}

}  // namespace textile_handling
