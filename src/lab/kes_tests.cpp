// KES-FB2 bending, KES-FB1 shear and tensile on any cloth model (material_lab.h, docs/material_lab.md).
#include <algorithm>
#include <cmath>
#include <string>

#include "lab_specimen.h"

namespace textile_handling {
namespace lab {
namespace {

constexpr Real kDeg = kPi / 180;

void checkSteps(int steps, const char* field) {
  if (steps < 4 || steps > 100000) throw MaterialLabError(std::string(field) + " must be in [4, 100000]");
}

void checkPositive(Real value, const char* field) {
  if (!std::isfinite(value) || !(value > 0)) throw MaterialLabError(std::string(field) + " must be finite and > 0");
}

// y at x on the branch cycle[first..last] (x monotone along it), by linear interpolation.
Real branchValue(const std::vector<CurvePoint>& cycle, std::size_t first, std::size_t last, Real x) {
  for (std::size_t k = first; k < last; ++k) {
    const Real x0 = cycle[k].x, x1 = cycle[k + 1].x;
    if ((x - x0) * (x - x1) <= 0 && x0 != x1) return cycle[k].y + (x - x0) / (x1 - x0) * (cycle[k + 1].y - cycle[k].y);
  }
  throw MaterialLabError("curve does not reach " + std::to_string(x));
}

// The quarters of a symmetric cycle of 4 n + 1 points: 0->+max, +max->0, 0->-max, -max->0.
struct Quarters {
  std::size_t n;
  Real loadPos(const std::vector<CurvePoint>& c, Real x) const { return branchValue(c, 0, n, x); }
  Real unloadPos(const std::vector<CurvePoint>& c, Real x) const { return branchValue(c, n, 2 * n, x); }
  Real loadNeg(const std::vector<CurvePoint>& c, Real x) const { return branchValue(c, 2 * n, 3 * n, x); }
  Real unloadNeg(const std::vector<CurvePoint>& c, Real x) const { return branchValue(c, 3 * n, 4 * n, x); }
  // Mean loading slope between |x| = lo and hi over both signs.
  Real slope(const std::vector<CurvePoint>& c, Real lo, Real hi) const {
    return 0.5 * ((loadPos(c, hi) - loadPos(c, lo)) + (loadNeg(c, -lo) - loadNeg(c, -hi))) / (hi - lo);
  }
  // Mean loop width at |x| = at over both signs.
  Real width(const std::vector<CurvePoint>& c, Real at) const {
    return 0.5 * ((loadPos(c, at) - unloadPos(c, at)) + (unloadNeg(c, -at) - loadNeg(c, -at)));
  }
};

// A point at distance s along an arc of curvature kappa through the origin, tangent to the a axis, with
// nodes spaced d apart keeping their chord length d (so no stretch enters the bending test).
Vec3 arcPoint(Real s, Real kappa, Real d) {
  const Real t = kappa * d / 2;
  // Node angle per unit rest length: 2 asin(kappa d / 2) / d = kappa * ratio.
  const Real ratio = std::abs(t) < 1e-8 ? 1 + t * t / 6 : std::asin(t) / t;
  const Real phi = kappa * ratio * s;
  Real sinc, versinc;  // sin(phi)/phi, (1 - cos(phi))/phi
  if (std::abs(phi) < 1e-4) {
    sinc = 1 - phi * phi / 6;
    versinc = phi / 2 - phi * phi * phi / 24;
  } else {
    sinc = std::sin(phi) / phi;
    versinc = (1 - std::cos(phi)) / phi;
  }
  return Vec3(ratio * s * sinc, 0, ratio * s * versinc);
}

}  // namespace

KesBendingResult runKesBending(const LabSample& sample, YarnDirection direction, const KesBendingProtocol& protocol) {
  checkPositive(protocol.length_cm, "bending.length_cm");
  checkPositive(protocol.width_cm, "bending.width_cm");
  checkPositive(protocol.max_curvature_per_cm, "bending.max_curvature_per_cm");
  if (protocol.max_curvature_per_cm < 1.5) throw MaterialLabError("bending.max_curvature_per_cm must be >= 1.5 (B is read between 0.5 and 1.5)");
  checkSteps(protocol.steps_per_quarter, "bending.steps_per_quarter");
  if (!std::isfinite(protocol.bias_deg) || protocol.bias_deg < 0 || protocol.bias_deg > 90)
    throw MaterialLabError("bending.bias_deg must be in [0, 90]");
  const Real d = sample.spacing;
  const int ca = cellsFor(protocol.length_cm * 0.01, d, 2, "bending.length_cm");
  const int cb = cellsFor(protocol.width_cm * 0.01, d, 1, "bending.width_cm");
  InteriorResponse response(sample, direction, ca, cb, true);
  const Real kmax = protocol.max_curvature_per_cm * 100;  // 1/m
  // Nodes a chord d apart on a circle of radius 1/kappa need kappa d <= 2; kappa d <= 1 keeps the angle
  // the nodes see within 5 % of the circle's curvature.
  if (kmax * d > 1)
    throw MaterialLabError("bending: the sample spacing d = " + std::to_string(d) + " m is too coarse for bending.max_curvature_per_cm = " +
                           std::to_string(protocol.max_curvature_per_cm) + " (needs kappa_max d <= 1, d <= " +
                           std::to_string(1 / kmax) + " m)");
  const std::vector<Real> q = symmetricCycle(kmax, protocol.steps_per_quarter);
  const Real bias = protocol.bias_deg * kDeg;
  const Vec2 along(std::cos(bias), std::sin(bias)), across(-std::sin(bias), std::cos(bias));
  const SpecimenMap map = [d, bias, along, across](Real a, Real b, Real kappa) {
    if (bias == 0) {
      Vec3 p = arcPoint(a, kappa, d);
      p.y() = b;
      return p;
    }
    // Isometric arc along `along`: arc length s, the across coordinate t unchanged.
    const Real s = along.dot(Vec2(a, b)), t = across.dot(Vec2(a, b));
    const Vec3 arc = arcPoint(s, kappa, 0);
    return Vec3(arc.x() * along.x() + t * across.x(), arc.x() * along.y() + t * across.y(), arc.z());
  };
  const Real dq = 1e-3 * kmax / protocol.steps_per_quarter;

  KesBendingResult r;
  r.direction = direction;
  for (const Real kappa : q) r.cycle.push_back({kappa * kPerMeterToPerCm, response.at(map, kappa, dq) / kGfCmPerCmToN});
  const Quarters quarters{static_cast<std::size_t>(protocol.steps_per_quarter)};
  r.B = quarters.slope(r.cycle, 0.5, 1.5);
  r.twoHB = quarters.width(r.cycle, 1.0);
  return r;
}

KesShearResult runKesShear(const LabSample& sample, YarnDirection direction, const KesShearProtocol& protocol) {
  checkPositive(protocol.length_cm, "shear.length_cm");
  checkPositive(protocol.height_cm, "shear.height_cm");
  checkPositive(protocol.max_angle_deg, "shear.max_angle_deg");
  if (protocol.max_angle_deg < 5 || protocol.max_angle_deg > 45) throw MaterialLabError("shear.max_angle_deg must be in [5, 45]");
  checkSteps(protocol.steps_per_quarter, "shear.steps_per_quarter");
  if (!std::isfinite(protocol.pretension_strain) || protocol.pretension_strain < 0 || protocol.pretension_strain > 0.2)
    throw MaterialLabError("shear.pretension_strain must be in [0, 0.2]");
  const Real d = sample.spacing;
  const int ca = cellsFor(protocol.length_cm * 0.01, d, 1, "shear.length_cm");
  const int cb = cellsFor(protocol.height_cm * 0.01, d, 1, "shear.height_cm");
  InteriorResponse response(sample, direction, ca, cb, false);
  const Real tmax = protocol.max_angle_deg * kDeg;
  const std::vector<Real> q = symmetricCycle(tmax, protocol.steps_per_quarter);
  // Trellis shear: the yarns along the clamps (a) stay put, the crossing yarns turn by theta; both keep their length.
  // With pretension the crossing yarns are stretched by 1 + e as they turn.
  const Real stretch = 1 + protocol.pretension_strain;
  const SpecimenMap map = [stretch](Real a, Real b, Real theta) {
    return Vec3(a + stretch * b * std::sin(theta), stretch * b * std::cos(theta), 0);
  };
  const Real dq = 1e-3 * tmax / protocol.steps_per_quarter;

  KesShearResult r;
  r.direction = direction;
  for (const Real theta : q) r.cycle.push_back({theta, response.at(map, theta, dq) / kGfPerCmToNPerM});
  const Quarters quarters{static_cast<std::size_t>(protocol.steps_per_quarter)};
  r.G = quarters.slope(r.cycle, 0.5 * kDeg, 5 * kDeg) * kDeg;
  r.twoHG = quarters.width(r.cycle, 0.5 * kDeg);
  r.twoHG5 = quarters.width(r.cycle, 5 * kDeg);
  return r;
}

KesTensileResult runKesTensile(const LabSample& sample, YarnDirection direction, const KesTensileProtocol& protocol) {
  checkPositive(protocol.length_cm, "tensile.length_cm");
  checkPositive(protocol.width_cm, "tensile.width_cm");
  checkPositive(protocol.max_force_gf_per_cm, "tensile.max_force_gf_per_cm");
  checkPositive(protocol.strain_step, "tensile.strain_step");
  checkPositive(protocol.max_strain, "tensile.max_strain");
  if (protocol.max_strain / protocol.strain_step > 1e5) throw MaterialLabError("tensile.max_strain / tensile.strain_step must be <= 1e5");
  const Real d = sample.spacing;
  const int ca = cellsFor(protocol.length_cm * 0.01, d, 1, "tensile.length_cm");
  const int cb = cellsFor(protocol.width_cm * 0.01, d, 1, "tensile.width_cm");
  InteriorResponse response(sample, direction, ca, cb, false);
  const SpecimenMap map = [](Real a, Real b, Real strain) { return Vec3(a * (1 + strain), b, 0); };
  const Real h = protocol.strain_step;
  const Real fmax = protocol.max_force_gf_per_cm;

  // Loading, one increment at a time until F_max is passed (the cycle commits internal state as it goes).
  KesTensileResult r;
  r.direction = direction;
  Real strain = 0;
  Real force = response.at(map, 0.0, 0.1 * h) / kGfPerCmToNPerM;
  r.cycle.push_back({0, force});
  while (force < fmax) {
    strain += h;
    if (strain > protocol.max_strain)
      throw MaterialLabError("tensile: the force per width stays below tensile.max_force_gf_per_cm = " + std::to_string(fmax) +
                             " up to tensile.max_strain = " + std::to_string(protocol.max_strain));
    force = response.at(map, strain, 0.1 * h) / kGfPerCmToNPerM;
    r.cycle.push_back({strain, force});
  }
  // The strain at F_max, interpolated in the last increment; WT integrates the loading branch up to it.
  const CurvePoint prev = r.cycle[r.cycle.size() - 2];
  const Real em = prev.x + (fmax - prev.y) / (force - prev.y) * (strain - prev.x);
  r.cycle.back() = {em, response.at(map, em, 0.1 * h) / kGfPerCmToNPerM};
  const std::size_t loading = r.cycle.size();
  for (std::size_t k = 1; k < loading; ++k) r.WT += 0.5 * (r.cycle[k].y + r.cycle[k - 1].y) * (r.cycle[k].x - r.cycle[k - 1].x);
  // Unloading back to zero strain.
  Real recovered = 0;
  const int back = static_cast<int>(std::ceil(em / h));
  for (int k = 1; k <= back; ++k) {
    const Real e = em * (back - k) / back;
    const Real fe = response.at(map, e, 0.1 * h) / kGfPerCmToNPerM;
    recovered += 0.5 * (fe + r.cycle.back().y) * (r.cycle.back().x - e);
    r.cycle.push_back({e, fe});
  }
  r.EMT = 100 * em;
  r.LT = r.WT / (0.5 * fmax * em);
  r.RT = 100 * recovered / r.WT;
  return r;
}

Real materialKesB(const Material& material, YarnDirection direction) {
  const MaterialCurve& c = material.bendCurve(static_cast<int>(direction));
  return c.value(1.5) - c.value(0.5);
}

Real materialKesG(const Material& material, YarnDirection direction) {
  const MaterialCurve& c = material.shearCurve(static_cast<int>(direction));
  return (c.value(5 * kDeg) - c.value(0.5 * kDeg)) / 4.5;
}

}  // namespace lab
}  // namespace textile_handling
