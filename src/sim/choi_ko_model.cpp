#include "textile_handling/sim/choi_ko_model.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <unordered_map>

#include <Eigen/Geometry>

#include "textile_handling/sim/energy_kernels.h"

namespace textile_handling {

using choi_ko::PairTermResult;

std::string toString(ChoiKoBending b) { return b == ChoiKoBending::kBeam ? "beam" : "plate"; }

ChoiKoBending choiKoBendingFromString(const std::string& s) {
  if (s == "beam") return ChoiKoBending::kBeam;
  if (s == "plate") return ChoiKoBending::kPlate;
  throw SimError("unknown Choi-Ko bending version '" + s + "' (expected beam or plate)");
}

std::string toString(KesSlopeRule r) { return r == KesSlopeRule::kKesStandard ? "kes" : "initial"; }

KesSlopeRule kesSlopeRuleFromString(const std::string& s) {
  if (s == "kes") return KesSlopeRule::kKesStandard;
  if (s == "initial") return KesSlopeRule::kInitial;
  throw SimError("unknown KES slope rule '" + s + "' (expected kes or initial)");
}

namespace {

// KES-FB ranges: bending 0.5 .. 1.5 1/cm, shear 0.5 .. 5 degrees.
constexpr Real kBendLo = 50.0, kBendHi = 150.0;  // [1/m]
constexpr Real kShearLo = 0.5 * kPi / 180.0, kShearHi = 5.0 * kPi / 180.0;  // [rad]

// Plate-version calibration: for a cylindrical bend along warp or weft, the three hinge families of
// the triangulation (unshared-vertex offsets (1,1), (2,-1), (-1,2)) see the normal curvatures
// kappa cos^2(alpha) with cos^2 = 1/2, 4/5, 1/5, so the energy per cell is
// 1/2 B' d^2 kappa^2 (1/4 + 16/25 + 1/25) = 0.93 * 1/2 B' d^2 kappa^2: B' = B / 0.93.
constexpr Real kPlateCalibration = 0.93;

bool positiveFinite(Real v) { return v > 0 && std::isfinite(v); }

// The chord ratio s* = sin(theta*) / theta* of a beam unit (L = 2d, theta* = kappa* L / 2) bent to kappa*.
Real curvatureOnset(Real kappa, Real d) {
  const Real theta = kappa * d;
  // Below kappa* d = 1e-6 the onset 1 - theta^2 / 6 is too close to 1 for the segment's stiffness.
  if (!positiveFinite(kappa) || !(theta < 1) || !(theta >= 1e-6))
    throw SimError("ChoiKoClothModel: buckling_onset_curvature must lie in [1e-6, 1) / spacing = [" + std::to_string(1e-6 / d) +
                   ", " + std::to_string(1 / d) + ") 1/m, got " + std::to_string(kappa));
  return std::sin(theta) / theta;
}

}  // namespace

ChoiKoParameters choiKoParameters(const Material& material, const ChoiKoOptions& o, Real spacing) {
  auto bad = [](const std::string& m) { throw SimError("ChoiKoClothModel: " + m); };
  if (!(o.tensile_stiffness >= 0) || !std::isfinite(o.tensile_stiffness)) bad("tensile_stiffness must be >= 0");
  if (!(o.shear_stiffness >= 0) || !std::isfinite(o.shear_stiffness)) bad("shear_stiffness must be >= 0");
  if (!(o.bending_rigidity_warp >= 0) || !std::isfinite(o.bending_rigidity_warp) ||
      !(o.bending_rigidity_weft >= 0) || !std::isfinite(o.bending_rigidity_weft))
    bad("bending rigidities must be >= 0");
  if (!positiveFinite(o.reference_strain)) bad("reference_strain must be > 0");
  if (!(o.settle_damping >= 0) || !std::isfinite(o.settle_damping)) bad("settle_damping must be finite and >= 0");
  ChoiKoParameters p;
  p.areal_density = material.areal_density;
  p.tensile_stiffness = o.tensile_stiffness > 0
                            ? o.tensile_stiffness
                            : material.tension_stiffness * o.reference_strain * o.reference_strain * o.reference_strain;
  if (o.shear_stiffness > 0) {
    p.shear_stiffness = o.shear_stiffness;
  } else {
    Real g = 0;
    for (int dir = 0; dir < 2; ++dir) {
      g += o.slope_rule == KesSlopeRule::kInitial
               ? material.shearSlopeSI(dir, 0.0)
               : (material.shearForceSI(dir, kShearHi) - material.shearForceSI(dir, kShearLo)) / (kShearHi - kShearLo);
    }
    p.shear_stiffness = 0.5 * g;
  }
  const Real given[2] = {o.bending_rigidity_warp, o.bending_rigidity_weft};
  for (int dir = 0; dir < 2; ++dir) {
    p.bending_rigidity[dir] =
        given[dir] > 0 ? given[dir]
                       : (o.slope_rule == KesSlopeRule::kInitial
                              ? material.bendSlopeSI(dir, 0.0)
                              : (material.bendMomentSI(dir, kBendHi) - material.bendMomentSI(dir, kBendLo)) /
                                    (kBendHi - kBendLo));
  }
  if (!positiveFinite(p.tensile_stiffness)) bad("tensile stiffness must come out > 0");
  if (!(p.shear_stiffness >= 0) || !std::isfinite(p.shear_stiffness)) bad("shear stiffness came out negative");
  if (o.bending && !o.hysteresis.enabled() &&
      !(positiveFinite(p.bending_rigidity[0]) && positiveFinite(p.bending_rigidity[1])))
    bad("bending rigidity must come out > 0 (check the KES bending curves or set bending_rigidity_*)");
  p.diagonal_spring = 2 * p.shear_stiffness;
  p.law = choi_ko::makeBucklingLaw(o.buckling_onset_curvature > 0 ? curvatureOnset(o.buckling_onset_curvature, spacing)
                                                                  : o.buckling_onset);
  return p;
}

ChoiKoClothModel::ChoiKoClothModel(ParticleTopology topology, Material material, ChoiKoOptions options)
    : topo_(std::move(topology)), material_(std::move(material)), options_(std::move(options)) {
  std::string error;
  if (!material_.validate(&error)) throw SimError("ChoiKoClothModel: " + error);
  if (!options_.hysteresis.valid(&error)) throw SimError("ChoiKoClothModel: " + error);
  const Real d = topo_.spacing;
  if (!positiveFinite(d)) throw SimError("ChoiKoClothModel: bad spacing");
  const Index n = topo_.size();
  if (n < 1) throw SimError("ChoiKoClothModel: no particles");
  params_ = choiKoParameters(material_, options_, d);
  const bool hyst = options_.hysteresis.enabled();

  mass_.resize(3 * n);
  drag_coeff_.resize(n);
  for (Index r = 0; r < n; ++r) {
    mass_.segment<3>(3 * r).setConstant(material_.areal_density * topo_.area[r]);
    drag_coeff_[r] = 0.5 * material_.fluid_density * material_.drag_coefficient * topo_.area[r];
  }

  const auto& nb = topo_.neighbour;
  auto nbr = [&](Index a, int dir) { return a < 0 ? Index(-1) : nb[a][dir]; };
  // Width share (in units of d) as in the particle model: half a cell row per existing side, half a
  // row on a one-particle-wide strip.
  auto share = [](int sides) { return sides > 0 ? 0.5 * sides : 0.5; };
  auto cellExists = [&](Index a, int along, int side) {
    const Index b = nbr(a, along), c = nbr(a, side);
    return b >= 0 && c >= 0 && nbr(b, side) >= 0;
  };

  // ---- type 1: tension-only springs ----
  const Real et = params_.tensile_stiffness;
  for (Index r = 0; r < n; ++r) {
    if (options_.stretch) {
      if (nb[r][0] >= 0)
        springs_.push_back({r, nb[r][0], d, et * share(cellExists(r, 0, 1) + cellExists(r, 0, 3)), SpringKind::kWarp});
      if (nb[r][1] >= 0)
        springs_.push_back({r, nb[r][1], d, et * share(cellExists(r, 1, 0) + cellExists(r, 1, 2)), SpringKind::kWeft});
    }
    if (options_.shear && params_.diagonal_spring > 0) {
      const Index right = nb[r][0], up = nb[r][1], ru = nbr(right, 1);
      if (right >= 0 && up >= 0 && ru >= 0 && ru == nbr(up, 0)) {
        springs_.push_back({r, ru, std::sqrt(2.0) * d, params_.diagonal_spring, SpringKind::kShear});
        springs_.push_back({right, up, std::sqrt(2.0) * d, params_.diagonal_spring, SpringKind::kShear});
      }
    }
  }

  // ---- type 2: bending units ----
  const Real b_ref = options_.hysteresis.initialSlope();
  auto gridVec = [&](Index a) { return Vec2(topo_.grid[a][1], topo_.grid[a][0]); };  // (column, row)
  auto addUnit = [&](Index i, Index j, Real rest, Real weight, Real rigidity, int dir) {
    const Real b = hyst ? b_ref : rigidity;
    bends_.push_back({i, j, rest, weight, b, weight * b / (rest * rest * rest), dir});
  };
  if (options_.bending) {
    if (options_.bending_version == ChoiKoBending::kBeam) {
      for (Index m = 0; m < n; ++m) {
        const Index right = nb[m][0], up = nb[m][1], left = nb[m][2], down = nb[m][3];
        if (left >= 0 && right >= 0)  // warp beam, width = the particle's extent in y
          addUnit(left, right, 2 * d, share((up >= 0) + (down >= 0)) * d * d, params_.bending_rigidity[0], 0);
        if (down >= 0 && up >= 0)  // weft beam, width = the particle's extent in x
          addUnit(down, up, 2 * d, share((right >= 0) + (left >= 0)) * d * d, params_.bending_rigidity[1], 1);
      }
    } else {
      // Triangulation of collision.h: p owns (p, right, up) and (p, left, down) when they exist.
      std::unordered_map<std::int64_t, std::vector<Index>> opposite;  // edge -> opposite vertices
      auto key = [&](Index a, Index b) {
        return static_cast<std::int64_t>(std::min(a, b)) * static_cast<std::int64_t>(n) + std::max(a, b);
      };
      std::vector<std::int64_t> edge_order;
      auto addTri = [&](Index a, Index b, Index c) {
        const Index v[3] = {a, b, c};
        for (int e = 0; e < 3; ++e) {
          const auto k = key(v[e], v[(e + 1) % 3]);
          auto it = opposite.find(k);
          if (it == opposite.end()) {
            opposite.emplace(k, std::vector<Index>{v[(e + 2) % 3]});
            edge_order.push_back(k);
          } else {
            it->second.push_back(v[(e + 2) % 3]);
          }
        }
      };
      for (Index p = 0; p < n; ++p) {
        if (nb[p][0] >= 0 && nb[p][1] >= 0) addTri(p, nb[p][0], nb[p][1]);
        if (nb[p][2] >= 0 && nb[p][3] >= 0) addTri(p, nb[p][2], nb[p][3]);
      }
      const Real weight = d * d / kPlateCalibration;  // (A_i + A_j) = d^2 at rest
      const Real rigidity = 0.5 * (params_.bending_rigidity[0] + params_.bending_rigidity[1]);
      for (const auto k : edge_order) {  // first-seen order: deterministic
        const auto& opp = opposite[k];
        if (opp.size() != 2) continue;
        const Index i = std::min(opp[0], opp[1]), j = std::max(opp[0], opp[1]);
        addUnit(i, j, (gridVec(j) - gridVec(i)).norm() * d, weight, rigidity, 2);
      }
    }
  }

  // ---- pattern and incidence ----
  std::vector<std::pair<Index, Index>> couplings;
  for (const auto& s : springs_) couplings.emplace_back(s.i, s.j);
  for (const auto& b : bends_) couplings.emplace_back(b.i, b.j);
  pattern_ = BlockPattern(n, 3, couplings);
  const Index terms = static_cast<Index>(couplings.size());
  inc_start_.assign(n + 1, 0);
  for (const auto& c : couplings) {
    ++inc_start_[c.first + 1];
    ++inc_start_[c.second + 1];
  }
  for (Index r = 0; r < n; ++r) inc_start_[r + 1] += inc_start_[r];
  inc_.resize(inc_start_[n]);
  std::vector<Index> fill(inc_start_.begin(), inc_start_.end() - 1);
  for (Index t = 0; t < terms; ++t) {
    const Index i = couplings[t].first, j = couplings[t].second;
    inc_[fill[i]++] = {t, j, pattern_.find(i, j), 1.0};
    inc_[fill[j]++] = {t, i, pattern_.find(j, i), -1.0};
  }
  term_.resize(terms);
  term_ok_.assign(terms, 1);

  if (hyst) {
    sign_.assign(bends_.size(), 1.0);
    hyst_.assign(bends_.size(), choi_ko::HysteresisState::initial(options_.hysteresis));
  }
}

bool ChoiKoClothModel::vertexNormal(Index p, const VecX& x, Vec3* n) const {
  const auto& nb = topo_.neighbour[p];
  const Vec3 t1 = node3(x, nb[0] >= 0 ? nb[0] : p) - node3(x, nb[2] >= 0 ? nb[2] : p);
  const Vec3 t2 = node3(x, nb[1] >= 0 ? nb[1] : p) - node3(x, nb[3] >= 0 ? nb[3] : p);
  const Vec3 c = t1.cross(t2);
  const Real len = c.norm();
  if (!(len > 0) || !std::isfinite(len)) return false;
  *n = c / len;
  return true;
}

Real ChoiKoClothModel::trialSign(Index k, const VecX& x, Real theta) const {
  // The cloth normal (warp x weft) turns along the chord of a bent unit: on an arc of half angle
  // theta it turns by 2 theta, and (n_j - n_i) . (x_j - x_i) = -2 sin(theta) r for a valley (middle
  // on the -n side: negative curvature), +2 sin(theta) r for a ridge. The geometric sign is taken
  // where it is at least a quarter of that (one-sided normals at the border see about half the
  // turn); otherwise (in-plane compression, where the distance-based curvature has no geometric
  // counterpart) the committed sign is kept.
  const BendingUnit& b = bends_[k];
  const Real committed = sign_[k];
  if (!(theta > 0)) return committed;
  Vec3 ni, nj;
  if (!vertexNormal(b.i, x, &ni) || !vertexNormal(b.j, x, &nj)) return committed;
  const Vec3 chord = node3(x, b.j) - node3(x, b.i);
  const Real q = (nj - ni).dot(chord);
  if (std::abs(q) >= 0.5 * std::sin(std::min(theta, 0.5 * kPi)) * chord.norm()) return q > 0 ? 1.0 : -1.0;
  return committed;
}

Real ChoiKoClothModel::signedCurvature(Index k, const VecX& x) const {
  const BendingUnit& b = bends_[k];
  const Real r = (node3(x, b.j) - node3(x, b.i)).norm();
  if (!(r < b.rest)) return 0;
  const Real theta = choi_ko::halfAngleFromChordDeficit((b.rest - r) / b.rest);
  const Real s = sign_.empty() ? 1.0 : trialSign(k, x, theta);
  return s * 2 * theta / b.rest;
}

bool ChoiKoClothModel::evalBending(Index k, const VecX& x, bool want_jac, PairTermResult* out) const {
  const BendingUnit& b = bends_[k];
  const choi_ko::BendingJacobian mode = options_.bending_jacobian;
  if (!options_.hysteresis.enabled())
    return choi_ko::bucklingUnit(node3(x, b.i), node3(x, b.j), b.rest, b.f0, params_.law, want_jac, mode, out);
  const Vec3 dx = node3(x, b.j) - node3(x, b.i);
  const Real r = dx.norm();
  if (!std::isfinite(r) || !(r > 0)) return false;
  PairTermResult o;
  o.r = r;
  o.unit = dx / r;
  if (r < b.rest) {
    o.active = true;
    const Real u = (b.rest - r) / b.rest;
    const choi_ko::BucklingShape shape = choi_ko::bucklingShape(u);
    const Real sign = trialSign(k, x, shape.theta);
    const Real curvature = sign * 2 * shape.theta / b.rest;
    Real tangent = 0;
    const Real moment = choi_ko::hysteresisMoment(options_.hysteresis, hyst_[k], curvature, &tangent);
    const auto h = choi_ko::hystereticBending(shape, u, sign, moment, tangent, b.rest, b.rigidity, params_.law);
    o.f = b.f0 * h.f;
    if (want_jac) o.jac = choi_ko::bendingJacobianBlock(o.unit, r, b.rest, b.f0, o.f, h.df, u, mode);
  }
  *out = o;
  return true;
}

ForceReport ChoiKoClothModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const Index n = numNodes();
  f.setZero(3 * n);
  BlockSparseMatrix* K = nullptr;
  if (jac) {
    jac->dfdx.setZero();
    jac->dfdv.setZero();
    K = &jac->dfdx;
  }
  const bool want = jac != nullptr;
  const Index ns = static_cast<Index>(springs_.size());
  const Index terms = static_cast<Index>(term_.size());
  // Phase 1: every term on its own (writes only its own slot).
#pragma omp parallel for schedule(static)
  for (Index t = 0; t < terms; ++t) {
    bool ok;
    if (t < ns) {
      const Spring& s = springs_[t];
      ok = choi_ko::tensionOnlySpring(node3(x, s.i), node3(x, s.j), s.rest, s.k, want, &term_[t]);
    } else {
      ok = evalBending(t - ns, x, want, &term_[t]);
    }
    term_ok_[t] = ok;
    if (ok && !std::isfinite(term_[t].f)) term_ok_[t] = 0;
  }
  Index degenerate = 0;
  for (Index t = 0; t < terms; ++t) degenerate += term_ok_[t] ? 0 : 1;
  // Phase 2: gather per node in a fixed order (one thread per row: no races, thread-count independent).
#pragma omp parallel for schedule(static)
  for (Index r = 0; r < n; ++r) {
    Vec3 acc = Vec3::Zero();
    Mat3 diag = Mat3::Zero();
    for (Index e = inc_start_[r]; e < inc_start_[r + 1]; ++e) {
      const Incidence& in = inc_[e];
      const PairTermResult& res = term_[in.term];
      if (!term_ok_[in.term] || !res.active) continue;
      acc += in.side * res.f * res.unit;
      if (K) {
        diag -= res.jac;
        K->add3(in.slot_other, res.jac);
      }
    }
    if (K) K->add3(pattern_.diagonal(r), diag);
    if (options_.gravity) acc.z() -= mass_[3 * r] * kGravity;
    if (options_.drag && drag_coeff_[r] > 0) {
      DragDerivatives dd;
      dragTerm(node3(v, r), drag_coeff_[r], want, &dd);
      acc += dd.force;
      if (jac) jac->dfdv.add3(pattern_.diagonal(r), dd.dforce_dv);
    }
    if (options_.settle_damping > 0) {
      const Real c = options_.settle_damping * mass_[3 * r];
      acc -= c * node3(v, r);
      if (jac) jac->dfdv.add3(pattern_.diagonal(r), -c * Mat3::Identity());
    }
    node3(f, r) = acc;
  }
  return ForceReport{degenerate};
}

Real ChoiKoClothModel::unitEnergy(const BendingUnit& b, const VecX& x) const {
  PairTermResult res;
  if (!choi_ko::bucklingUnit(node3(x, b.i), node3(x, b.j), b.rest, b.f0, params_.law, false,
                             choi_ko::BendingJacobian::kDropNegative, &res))
    return 0;
  return res.energy;
}

Real ChoiKoClothModel::potentialEnergy(const VecX& x) const {
  Real e = 0;
  for (const Spring& s : springs_) {
    PairTermResult res;
    if (choi_ko::tensionOnlySpring(node3(x, s.i), node3(x, s.j), s.rest, s.k, false, &res)) e += res.energy;
  }
  for (const BendingUnit& b : bends_) e += unitEnergy(b, x);
  if (options_.gravity)
    for (Index r = 0; r < numNodes(); ++r) e += mass_[3 * r] * kGravity * x[3 * r + 2];
  return e;
}

Real ChoiKoClothModel::maxEdgeStretch(const VecX& x) const {
  Real worst = 0;
  for (Index r = 0; r < numNodes(); ++r) {
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

void ChoiKoClothModel::acceptStep(const VecX& x, VecX& /*v*/) {
  if (!options_.hysteresis.enabled()) return;
  const Index nb = static_cast<Index>(bends_.size());
#pragma omp parallel for schedule(static)
  for (Index k = 0; k < nb; ++k) {
    const BendingUnit& b = bends_[k];
    const Real r = (node3(x, b.j) - node3(x, b.i)).norm();
    if (!std::isfinite(r)) continue;  // a diverged state is not committed
    Real theta = 0;
    if (r < b.rest) theta = choi_ko::halfAngleFromChordDeficit((b.rest - r) / b.rest);
    const Real s = trialSign(k, x, theta);
    choi_ko::hysteresisCommit(options_.hysteresis, hyst_[k], s * 2 * theta / b.rest);
    sign_[k] = s;
  }
}

// Layout: [1 (version), kind (1 discrete, 2 continuous), units, then per unit: sign, X, count,
// data...] with data = the count slip offsets (discrete) or count reversal points as X, M pairs.
std::vector<Real> ChoiKoClothModel::internalState() const {
  if (!options_.hysteresis.enabled()) return {};
  const bool discrete = options_.hysteresis.kind == choi_ko::HysteresisSpec::Kind::kDiscrete;
  std::vector<Real> s{1.0, discrete ? 1.0 : 2.0, static_cast<Real>(bends_.size())};
  for (size_t k = 0; k < bends_.size(); ++k) {
    const auto& h = hyst_[k];
    s.push_back(sign_[k]);
    s.push_back(h.x);
    if (discrete) {
      s.push_back(static_cast<Real>(h.slip.size()));
      s.insert(s.end(), h.slip.begin(), h.slip.end());
    } else {
      s.push_back(static_cast<Real>(h.reversals.size()));
      for (const auto& p : h.reversals) {
        s.push_back(p[0]);
        s.push_back(p[1]);
      }
    }
  }
  return s;
}

bool ChoiKoClothModel::setInternalState(const std::vector<Real>& state) {
  if (!options_.hysteresis.enabled()) return state.empty();
  const bool discrete = options_.hysteresis.kind == choi_ko::HysteresisSpec::Kind::kDiscrete;
  for (Real v : state)
    if (!std::isfinite(v)) return false;
  if (state.size() < 3 || state[0] != 1.0 || state[1] != (discrete ? 1.0 : 2.0) ||
      state[2] != static_cast<Real>(bends_.size()))
    return false;
  std::vector<Real> signs(bends_.size());
  std::vector<choi_ko::HysteresisState> hs(bends_.size());
  size_t p = 3;
  const size_t nslip = options_.hysteresis.slip_moment.size();
  for (size_t k = 0; k < bends_.size(); ++k) {
    if (p + 3 > state.size()) return false;
    const Real sg = state[p], xk = state[p + 1], count = state[p + 2];
    p += 3;
    if (sg != 1.0 && sg != -1.0) return false;
    if (!(count >= 0) || count != std::floor(count)) return false;
    const size_t c = static_cast<size_t>(count);
    if (discrete ? c != nslip : c > static_cast<size_t>(choi_ko::HysteresisState::kMaxReversals)) return false;
    const size_t need = discrete ? c : 2 * c;
    if (p + need > state.size()) return false;
    signs[k] = sg;
    hs[k].x = xk;
    if (discrete) {
      hs[k].slip.assign(state.begin() + static_cast<std::ptrdiff_t>(p), state.begin() + static_cast<std::ptrdiff_t>(p + c));
    } else {
      for (size_t q = 0; q < c; ++q) hs[k].reversals.push_back({state[p + 2 * q], state[p + 2 * q + 1]});
    }
    p += need;
  }
  if (p != state.size()) return false;
  sign_ = std::move(signs);
  hyst_ = std::move(hs);
  return true;
}

}  // namespace textile_handling
