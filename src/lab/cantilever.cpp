// ASTM D1388 cantilever bending length on any cloth model, and the bending length a material's curve
// implies (material_lab.h, docs/material_lab.md).
#include <algorithm>
#include <cmath>
#include <string>

#include "lab_specimen.h"
#include "textile_handling/lab/lab_material.h"
#include "textile_handling/sim/drape_simulation.h"

namespace textile_handling {
namespace lab {
namespace {

constexpr Real kDeg = kPi / 180;
// Columns of the clamp on the platform: the edge column and two behind it, so the edge holds the slope.
constexpr int kClampColumns = 2;

// Angle below the horizontal [deg] of the line from the platform edge to the tip of a strip whose
// overhang is `cells` grid cells, at static equilibrium. The static solve starts from the flat strip;
// if it fails (a model whose energy landscape the solver cannot descend from there, such as Choi-Ko's
// buckling units), a dynamic settle from the flat strip comes first and the static solve finishes it.
CantileverPoint solveOverhang(const LabSample& sample, YarnDirection direction, int cells, int cells_b,
                              const CantileverProtocol& protocol) {
  const Real d = sample.spacing;
  Specimen s = makeSpecimen(settlingSample(sample), direction, -kClampColumns * d, cells + kClampColumns, cells_b);
  ClothModel& model = *s.model;
  PinnedNodes pins;
  const Index n = model.numNodes();
  std::vector<Index> tip;
  for (Index i = 0; i < n; ++i) {
    if (s.a[i] <= 0.5 * d * 1e-6) {
      pins.nodes.push_back(i);
      pins.anchors.push_back(model.nodePosition(s.x_rest, i));
    }
    if (s.a[i] >= s.a_max - 1e-6 * d) tip.push_back(i);
  }
  CantileverPoint p;
  p.overhang_m = cells * d;
  VecX x = s.x_rest;
  StaticEquilibriumResult r = solveStaticEquilibrium(model, pins, 0, x, protocol.statics);
  p.iterations = r.iterations;
  if (!r.converged) {
    SimulationSettings settings;
    settings.max_time = protocol.settle_time_s;
    settings.dt_max = 5e-3;
    settings.error_tolerance = 1e-4;
    settings.rest_speed = 1e-4;
    settings.rest_mean_speed = 2e-5;
    DrapeSimulation sim(model, pins, settings, s.x_rest, VecX::Zero(model.numDofs()));
    const RunResult run = sim.run();
    if (run.diverged)
      throw MaterialLabError("cantilever: the dynamic settle of the " + std::to_string(p.overhang_m) + " m overhang (" +
                             toString(direction) + ") diverged: " + run.divergence_reason);
    x = sim.state();
    r = solveStaticEquilibrium(model, pins, 0, x, protocol.statics);
    p.iterations += r.iterations;
    p.settled_dynamically = true;
    if (!r.converged)
      throw MaterialLabError("cantilever: the static solve of the " + std::to_string(p.overhang_m) + " m overhang (" +
                             toString(direction) + ") did not converge, also after a dynamic settle: " + r.failure);
  }
  Vec3 t = Vec3::Zero();
  for (const Index i : tip) t += model.nodePosition(x, i);
  t /= static_cast<Real>(tip.size());
  const Real along = direction == YarnDirection::kWarp ? t.x() : t.y();
  p.angle_deg = std::atan2(-t.z(), along) / kDeg;
  return p;
}

// The elastica of a clamped strip of overhang l: integrates from the free tip (moment 0, tangent angle
// psi_tip below the horizontal) to the clamp; returns the tangent angle there and the tip's chord angle.
struct ElasticaShot {
  Real clamp_angle;
  Real chord_angle;
};

class Elastica {
 public:
  Elastica(const Material& material, YarnDirection direction, Real weight_per_area)
      : material_(material), dir_(static_cast<int>(direction)), w_(weight_per_area) {}

  ElasticaShot shoot(Real length, Real psi_tip) {
    const int steps = 1000;
    const Real h = length / steps;
    Real psi = psi_tip, m = 0, x = 0, z = 0, s = 0;
    // State (psi, m, x, z); d psi/ds = -kappa(m), dm/ds = w s cos psi, dx/ds = cos psi, dz/ds = sin psi.
    auto rate = [&](Real ss, Real p, Real mm, Real out[4]) {
      out[0] = -curvature(mm);
      out[1] = w_ * ss * std::cos(p);
      out[2] = std::cos(p);
      out[3] = std::sin(p);
    };
    for (int k = 0; k < steps; ++k) {
      Real k1[4], k2[4], k3[4], k4[4];
      rate(s, psi, m, k1);
      rate(s + h / 2, psi + h / 2 * k1[0], m + h / 2 * k1[1], k2);
      rate(s + h / 2, psi + h / 2 * k2[0], m + h / 2 * k2[1], k3);
      rate(s + h, psi + h * k3[0], m + h * k3[1], k4);
      psi += h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0]);
      m += h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1]);
      x += h / 6 * (k1[2] + 2 * k2[2] + 2 * k3[2] + k4[2]);
      z += h / 6 * (k1[3] + 2 * k2[3] + 2 * k3[3] + k4[3]);
      s += h;
    }
    return {psi, std::atan2(z, x)};
  }

  // Chord angle of the equilibrium of overhang `length` (the tip angle found by bisection so the clamp
  // angle is 0); pi/2 if even a vertical tip cannot balance (the strip hangs past vertical).
  Real chordAngle(Real length) {
    prepare(0.5 * w_ * length * length);
    if (shoot(length, kPi / 2).clamp_angle < 0) return kPi / 2;
    Real lo = 0, hi = kPi / 2;
    for (int it = 0; it < 40; ++it) {
      const Real mid = 0.5 * (lo + hi);
      (shoot(length, mid).clamp_angle < 0 ? lo : hi) = mid;
    }
    return shoot(length, 0.5 * (lo + hi)).chord_angle;
  }

 private:
  // Tabulates M(kappa) up to a moment of at least max_moment, for inversion.
  void prepare(Real max_moment) {
    Real kmax = 1;
    while (material_.bendMomentSI(dir_, kmax) < max_moment && kmax < 1e7) kmax *= 2;
    if (!(material_.bendMomentSI(dir_, kmax) >= max_moment))
      throw MaterialLabError("bending curve " + std::string(dir_ == 0 ? "bend_warp" : "bend_weft") +
                             " never reaches the cantilever's clamp moment");
    const int n = 20000;
    kappa_.resize(n + 1);
    moment_.resize(n + 1);
    for (int k = 0; k <= n; ++k) {
      kappa_[k] = kmax * k / n;
      moment_[k] = material_.bendMomentSI(dir_, kappa_[k]);
      if (k > 0 && !(moment_[k] > moment_[k - 1]))
        throw MaterialLabError("bending curve " + std::string(dir_ == 0 ? "bend_warp" : "bend_weft") +
                               " is not increasing at " + std::to_string(kappa_[k] * kPerMeterToPerCm) + " 1/cm");
    }
  }
  Real curvature(Real m) const {
    if (m <= 0) return 0;
    const auto it = std::upper_bound(moment_.begin(), moment_.end(), m);
    if (it == moment_.end()) return kappa_.back();
    const std::size_t k = static_cast<std::size_t>(it - moment_.begin());
    return kappa_[k - 1] + (m - moment_[k - 1]) / (moment_[k] - moment_[k - 1]) * (kappa_[k] - kappa_[k - 1]);
  }

  const Material& material_;
  int dir_;
  Real w_;
  std::vector<Real> kappa_, moment_;
};

}  // namespace

CantileverResult runCantilever(const LabSample& sample, YarnDirection direction, const CantileverProtocol& protocol) {
  if (!std::isfinite(protocol.angle_deg) || !(protocol.angle_deg > 5) || !(protocol.angle_deg < 85))
    throw MaterialLabError("cantilever.angle_deg must be in (5, 85)");
  if (!(protocol.min_overhang_m > 0) || !(protocol.max_overhang_m > protocol.min_overhang_m) || !std::isfinite(protocol.max_overhang_m))
    throw MaterialLabError("cantilever: need 0 < min_overhang_m < max_overhang_m (finite)");
  const Real d = sample.spacing;
  if (!std::isfinite(d) || !(d > 0)) throw MaterialLabError("sample spacing must be finite and > 0");
  const int cells_b = cellsFor(protocol.width_m, d, 1, "cantilever.width_m");
  int lo = cellsFor(protocol.min_overhang_m, d, 2, "cantilever.min_overhang_m");
  const int max_cells = cellsFor(protocol.max_overhang_m, d, lo + 1, "cantilever.max_overhang_m");

  CantileverResult result;
  result.direction = direction;
  auto solve = [&](int cells) {
    result.samples.push_back(solveOverhang(sample, direction, cells, cells_b, protocol));
    return result.samples.back().angle_deg;
  };
  // Bracket the angle by doubling the overhang, then close the bracket to adjacent grid lengths.
  Real a_lo = solve(lo);
  if (a_lo >= protocol.angle_deg)
    throw MaterialLabError("cantilever: the shortest overhang (" + std::to_string(lo * d) + " m) already droops past " +
                           std::to_string(protocol.angle_deg) + " deg; lower cantilever.min_overhang_m");
  int hi = lo;
  Real a_hi = a_lo;
  while (a_hi < protocol.angle_deg) {
    if (hi >= max_cells)
      throw MaterialLabError("cantilever: even the longest overhang (" + std::to_string(max_cells * d) + " m) droops less than " +
                             std::to_string(protocol.angle_deg) + " deg; raise cantilever.max_overhang_m");
    lo = hi;
    a_lo = a_hi;
    hi = std::min(2 * hi, max_cells);
    a_hi = solve(hi);
  }
  while (hi - lo > 1) {
    const int mid = (lo + hi) / 2;
    const Real a = solve(mid);
    if (a < protocol.angle_deg) {
      lo = mid;
      a_lo = a;
    } else {
      hi = mid;
      a_hi = a;
    }
  }
  result.overhang_m = d * (lo + (protocol.angle_deg - a_lo) / (a_hi - a_lo) * (hi - lo));
  result.bending_length_m = 0.5 * result.overhang_m;
  // Peirce's flexural rigidity with the specimen's own weight per area (any model's mass).
  const Real w = sampleArealDensity(sample) * kGravity;
  result.flexural_rigidity_Nm = w * std::pow(result.bending_length_m, 3);
  return result;
}

Real materialCantileverBendingLength(const Material& material, YarnDirection direction, Real angle_deg) {
  std::string error;
  if (!material.validate(&error)) throw MaterialLabError("material: " + error);
  if (!std::isfinite(angle_deg) || !(angle_deg > 5) || !(angle_deg < 85)) throw MaterialLabError("angle_deg must be in (5, 85)");
  const Real target = angle_deg * kDeg;
  Elastica elastica(material, direction, material.areal_density * kGravity);
  Real lo = 1e-4, hi = 1e-3;
  while (elastica.chordAngle(hi) < target) {
    lo = hi;
    hi *= 2;
    if (hi > 1e3) throw MaterialLabError("material: the cantilever never droops to " + std::to_string(angle_deg) + " deg");
  }
  for (int it = 0; it < 40; ++it) {
    const Real mid = 0.5 * (lo + hi);
    (elastica.chordAngle(mid) < target ? lo : hi) = mid;
  }
  return 0.25 * (lo + hi);
}

}  // namespace lab
}  // namespace textile_handling
