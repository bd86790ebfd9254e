#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "textile_handling/sim/textile_geometry.h"
#include "parallel_size.h"

namespace textile_handling {

ParticleClothModel::ParticleClothModel(ParticleTopology topology, Material material,
                                       ParticleModelOptions options)
    : topo_(std::move(topology)), material_(std::move(material)), options_(options) {
  std::string error;
  if (!material_.validate(&error)) throw SimError("ParticleClothModel: " + error);
  const Real d = topo_.spacing;
  if (!(d > 0) || !std::isfinite(d)) throw SimError("ParticleClothModel: bad spacing");
  if (!(options_.settle_damping >= 0) || !std::isfinite(options_.settle_damping))
    throw SimError("ParticleClothModel: settle_damping must be finite and >= 0");
  const Index n = topo_.size();
  if (n < 1) throw SimError("ParticleClothModel: no particles");
  c0_ = d * d * material_.tension_stiffness / 5.0;
  mass_.resize(3 * n);
  drag_coeff_.resize(n);
  for (Index r = 0; r < n; ++r) {
    const Real m = material_.areal_density * topo_.area[r];
    mass_.segment<3>(3 * r).setConstant(m);
    drag_coeff_[r] = 0.5 * material_.fluid_density * material_.drag_coefficient * topo_.area[r];
  }

  // Couplings: centre-neighbour (tension, all angles), neighbour j - neighbour j+1 (shear),
  // neighbour j - neighbour j+2 (bending).
  std::vector<std::pair<Index, Index>> couplings;
  for (Index r = 0; r < n; ++r) {
    const auto& nb = topo_.neighbour[r];
    for (int j = 0; j < 4; ++j) {
      if (nb[j] < 0) continue;
      couplings.emplace_back(r, nb[j]);
      if (nb[(j + 1) % 4] >= 0) couplings.emplace_back(nb[j], nb[(j + 1) % 4]);
      if (j < 2 && nb[j + 2] >= 0) couplings.emplace_back(nb[j], nb[j + 2]);
    }
  }
  pattern_ = BlockPattern(n, 3, couplings);

  stencils_.resize(n);
  colour_.assign(5, {});
  for (Index r = 0; r < n; ++r) {
    Stencil& st = stencils_[r];
    st.node[0] = r;
    for (int j = 0; j < 4; ++j) st.node[j + 1] = topo_.neighbour[r][j];
    for (int a = 0; a < 5; ++a)
      for (int b = 0; b < 5; ++b)
        st.slot[a][b] = (st.node[a] >= 0 && st.node[b] >= 0) ? pattern_.find(st.node[a], st.node[b]) : -1;
    // Width shares: an edge or hinge represents half a cell row on each side where that side's cell
    // exists; on a one-particle-wide strip it represents half a row (matching the strip's mass).
    const auto& nb = topo_.neighbour[r];
    auto cellExists = [&](Index a, int along, int side) {  // cell spanned by a, a+along, a+side
      const Index b = topo_.neighbour[a][along], c = topo_.neighbour[a][side];
      return b >= 0 && c >= 0 && topo_.neighbour[b][side] >= 0;
    };
    auto share = [](int cells) { return cells > 0 ? 0.5 * cells : 0.5; };
    // Edge to the right: cells above (up) and below (down); edge up: cells right and left.
    st.edge_width[0] = nb[0] < 0 ? 0 : share(cellExists(r, 0, 1) + cellExists(r, 0, 3));
    st.edge_width[1] = nb[1] < 0 ? 0 : share(cellExists(r, 1, 0) + cellExists(r, 1, 2));
    // Left-right hinge: the particle's extent in y; up-down hinge: its extent in x.
    st.bend_width[0] = share((nb[1] >= 0) + (nb[3] >= 0));
    st.bend_width[1] = share((nb[0] >= 0) + (nb[2] >= 0));
    // Plus-shaped stencils centred on (i + 2j) mod 5 == c tile the plane without overlap, so the
    // stencils of one colour write disjoint rows and can run in parallel deterministically.
    const int c = ((topo_.grid[r][0] + 2 * topo_.grid[r][1]) % 5 + 5) % 5;
    colour_[c].push_back(r);
  }
}

Real ParticleClothModel::shearEnergy(Real theta) const {
  const Real w = 0.25 * topo_.spacing * topo_.spacing;
  const Real t = std::abs(theta);
  return w * 0.5 * (material_.shearEnergyDensitySI(0, t) + material_.shearEnergyDensitySI(1, t));
}

Real ParticleClothModel::bendEnergy(int dir, Real theta) const {
  const Real d = topo_.spacing;
  return d * d * material_.bendEnergyDensitySI(dir, std::abs(theta) / d);
}

AngleProfile ParticleClothModel::shearProfile(Real theta) const {
  // Mean of warp and weft KES shear curves; weight d^2/4 per corner angle (decisions 3, 5).
  const Real w = 0.25 * topo_.spacing * topo_.spacing;
  const Real t = std::abs(theta);
  const Real sign = theta < 0 ? -1.0 : 1.0;
  const Real F = 0.5 * (material_.shearForceSI(0, t) + material_.shearForceSI(1, t));
  const Real dF = 0.5 * (material_.shearSlopeSI(0, t) + material_.shearSlopeSI(1, t));
  AngleProfile p;
  p.energy = shearEnergy(theta);
  p.dE = w * sign * F;
  p.d2E = w * dF;
  p.secant = t > 0 ? w * F / t : p.d2E;
  return p;
}

AngleProfile ParticleClothModel::bendProfile(int dir, Real theta) const {
  // kappa = theta / d; E = d^2 * integral_0^kappa M; dE/dtheta = d M(kappa); d2E = M'(kappa).
  const Real d = topo_.spacing;
  const Real t = std::abs(theta);
  const Real kappa = t / d;
  AngleProfile p;
  p.energy = bendEnergy(dir, theta);
  const Real M = material_.bendMomentSI(dir, kappa);
  p.dE = d * M;
  p.d2E = material_.bendSlopeSI(dir, kappa);
  p.secant = t > 0 ? d * M / t : p.d2E;
  return p;
}

namespace {
// The angle a term acts on: the shear angle's deviation from a right angle, or the bending angle
// (the deviation of the hinge from straight).
Real termAngle(const AngleGeometry& geo, AngleKind kind) {
  return kind == AngleKind::kShear ? geo.phi - kPi / 2 : kPi - geo.phi;
}
}  // namespace

template <class F>
void ParticleClothModel::forEachAngle(const Stencil& st, F&& f) const {
  // The stencil's angle terms in a fixed order: the four shear angles between consecutive arms,
  // then the two bending hinges (left-right, up-down).
  if (options_.shear) {
    for (int j = 1; j <= 4; ++j) {
      const int k = j % 4 + 1;
      if (st.node[j] >= 0 && st.node[k] >= 0) f(j, k, AngleKind::kShear, 0);
    }
  }
  if (options_.bending) {
    for (int j = 1; j <= 2; ++j) {
      if (st.node[j] >= 0 && st.node[j + 2] >= 0) f(j, j + 2, AngleKind::kBending, j - 1);
    }
  }
}

Index ParticleClothModel::addStencil(const Stencil& st, const VecX& x, VecX& f, BlockSparseMatrix* K,
                                     Real* energy) const {
  const bool hess = K != nullptr;
  const bool fix = options_.jacobian == JacobianMode::kDefiniteFix;
  Index degenerate = 0;
  const Index c = st.node[0];
  const Vec3 p0 = node3(x, c);

  // Tension: edges to the right and up neighbours, so every edge is visited once.
  for (int j = 1; j <= 2; ++j) {
    const Index q = st.node[j];
    if (q < 0) continue;
    TensionDerivatives t;
    if (!tensionTerm(p0, node3(x, q), topo_.spacing, c0_ * st.edge_width[j - 1], hess, fix, &t)) {
      ++degenerate;
      continue;
    }
    if (energy) *energy += t.energy;
    node3(f, c) -= t.grad0;
    node3(f, q) += t.grad0;
    if (hess) {
      K->add3(st.slot[0][0], -t.hess00);
      K->add3(st.slot[j][j], -t.hess00);
      K->add3(st.slot[0][j], t.hess00);
      K->add3(st.slot[j][0], t.hess00);
    }
  }

  auto addAngle = [&](int a, int b, AngleKind kind, int dir) {
    const Index qa = st.node[a], qb = st.node[b];
    AngleGeometry geo;
    if (!angleGeometry(p0, node3(x, qa), node3(x, qb), &geo)) {
      ++degenerate;
      return;
    }
    const Real theta = termAngle(geo, kind);
    AngleProfile prof = kind == AngleKind::kShear ? shearProfile(theta) : bendProfile(dir, theta);
    if (kind == AngleKind::kBending) {
      const Real w = st.bend_width[dir];
      prof.energy *= w;
      prof.dE *= w;
      prof.d2E *= w;
      prof.secant *= w;
    }
    AngleDerivatives ad;
    angleTermDerivatives(geo, kind, prof, hess, fix, &ad);
    if (!std::isfinite(ad.grad[0].squaredNorm())) {
      ++degenerate;
      return;
    }
    if (energy) *energy += ad.energy;
    const int idx[3] = {0, a, b};
    for (int u = 0; u < 3; ++u) node3(f, st.node[idx[u]]) -= ad.grad[u];
    if (hess)
      for (int u = 0; u < 3; ++u)
        for (int w = 0; w < 3; ++w) K->add3(st.slot[idx[u]][idx[w]], -ad.hess[u][w]);
  };

  forEachAngle(st, addAngle);
  return degenerate;
}

ForceReport ParticleClothModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const Index n = numNodes();
  f.setZero(3 * n);
  BlockSparseMatrix* K = nullptr;
  if (jac) {
    jac->dfdx.setZero();
    jac->dfdv.setZero();
    K = &jac->dfdx;
  }
  Index degenerate = 0;
  const bool parallel = n >= kParallelMinStencils;  // one stencil per particle
  for (const auto& group : colour_) {
    const Index m = static_cast<Index>(group.size());
#pragma omp parallel for schedule(static) reduction(+ : degenerate) if (parallel)
    for (Index k = 0; k < m; ++k) degenerate += addStencil(stencils_[group[k]], x, f, K, nullptr);
  }
  // Per-particle external forces: gravity (-z) and drag.
#pragma omp parallel for schedule(static) if (parallel)
  for (Index r = 0; r < n; ++r) {
    if (options_.gravity) f[3 * r + 2] -= mass_[3 * r] * kGravity;
    if (options_.drag && drag_coeff_[r] > 0) {
      DragDerivatives dd;
      dragTerm(node3(v, r), drag_coeff_[r], jac != nullptr, &dd);
      node3(f, r) += dd.force;
      if (jac) jac->dfdv.add3(pattern_.diagonal(r), dd.dforce_dv);
    }
    if (options_.settle_damping > 0) {
      const Real c = options_.settle_damping * mass_[3 * r];
      node3(f, r) -= c * node3(v, r);
      if (jac) jac->dfdv.add3(pattern_.diagonal(r), -c * Mat3::Identity());
    }
  }
  return ForceReport{degenerate};
}

Real ParticleClothModel::stencilEnergy(const Stencil& st, const VecX& x) const {
  // The energy terms of addStencil in the same order, without their derivatives; a term whose
  // geometry is degenerate (or whose energy is not finite) is left out, as there.
  const Index c = st.node[0];
  const Vec3 p0 = node3(x, c);
  Real e = 0;
  for (int j = 1; j <= 2; ++j) {
    const Index q = st.node[j];
    if (q < 0) continue;
    TensionDerivatives t;
    if (!tensionTerm(p0, node3(x, q), topo_.spacing, c0_ * st.edge_width[j - 1], false, false, &t)) continue;
    e += t.energy;
  }
  auto angle = [&](int a, int b, AngleKind kind, int dir) {
    AngleGeometry geo;
    if (!angleGeometry(p0, node3(x, st.node[a]), node3(x, st.node[b]), &geo)) return;
    const Real theta = termAngle(geo, kind);
    Real en = kind == AngleKind::kShear ? shearEnergy(theta) : bendEnergy(dir, theta);
    if (kind == AngleKind::kBending) en *= st.bend_width[dir];
    if (std::isfinite(en)) e += en;
  };
  forEachAngle(st, angle);
  return e;
}

Real ParticleClothModel::potentialEnergy(const VecX& x) const {
  // Energies only (stencilEnergy), in parallel; summed in particle order, so the result does not
  // depend on the thread count. The simulation evaluates it after every step with a collision
  // rollback, to re-base its energy check.
  const Index n = numNodes();
  std::vector<Real> per(static_cast<size_t>(n), 0.0);
#pragma omp parallel for schedule(static) if (n >= kParallelMinStencils)
  for (Index r = 0; r < n; ++r) per[static_cast<size_t>(r)] = stencilEnergy(stencils_[static_cast<size_t>(r)], x);
  Real e = 0;
  for (Index r = 0; r < n; ++r) {
    Real p = per[static_cast<size_t>(r)];
    if (options_.gravity) p += mass_[3 * r] * kGravity * x[3 * r + 2];
    e += p;
  }
  return e;
}

Real ParticleClothModel::maxEdgeStretch(const VecX& x) const {
  Real worst = 0;
  const Index n = numNodes();
  for (Index r = 0; r < n; ++r) {
    for (int j = 0; j < 2; ++j) {
      const Index q = topo_.neighbour[r][j];
      if (q < 0) continue;
      const Real len = (node3(x, r) - node3(x, q)).norm();
      if (!std::isfinite(len)) return std::numeric_limits<Real>::infinity();
      worst = std::max(worst, len / topo_.spacing);
    }
  }
  return worst;
}

}  // namespace textile_handling
