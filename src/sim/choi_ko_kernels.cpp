#include "textile_handling/sim/choi_ko_kernels.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace textile_handling {
namespace choi_ko {

namespace {

// Series of the arc functions for |t| < 1, with T_k = t^(2k) / (2k+1)!:
//   1 - sinc t           = sum_{k>=1} (-1)^(k+1) T_k
//   D / t^2              = sum_{k>=1} (-1)^k 2k T_k / t^2
//   (2D + t sin t)/t^2   = sum_{k>=1} (-1)^(k+1) 2k(2k-1) T_k / t^2
//   (3D + t sin t)/t^4   = sum_{k>=2} (-1)^(k+1) 4k(k-1) T_k / t^4
// (from cos t = sum (-1)^k t^2k/(2k)!, sinc t = sum (-1)^k t^2k/(2k+1)!, t sin t = sum (-1)^(k-1) t^2k/(2k-1)!).
// 14 terms: the first omitted term is below 1e-30 of the leading one for |t| < 1.
constexpr int kSeriesTerms = 14;

struct ArcRatios {
  Real dn;  // D / t^2
  Real e2;  // (2D + t sin t) / t^2
  Real e3;  // (3D + t sin t) / t^4
};

ArcRatios arcRatios(Real t) {
  ArcRatios a;
  if (std::abs(t) < 1.0) {
    const Real t2 = t * t;
    // U_k = T_k / t^2 = t^(2k-2) / (2k+1)!; U_1 = 1/6.
    Real u = 1.0 / 6.0;
    Real dn = 0, e2 = 0, e3 = 0;
    for (int k = 1; k <= kSeriesTerms; ++k) {
      const Real sgn = (k % 2 == 0) ? 1.0 : -1.0;  // (-1)^k
      dn += sgn * 2 * k * u;
      e2 -= sgn * 2 * k * (2 * k - 1) * u;
      u *= t2 / ((2.0 * k + 2) * (2.0 * k + 3));
    }
    // Separate loop for e3 (k >= 2): V_k = t^(2k-4) / (2k+1)!, V_2 = 1/120.
    Real v = 1.0 / 120.0;
    for (int k = 2; k <= kSeriesTerms + 1; ++k) {
      const Real sgn = (k % 2 == 0) ? 1.0 : -1.0;
      e3 -= sgn * 4 * k * (k - 1) * v;
      v *= t2 / ((2.0 * k + 2) * (2.0 * k + 3));
    }
    a.dn = dn;
    a.e2 = e2;
    a.e3 = e3;
  } else {
    const Real c = std::cos(t), s = std::sin(t);
    const Real d = c - s / t;
    const Real t2 = t * t;
    a.dn = d / t2;
    a.e2 = (2 * d + t * s) / t2;
    a.e3 = (3 * d + t * s) / (t2 * t2);
  }
  return a;
}

}  // namespace

Real sinc(Real t) {
  if (std::abs(t) < 1e-4) return 1 - t * t / 6.0 + t * t * t * t / 120.0;
  return std::sin(t) / t;
}

Real oneMinusSinc(Real t) {
  if (std::abs(t) < 1.0) {
    const Real t2 = t * t;
    Real term = t2 / 6.0, sum = 0;
    for (int k = 1; k <= kSeriesTerms; ++k) {
      sum += (k % 2 == 1) ? term : -term;
      term *= t2 / ((2.0 * k + 2) * (2.0 * k + 3));
    }
    return sum;
  }
  return 1 - std::sin(t) / t;
}

Real bucklingD(Real t) { return arcRatios(t).dn * t * t; }

Real halfAngleFromChordDeficit(Real u) {
  if (!(u > 0)) return 0;  // also NaN -> 0 (callers check finiteness of the geometry)
  if (u >= 1) return kPi;
  // Bracket [lo, hi] on which 1 - sinc is increasing from 0 to 1.
  Real lo = 0, hi = kPi;
  Real t = std::min(std::sqrt(6 * u + 1.8 * u * u), kPi);
  for (int it = 0; it < 100; ++it) {
    const Real res = oneMinusSinc(t) - u;  // increasing in t
    if (res > 0) hi = t; else lo = t;
    if (res == 0) return t;
    // d(1 - sinc)/dt = -D/t = -t (D/t^2) > 0.
    const Real slope = -t * arcRatios(t).dn;
    Real next = slope > 0 ? t - res / slope : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const Real step = std::abs(next - t);
    t = next;
    if (step <= 4e-16 * t || hi - lo <= 4e-16 * hi) break;
  }
  return t;
}

BucklingShape bucklingShape(Real u) {
  BucklingShape b;
  const Real t = halfAngleFromChordDeficit(u);
  b.theta = t;
  const ArcRatios a = arcRatios(t);
  const Real dn3 = a.dn * a.dn * a.dn;
  b.g = 4.0 / a.dn;
  b.dg = 4.0 * a.e3 / dn3;
  if (t > 0) {
    b.k1 = 2.0 / (t * a.dn);
    b.k2 = 2.0 * a.e2 / (t * t * t * dn3);
  } else {
    b.k1 = -std::numeric_limits<Real>::infinity();
    b.k2 = -std::numeric_limits<Real>::infinity();
  }
  return b;
}

BucklingLaw makeBucklingLaw(Real onset) {
  if (!(onset > 0 && onset < 1)) {
    std::ostringstream m;
    m << "Choi-Ko buckling onset s* must lie in (0, 1), got " << onset;
    throw SimError(m.str());
  }
  BucklingLaw law;
  law.onset = onset;
  const Real u_on = 1 - onset;
  const BucklingShape on = bucklingShape(u_on);
  law.theta_onset = on.theta;
  law.gamma = -on.g / u_on;
  law.e_onset = 0.5 * law.gamma * u_on * u_on;
  // Second crossing: h(s) = gamma (s - 1) - g(s) is convex with h(s*) = 0; h(0) = 4 pi^2 - gamma.
  if (law.gamma < 4 * kPi * kPi) {
    Real lo = 0, hi = onset;  // h(lo) > 0 >= h(hi) on the part of the curve used below s*
    // h < 0 just below s* (the curve is used there); bisection on the sign of h.
    for (int it = 0; it < 200; ++it) {
      const Real mid = 0.5 * (lo + hi);
      const Real h = law.gamma * (mid - 1) - bucklingShape(1 - mid).g;
      if (h > 0) lo = mid; else hi = mid;
      if (hi - lo < 1e-15) break;
    }
    law.s_lo = 0.5 * (lo + hi);
    law.theta_lo = halfAngleFromChordDeficit(1 - law.s_lo);
    law.e_lo = law.e_onset + 2 * (law.theta_lo * law.theta_lo - law.theta_onset * law.theta_onset);
  } else {
    law.s_lo = 0;
    law.theta_lo = kPi;
    law.e_lo = law.e_onset + 2 * (kPi * kPi - law.theta_onset * law.theta_onset);
  }
  return law;
}

BucklingResponse bucklingResponse(Real u, const BucklingLaw& law) {
  BucklingResponse r;
  if (!(u > 0)) return r;
  const Real uu = std::min(u, 1.0);
  const Real s = 1 - uu;
  if (s >= law.onset) {
    r.f = -law.gamma * uu;
    r.df = law.gamma;
    r.e = 0.5 * law.gamma * uu * uu;
    return r;
  }
  if (s >= law.s_lo) {
    r.shape = bucklingShape(uu);
    r.on_curve = true;
    r.f = r.shape.g;
    r.df = r.shape.dg;
    r.e = law.e_onset + 2 * (r.shape.theta * r.shape.theta - law.theta_onset * law.theta_onset);
    return r;
  }
  const Real u_lo = 1 - law.s_lo;
  r.f = -law.gamma * uu;
  r.df = law.gamma;
  r.e = law.e_lo + 0.5 * law.gamma * (uu * uu - u_lo * u_lo);
  return r;
}

bool tensionOnlySpring(const Vec3& xi, const Vec3& xj, Real rest, Real k, bool want_jacobian,
                       PairTermResult* out) {
  const Vec3 d = xj - xi;
  const Real r = d.norm();
  if (!std::isfinite(r) || !(r > 0)) return false;
  PairTermResult o;
  o.r = r;
  o.unit = d / r;
  if (r >= rest) {
    o.active = true;
    const Real e = r - rest;
    o.energy = 0.5 * k * e * e;
    o.f = k * e;
    if (want_jacobian) {
      const Mat3 uu = o.unit * o.unit.transpose();
      o.jac = k * uu + k * (1 - rest / r) * (Mat3::Identity() - uu);
    }
  }
  *out = o;
  return true;
}

std::string toString(BendingJacobian j) {
  switch (j) {
    case BendingJacobian::kExact: return "exact";
    case BendingJacobian::kDropNegative: return "drop_negative";
    case BendingJacobian::kSecant: return "secant";
  }
  return "unknown";
}

BendingJacobian bendingJacobianFromString(const std::string& s) {
  if (s == "exact") return BendingJacobian::kExact;
  if (s == "drop_negative") return BendingJacobian::kDropNegative;
  if (s == "secant") return BendingJacobian::kSecant;
  throw SimError("unknown bending Jacobian '" + s + "' (expected exact, drop_negative or secant)");
}

Mat3 bendingJacobianBlock(const Vec3& unit, Real r, Real rest, Real f0, Real f, Real df, Real u, BendingJacobian mode) {
  const Mat3 uu = unit * unit.transpose();
  if (mode == BendingJacobian::kExact) return (f0 / rest) * df * uu + (f / r) * (Mat3::Identity() - uu);
  Real slope = std::max(df, 0.0);
  if (mode == BendingJacobian::kSecant && f < 0 && u > 0) slope = std::max(slope, -f / (f0 * u));
  return (f0 / rest) * slope * uu;
}

bool bucklingUnit(const Vec3& xi, const Vec3& xj, Real rest, Real f0, const BucklingLaw& law,
                  bool want_jacobian, BendingJacobian mode, PairTermResult* out) {
  const Vec3 d = xj - xi;
  const Real r = d.norm();
  if (!std::isfinite(r) || !(r > 0)) return false;
  PairTermResult o;
  o.r = r;
  o.unit = d / r;
  if (r < rest) {
    o.active = true;
    const BucklingResponse b = bucklingResponse((rest - r) / rest, law);
    o.energy = f0 * rest * b.e;
    o.f = f0 * b.f;
    if (want_jacobian) o.jac = bendingJacobianBlock(o.unit, r, rest, f0, o.f, b.df, (rest - r) / rest, mode);
  }
  *out = o;
  return true;
}

HystereticBendingScalar hystereticBending(const BucklingShape& shape, Real u, Real sign, Real moment,
                                          Real tangent, Real rest, Real reference_rigidity,
                                          const BucklingLaw& law) {
  HystereticBendingScalar h;
  if (!(u > 0)) return h;
  const Real kappa = 2 * shape.theta / rest;
  const Real remainder = moment - tangent * sign * kappa;
  const Real a = tangent / reference_rigidity;
  const Real b = sign * remainder * rest / reference_rigidity;
  h.f = a * shape.g + b * shape.k1;
  h.df = a * shape.dg + b * shape.k2;
  const Real bound = law.gamma * std::min(u, 1.0);
  if (!(std::abs(h.f) <= bound)) {
    h.clamped = true;
    if (h.f < 0) {
      h.f = -bound;
      h.df = law.gamma;
    } else {
      h.f = bound;
      h.df = -law.gamma;
    }
  }
  return h;
}

// ---- hysteresis -------------------------------------------------------------------------------------

HysteresisSpec HysteresisSpec::discrete(std::vector<Real> stiffness, std::vector<Real> slip_moment) {
  HysteresisSpec s;
  s.kind = Kind::kDiscrete;
  s.stiffness = std::move(stiffness);
  s.slip_moment = std::move(slip_moment);
  return s;
}

HysteresisSpec HysteresisSpec::continuous(Real k0, Real k_sum, Real yield_min, Real yield_max) {
  HysteresisSpec s;
  s.kind = Kind::kContinuous;
  s.k0 = k0;
  s.k_sum = k_sum;
  s.yield_min = yield_min;
  s.yield_max = yield_max;
  return s;
}

HysteresisSpec HysteresisSpec::continuousFromKes(Real bending_rigidity, Real two_hb, Real yield_min,
                                                 Real yield_max) {
  return continuous(bending_rigidity, two_hb / (yield_min + yield_max), yield_min, yield_max);
}

Real HysteresisSpec::initialSlope() const {
  switch (kind) {
    case Kind::kNone: return 0;
    case Kind::kDiscrete: {
      Real s = 0;
      for (Real k : stiffness) s += k;
      return s;
    }
    case Kind::kContinuous: return k0 + k_sum;
  }
  return 0;
}

Real HysteresisSpec::virginMoment(Real x, Real* tangent) const {
  const Real a = std::abs(x);
  const Real sg = x < 0 ? -1.0 : 1.0;
  if (kind == Kind::kDiscrete) {
    Real m = stiffness.empty() ? 0 : stiffness[0] * a;
    Real t = stiffness.empty() ? 0 : stiffness[0];
    for (size_t i = 0; i < slip_moment.size(); ++i) {
      const Real k = stiffness[i + 1];
      const Real yield = slip_moment[i] / k;
      if (a < yield) {
        m += k * a;
        t += k;
      } else {
        m += slip_moment[i];
      }
    }
    if (tangent) *tangent = t;
    return sg * m;
  }
  if (kind == Kind::kContinuous) {
    Real phi, dphi;
    if (a <= yield_min) {
      phi = a;
      dphi = 1;
    } else if (a < yield_max) {
      const Real w = yield_max - yield_min;
      phi = a - (a - yield_min) * (a - yield_min) / (2 * w);
      dphi = 1 - (a - yield_min) / w;
    } else {
      phi = 0.5 * (yield_min + yield_max);
      dphi = 0;
    }
    if (tangent) *tangent = k0 + k_sum * dphi;
    return sg * (k0 * a + k_sum * phi);
  }
  if (tangent) *tangent = 0;
  return 0;
}

bool HysteresisSpec::valid(std::string* error) const {
  auto fail = [&](const std::string& m) {
    if (error) *error = "hysteresis: " + m;
    return false;
  };
  switch (kind) {
    case Kind::kNone: return true;
    case Kind::kDiscrete: {
      if (slip_moment.empty()) return fail("the discrete model needs at least one slip unit");
      if (stiffness.size() != slip_moment.size() + 1)
        return fail("the discrete model needs n + 1 spring constants for n slip units");
      if (!(stiffness[0] >= 0) || !std::isfinite(stiffness[0])) return fail("K_0 must be finite and >= 0");
      for (size_t i = 1; i < stiffness.size(); ++i)
        if (!(stiffness[i] > 0) || !std::isfinite(stiffness[i])) return fail("K_1..K_n must be finite and > 0");
      for (Real s : slip_moment)
        if (!(s > 0) || !std::isfinite(s)) return fail("slip moments must be finite and > 0");
      return true;
    }
    case Kind::kContinuous: {
      if (!(k0 >= 0) || !std::isfinite(k0)) return fail("k0 must be finite and >= 0");
      if (!(k_sum > 0) || !std::isfinite(k_sum)) return fail("k_sum must be finite and > 0");
      if (!(yield_min >= 0) || !(yield_max >= yield_min) || !(yield_max > 0) || !std::isfinite(yield_max))
        return fail("yield range must satisfy 0 <= x_a <= x_b, x_b > 0, finite");
      return true;
    }
  }
  return fail("unknown kind");
}

HysteresisState HysteresisState::initial(const HysteresisSpec& spec) {
  HysteresisState s;
  if (spec.kind == HysteresisSpec::Kind::kDiscrete) s.slip.assign(spec.slip_moment.size(), 0.0);
  return s;
}

namespace {

Real sgn(Real v) { return v > 0 ? 1.0 : (v < 0 ? -1.0 : 0.0); }

// Discrete model: exact update of every branch for the monotone path to x.
Real discreteMoment(const HysteresisSpec& spec, const std::vector<Real>& slip, Real x, Real* tangent,
                    std::vector<Real>* slip_out) {
  Real m = spec.stiffness[0] * x;
  Real t = spec.stiffness[0];
  for (size_t i = 0; i < spec.slip_moment.size(); ++i) {
    const Real k = spec.stiffness[i + 1];
    const Real yield = spec.slip_moment[i] / k;
    Real p = slip[i];
    bool sliding = false;
    if (x - p > yield) {
      p = x - yield;
      sliding = true;
    } else if (x - p < -yield) {
      p = x + yield;
      sliding = true;
    }
    m += k * (x - p);
    if (!sliding) t += k;
    if (slip_out) (*slip_out)[i] = p;
  }
  if (tangent) *tangent = t;
  return m;
}

// Continuous model (Masing with memory). The stack R_1..R_m of reversal points (oldest first) plus
// possibly one new point E (the committed position, when the path reverses there) forms a virtual
// stack of `top` entries; the branch in use starts at entry `top` (the virgin curve when top = 0).
struct MasingWalk {
  int top = 0;        // entries of the virtual stack in use
  bool extra = false; // whether entry m+1 (the new reversal E) is part of it
  std::array<Real, 2> e{{0, 0}};
};

class MasingView {
 public:
  MasingView(const HysteresisSpec& spec, const HysteresisState& st) : spec_(spec), st_(st) {}
  int m() const { return static_cast<int>(st_.reversals.size()); }
  std::array<Real, 2> at(int k, const MasingWalk& w) const {  // 1-based
    return k <= m() ? st_.reversals[static_cast<size_t>(k - 1)] : w.e;
  }
  // Moment (and tangent) on the branch starting at entry k (0 = virgin).
  Real branch(int k, const MasingWalk& w, Real x, Real* tangent) const {
    if (k == 0) return spec_.virginMoment(x, tangent);
    const auto p = at(k, w);
    const Real v = spec_.virginMoment(0.5 * (x - p[0]), tangent);
    return p[1] + 2 * v;
  }
  // Closure point of the branch starting at entry k >= 1: the previous reversal, or for k = 1 the
  // mirror point -X_1 where the first reversal branch rejoins the virgin curve.
  Real closure(int k, const MasingWalk& w) const { return k == 1 ? -at(1, w)[0] : at(k - 1, w)[0]; }

  MasingWalk walk(Real x) const {
    MasingWalk w;
    w.top = m();
    const Real xc = st_.x;
    const Real d = sgn(x - xc);
    if (d == 0) return w;
    if (w.top == 0) {
      if (xc != 0 && d != sgn(xc)) push(w, xc);
    } else {
      const auto last = at(w.top, w);
      const Real dir = sgn(closure(w.top, w) - last[0]);
      if (d != dir) {
        if (xc == last[0]) {
          --w.top;  // reversing exactly at a reversal point: back onto the branch before it
        } else {
          push(w, xc);
        }
      }
    }
    // Close every loop the path runs through.
    while (w.top > 0) {
      const Real c = closure(w.top, w);
      const Real dir = sgn(c - at(w.top, w)[0]);
      if (dir != 0 && (x - c) * dir > 0) {
        w.top = w.top == 1 ? 0 : w.top - 2;
      } else {
        break;
      }
    }
    return w;
  }

 private:
  void push(MasingWalk& w, Real xc) const {
    w.e = {xc, branch(w.top, w, xc, nullptr)};
    w.extra = true;
    w.top = m() + 1;
  }
  const HysteresisSpec& spec_;
  const HysteresisState& st_;
};

}  // namespace

Real hysteresisMoment(const HysteresisSpec& spec, const HysteresisState& state, Real x, Real* tangent) {
  switch (spec.kind) {
    case HysteresisSpec::Kind::kNone:
      if (tangent) *tangent = 0;
      return 0;
    case HysteresisSpec::Kind::kDiscrete: return discreteMoment(spec, state.slip, x, tangent, nullptr);
    case HysteresisSpec::Kind::kContinuous: {
      const MasingView view(spec, state);
      const MasingWalk w = view.walk(x);
      return view.branch(w.top, w, x, tangent);
    }
  }
  return 0;
}

void hysteresisCommit(const HysteresisSpec& spec, HysteresisState& state, Real x) {
  if (spec.kind == HysteresisSpec::Kind::kDiscrete) {
    discreteMoment(spec, state.slip, x, nullptr, &state.slip);
  } else if (spec.kind == HysteresisSpec::Kind::kContinuous) {
    const MasingView view(spec, state);
    const MasingWalk w = view.walk(x);
    const int m = static_cast<int>(state.reversals.size());
    if (w.top <= m) {
      state.reversals.resize(static_cast<size_t>(w.top));
    } else {
      if (m + 1 > HysteresisState::kMaxReversals && m >= 2) state.reversals.resize(static_cast<size_t>(m - 2));
      state.reversals.push_back(w.e);
    }
  }
  state.x = x;
}

HysteresisUnit::HysteresisUnit(HysteresisSpec spec) : spec_(std::move(spec)) {
  std::string error;
  if (!spec_.valid(&error)) throw SimError(error);
  state_ = HysteresisState::initial(spec_);
}

Real HysteresisUnit::drive(Real x) {
  const Real m = moment(x);
  hysteresisCommit(spec_, state_, x);
  return m;
}

}  // namespace choi_ko
}  // namespace textile_handling
