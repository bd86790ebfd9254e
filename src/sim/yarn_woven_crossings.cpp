// The crossing terms of the yarn_woven model (yarn_woven_model.h): shear with compression-dependent
// stiffness and jamming (eq. 11), shear friction (eq. 12), sliding friction (eq. 10) and contact
// between neighbouring parallel yarns (eq. 13), with the lagged normal compression of eq. 9 and the
// friction anchors. Kernels: yarn_crossing_kernels.h; docs/yarn_model.md, "Crossing terms in the model".
#include <algorithm>
#include <cmath>
#include <utility>

#include "textile_handling/sim/yarn_crossing_kernels.h"
#include "textile_handling/sim/yarn_normal_force.h"
#include "textile_handling/sim/yarn_woven_model.h"
#include "ordered_parallel.h"
#include "parallel_size.h"

namespace textile_handling {

namespace {
constexpr int kB = kYarnDofsPerNode;
constexpr Real kRightAngle = 0.5 * kPi;
}  // namespace

void YarnWovenModel::buildCrossingTerms(const std::vector<std::array<Index, 4>>& around) {
  const YarnGrid& g = sheet_.grid;
  const Real n = options_.bundle_size;
  const YarnCrossingOptions& c = options_.crossing;
  spacing_ = 0.5 * (fabric_.warpSpacing() + fabric_.weftSpacing());
  const Real k_s = fabric_.stretchStiffness(), R = fabric_.yarn_radius_m;
  k_x_ = fabric_.shear_modulus_pa * R * R;
  k_f_ = c.friction_stiffness_factor * k_s / spacing_;
  d_f_ = fabric_.damping_stiffness_s * k_f_;
  k_fphi_ = c.shear_friction_stiffness_factor * k_x_ * spacing_;
  mu_phi_ = fabric_.sliding_friction * spacing_ / n;  // mu L of the real yarn (notes 3.6)
  c_n_ = c.compression_gain_per_n / (n * n);
  k_c_ = c.contact_stiffness_factor * k_s / (spacing_ * spacing_);
  compression_fabric_ = fabric_;
  compression_fabric_.bending_modulus = fabric_.bending_modulus * n * n * n;

  auto flag = [&](Index node) { return static_cast<std::size_t>(node) < g.crossings.size() && g.crossings[node].warp_on_top; };
  auto isCrossing = [&](Index node) { return node >= 0 && static_cast<std::size_t>(node) < g.crossings.size(); };
  if (c.shear)
    for (std::size_t k = 0; k < g.crossings.size(); ++k)
      for (int i : {0, 1})
        for (int j : {2, 3}) {
          const Index a = around[k][i], b = around[k][j];
          if (a < 0 || b < 0) continue;
          ShearPair p;
          p.node = {static_cast<Index>(k), a, b};
          const bool warp_changes = isCrossing(a) && flag(a) != flag(static_cast<Index>(k));
          const bool weft_changes = isCrossing(b) && flag(b) != flag(static_cast<Index>(k));
          p.interlaced = warp_changes || weft_changes;
          for (int r = 0; r < 3; ++r)
            for (int s = 0; s < 3; ++s) p.slot[static_cast<std::size_t>(3 * r + s)] = pattern_.find(p.node[r], p.node[s]);
          shear_pairs_.push_back(p);
        }
  angle_anchor_.assign(shear_pairs_.size(), kRightAngle);
  if (c.contact)
    for (const YarnPiece& piece : g.pieces)
      for (std::size_t k = 0; !piece.seam && k + 1 < piece.nodes.size(); ++k) {  // a seam is sewn: no contact
        const Index a = static_cast<Index>(piece.nodes[k]), b = static_cast<Index>(piece.nodes[k + 1]);
        if (!isCrossing(a) || !isCrossing(b)) continue;
        ContactPair p;
        p.node = {a, b};
        const std::size_t off = piece.warp ? 3 : 4;
        p.dof = {kB * static_cast<std::size_t>(a) + off, kB * static_cast<std::size_t>(b) + off};
        p.distance = yarn::parallelContactDistance(R, flag(a) != flag(b));
        p.slot = {pattern_.diagonal(a), pattern_.find(a, b), pattern_.find(b, a), pattern_.diagonal(b)};
        contacts_.push_back(p);
      }
  slide_anchor_ = VecX::Zero(static_cast<Eigen::Index>(sheet_.dofCount()));
  collectSlidingDofs();
}

void YarnWovenModel::collectSlidingDofs() {
  sliding_dofs_.clear();
  for (std::size_t node = 0; node < sheet_.grid.crossings.size(); ++node)
    for (std::size_t off : {3, 4})
      if (!held_[kB * node + off]) sliding_dofs_.push_back({static_cast<Eigen::Index>(kB * node + off), node});
}

void YarnWovenModel::updateCompression(const VecX& q) {
  compression_ = crossingNormalForces(sheet_, compression_fabric_, q);
  for (Real& f : compression_)
    if (!std::isfinite(f)) f = 0;  // a yarn folded back on itself: no friction rather than NaN
}

namespace {

yarn::CrossingVector crossingStencil(const VecX& q, const std::array<Index, 3>& node) {
  return yarn::packCrossingStencil(q.segment<3>(kB * node[0]), q.segment<3>(kB * node[1]), q.segment<3>(kB * node[2]));
}

}  // namespace

Real YarnWovenModel::pairCompression(const ShearPair& p) const {
  return compression_.empty() ? 0 : compression_[static_cast<std::size_t>(p.node[0])];
}

yarn::ShearParameters YarnWovenModel::shearParameters(const ShearPair& p, Real F_n) const {
  return {yarn::shearStiffness(k_x_, c_n_, F_n), spacing_, fabric_.jammingAngle(), options_.crossing.jamming_gain,
          p.interlaced};
}

Real YarnWovenModel::crossingEnergy(const VecX& q) const {
  Real e = 0;
  for (std::size_t k = 0; k < shear_pairs_.size(); ++k) {
    const ShearPair& p = shear_pairs_[k];
    if (p.torn) continue;
    const Real F_n = pairCompression(p);
    const yarn::ShearParameters s = shearParameters(p, F_n);
    const yarn::CrossingVector x = crossingStencil(q, p.node);
    e += yarn::shearEnergy(x, s);
    if (options_.crossing.friction) {  // the stick spring's elastic energy, capped at the Coulomb limit
      const Real limit = mu_phi_ * F_n, d = std::min(std::abs(yarn::crossingAngle(x) - angle_anchor_[k]), limit / k_fphi_);
      e += 0.5 * k_fphi_ * d * d;
    }
  }
  for (const ContactPair& p : contacts_)
    if (!p.torn)
      e += yarn::parallelContactEnergy(q[static_cast<Eigen::Index>(p.dof[0])], q[static_cast<Eigen::Index>(p.dof[1])], k_c_,
                                       spacing_, p.distance);
  if (options_.crossing.friction && !compression_.empty())
    for (const SlidingDof& s : sliding_dofs_) {
      const Real limit = fabric_.sliding_friction * compression_[s.crossing];
      const Real d = std::min(std::abs(q[s.dof] - arc_offset_[s.dof] - slide_anchor_[s.dof]), limit / k_f_);
      e += 0.5 * k_f_ * d * d;
    }
  return e;
}

void YarnWovenModel::addCrossingForces(const VecX& q, const VecX& v, VecX* f, BlockSparseMatrix* dfdx,
                                       BlockSparseMatrix* dfdv, bool clamped, int terms, Real scale) const {
  const bool friction = options_.crossing.friction && (terms & kFrictionTerms);
  const bool conservative = terms & kConservativeTerms, conservative_forces = conservative || (terms & kConservativeForceTerms);
  // Adds factor m into the position blocks of the pair's rows that `rows` owns.
  auto addPositions = [&](const ShearPair& p, const yarn::CrossingMatrix& m, Real factor, const RowShare& rows) {
    for (int a = 0; a < 3; ++a) {
      if (!rows.owns(p.node[static_cast<std::size_t>(a)])) continue;
      for (int b = 0; b < 3; ++b) {
        Real* blk = dfdx->block(p.slot[static_cast<std::size_t>(3 * a + b)]);
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) blk[r * kB + c] += factor * m(3 * a + r, 3 * b + c);
      }
    }
  };
  auto addForce = [&](const ShearPair& p, const yarn::CrossingVector& g, Real factor, const RowShare& rows) {
    for (int a = 0; a < 3; ++a) {
      const Index node = p.node[static_cast<std::size_t>(a)];
      if (rows.owns(node)) f->segment<3>(kB * node) += factor * g.segment<3>(3 * a);
    }
  };
  // The kernels of a pair and their sums run on all threads, each adding its rows in pair order (ordered_parallel.h).
  struct PairTerms {
    yarn::CrossingVector gradient;
    yarn::CrossingMatrix hessian;
    yarn::ShearFriction friction;
  };
  const bool with_f = conservative_forces && f, with_dfdx = conservative && dfdx;
  computeInParallelApplyByRowRanges<PairTerms>(
      shearPairSchedule(), conservative_forces || friction ? shear_pairs_.size() : 0, static_cast<Index>(sheet_.nodeCount()),
      [&](std::size_t k, auto&& visit) {
        for (Index node : shear_pairs_[k].node) visit(node);
      },
      [&](std::size_t k, PairTerms& t) {
        const ShearPair& p = shear_pairs_[k];
        if (p.torn) return;
        const Real F_n = pairCompression(p);
        const yarn::ShearParameters s = shearParameters(p, F_n);
        const yarn::CrossingVector x = crossingStencil(q, p.node);
        if (clamped) {  // phi and dphi once for every term (the same values as the separate kernels')
          const yarn::AngleWithGradient a = yarn::crossingAngleWithGradient(x);
          if (with_f) t.gradient = yarn::shearGradient(a, s);
          if (with_dfdx) t.hessian = yarn::shearHessianClamped(a, s);
          if (friction) t.friction = yarn::shearFrictionClamped(a, angle_anchor_[k], k_fphi_, mu_phi_, F_n);
          return;
        }
        if (with_f) t.gradient = yarn::shearGradient(x, s);
        if (with_dfdx) t.hessian = yarn::shearHessian(x, s);
        if (friction) t.friction = yarn::shearFriction(x, angle_anchor_[k], k_fphi_, mu_phi_, F_n, false);
      },
      [&](std::size_t k, const PairTerms& t, const RowShare& rows) {
        const ShearPair& p = shear_pairs_[k];
        if (p.torn) return;
        if (with_f && t.gradient.allFinite()) addForce(p, t.gradient, -1, rows);
        if (with_dfdx && t.hessian.allFinite()) addPositions(p, t.hessian, -scale, rows);
        if (!friction || !t.friction.force.allFinite() || !t.friction.jacobian.allFinite()) return;
        if (f) addForce(p, t.friction.force, 1, rows);
        if (dfdx) addPositions(p, t.friction.jacobian, scale, rows);
      });
  for (std::size_t k = 0; conservative_forces && k < contacts_.size(); ++k) {
    const ContactPair& p = contacts_[k];
    const Real u0 = q[static_cast<Eigen::Index>(p.dof[0])], u1 = q[static_cast<Eigen::Index>(p.dof[1])];
    if (p.torn || u1 - u0 >= p.distance) continue;
    const yarn::ContactVector g = yarn::parallelContactGradient(u0, u1, k_c_, spacing_, p.distance);
    if (f)
      for (int i = 0; i < 2; ++i) (*f)[static_cast<Eigen::Index>(p.dof[static_cast<std::size_t>(i)])] -= g[i];
    if (dfdx && conservative) {
      const yarn::ContactMatrix h = yarn::parallelContactHessian(u0, u1, k_c_, spacing_, p.distance);
      for (int i = 0; i < 2; ++i)
        for (int j = 0; j < 2; ++j) {
          if (held_[p.dof[static_cast<std::size_t>(i)]] || held_[p.dof[static_cast<std::size_t>(j)]]) continue;
          const int r = static_cast<int>(p.dof[static_cast<std::size_t>(i)] % kB), c = static_cast<int>(p.dof[static_cast<std::size_t>(j)] % kB);
          dfdx->block(p.slot[static_cast<std::size_t>(2 * i + j)])[r * kB + c] -= scale * h(i, j);
        }
    }
  }
  if (!friction || compression_.empty()) return;
  // Each sliding DOF writes only its own entries: on all threads with the same results.
  const auto sliding = static_cast<std::ptrdiff_t>(sliding_dofs_.size());
#pragma omp parallel for schedule(static) if (sliding >= kParallelMinStencils)
  for (std::ptrdiff_t k = 0; k < sliding; ++k) {
    const SlidingDof& sd = sliding_dofs_[static_cast<std::size_t>(k)];
    const Eigen::Index d = sd.dof;
    const yarn::StickSlip s = yarn::slidingFriction(q[d] - arc_offset_[d], slide_anchor_[d], k_f_, fabric_.sliding_friction,
                                                    compression_[sd.crossing]);
    if (f) (*f)[d] += s.force + yarn::slidingDamping(v[d], d_f_);
    if (dfdx) diagonalEntry(*dfdx, static_cast<std::size_t>(d)) += scale * s.stiffness;
    if (dfdv) diagonalEntry(*dfdv, static_cast<std::size_t>(d)) -= scale * d_f_;
  }
}

void YarnWovenModel::acceptStep(const VecX& x, VecX& v) {
  const VecX q = kernelCoordinates(x);
  if (options_.crossing.friction && !compression_.empty()) {
    // Each anchor is its own DOF's or pair's: the loops run on all threads with the same results.
    const auto dofs = static_cast<std::ptrdiff_t>(sliding_dofs_.size()), pairs = static_cast<std::ptrdiff_t>(shear_pairs_.size());
#pragma omp parallel for schedule(static) if (dofs >= kParallelMinStencils)
    for (std::ptrdiff_t k = 0; k < dofs; ++k) {
      const SlidingDof& s = sliding_dofs_[static_cast<std::size_t>(k)];
      slide_anchor_[s.dof] =
          yarn::slidingFrictionAnchor(x[s.dof], slide_anchor_[s.dof], k_f_, fabric_.sliding_friction, compression_[s.crossing]);
    }
#pragma omp parallel for schedule(static) if (pairs >= kParallelMinStencils)
    for (std::ptrdiff_t k = 0; k < pairs; ++k) {
      const ShearPair& p = shear_pairs_[static_cast<std::size_t>(k)];
      const Real phi = yarn::crossingAngle(crossingStencil(q, p.node));
      if (!p.torn && std::isfinite(phi))
        angle_anchor_[static_cast<std::size_t>(k)] =
            yarn::shearFrictionAnchor(phi, angle_anchor_[static_cast<std::size_t>(k)], k_fphi_, mu_phi_, pairCompression(p));
    }
  }
  tearOverloadedSegments(q, v);
  updateCompression(q);
  acceptSelfContacts(x);
  damping_stale_ = true;
}

std::vector<Real> YarnWovenModel::internalState() const {
  std::vector<Real> s;
  const std::size_t n = sheet_.nodeCount(), c = sheet_.grid.crossings.size();
  s.reserve(2 * n + angle_anchor_.size() + c + 1);
  for (std::size_t node = 0; node < n; ++node)
    for (std::size_t off : {3, 4}) s.push_back(slide_anchor_[static_cast<Eigen::Index>(kB * node + off)]);
  s.insert(s.end(), angle_anchor_.begin(), angle_anchor_.end());
  if (compression_.empty()) s.insert(s.end(), c, 0.0);
  else s.insert(s.end(), compression_.begin(), compression_.end());
  s.push_back(compression_.empty() ? 0 : 1);
  appendSelfContactState(s);
  if (!tears_.torn.empty()) {  // last: the torn list ends with its count
    s.insert(s.end(), tears_.torn.begin(), tears_.torn.end());
    s.push_back(static_cast<Real>(tears_.torn.size()));
  }
  return s;
}

bool YarnWovenModel::setInternalState(const std::vector<Real>& state) {
  const std::size_t n = sheet_.nodeCount(), c = sheet_.grid.crossings.size();
  const std::size_t base = 2 * n + angle_anchor_.size() + c + 1;  // then the self-contacts, then the torn segments
  std::vector<yarn::PenaltyContact> contacts;
  bool detected = false;
  std::size_t torn_from = base;
  std::vector<std::size_t> torn;
  if (state.size() < base || !readSelfContactState(state, base, &contacts, &detected, &torn_from) ||
      !readTornSegments(state, torn_from, &torn))
    return false;
  for (Real r : state)
    if (!std::isfinite(r)) return false;
  const Real evaluated = state[base - 1];
  if (evaluated != 0 && evaluated != 1) return false;
  std::size_t k = 0;
  for (std::size_t node = 0; node < n; ++node)
    for (std::size_t off : {3, 4}) slide_anchor_[static_cast<Eigen::Index>(kB * node + off)] = state[k++];
  for (Real& a : angle_anchor_) a = state[k++];
  if (evaluated == 1) compression_.assign(state.begin() + static_cast<std::ptrdiff_t>(k), state.begin() + static_cast<std::ptrdiff_t>(k + c));
  else compression_.clear();
  self_contacts_ = std::move(contacts);
  self_contacts_detected_ = detected;
  tears_.torn = std::move(torn);
  applyTornSegments();
  damping_stale_ = true;
  return true;
}

}  // namespace textile_handling
