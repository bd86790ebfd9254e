// Small kernels of the Choi–Ko cloth model (docs/choi_ko.md): the immediate buckling law, the
// tension-only spring and the two Choi–Ko hysteresis models (moment vs curvature).
//
// Sources: the patent seed shared/seeds/002_8c736abc780ab69f.txt (ES 2 587 682 T3 = EP 1 439 476) and
// its English notes with errata shared/reference/choi-ko-buckling-hysteresis.md ("notes" below; where
// they differ from the seed, the notes are followed). Equation numbers are the seed's.
//
// Conventions (notes section 0): a unit joins particles i and j, x_ij = x_j - x_i, r = |x_ij|,
// u = x_ij / r, L the rest distance, s = r/L. The force on i is f_i = f u and f_j = -f_i, so f < 0
// pushes i away from j (compression resistance) and f > 0 pulls them together. The Jacobian block
// J = df_i/dx_j = df_j/dx_i; df_i/dx_i = df_j/dx_j = -J. Kernels return false on degenerate geometry
// (non-finite input, r == 0) and then leave their outputs untouched.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace choi_ko {

// ---- the circular-arc geometry of a buckled unit --------------------------------------------------

/// sinc(t) = sin(t)/t, 1 at t = 0.
Real sinc(Real t);
/// 1 - sinc(t), accurate for small t (series below |t| = 1).
Real oneMinusSinc(Real t);
/// D(t) = cos t - sinc t (< 0 on (0, pi]); series below |t| = 1.
Real bucklingD(Real t);

/// Half bend angle theta = kappa L / 2 in [0, pi] of a circular arc of length L whose chord is
/// r = L (1 - u), i.e. the inverse of eq (3): sinc(theta) = r/L = s. Solves 1 - sinc(theta) = u by
/// safeguarded Newton from theta0 = sqrt(6u + 1.8u^2) (notes section 7). Passing the chord deficit u
/// = (L - r)/L instead of s keeps full relative precision near s = 1. u <= 0 gives 0, u >= 1 gives pi.
Real halfAngleFromChordDeficit(Real u);
/// theta = sinc^-1(s) on the branch [0, pi] (s clamped to [0, 1]).
inline Real inverseSinc(Real s) { return halfAngleFromChordDeficit(1 - s); }

/// Dimensionless functions of the buckling branch at chord deficit u in (0, 1] (notes section 2.6):
///   theta = sinc^-1(1 - u),  D = cos(theta) - sinc(theta),
///   g  = 4 theta^2 / D                              = f_b L^3 / (W B)   (f_b of eq (5)/(9))
///   dg = 4 theta^2 (3D + theta sin theta) / D^3     = g'(s)
///   k1 = 2 theta / D                                = L^2 dkappa/dr
///   k2 = 2 theta (2D + theta sin theta) / D^3       = L^3 d2kappa/dr2
/// g and dg are evaluated through series-stable ratios, so g -> -12 and dg -> 7.2 as u -> 0
/// (k1 and k2 diverge like -6/theta and -18/theta^3 there).
struct BucklingShape {
  Real theta = 0;
  Real g = -12;
  Real dg = 7.2;
  Real k1 = 0;
  Real k2 = 0;
};
BucklingShape bucklingShape(Real u);

// ---- immediate buckling law with the linear segment ----------------------------------------------

/// The compressive force law of a bending unit in units of F0 = W B / L^3 (beam: W = k_b/B L, i.e.
/// F0 = k_b / L^2; plate: W = A_i + A_j, eq (9)), as a function of s = r/L < 1:
///   f*(s) = max( g(s), gamma (s - 1) )         (seed: f_b* = c_b (r - L) where f_b < c_b (r - L))
/// with gamma = c_b L / F0. The linear segment is parametrised by its onset s* < 1, the chord ratio
/// below which the buckling curve is used: gamma = |g(s*)| / (1 - s*) (notes section 8; the seed
/// calls c_b arbitrary). If gamma < 4 pi^2 the segment takes over again below a second crossing
/// s_lo (notes section 7 table). The energy E = F0 L e(s) with de/ds = f*, e(1) = 0:
///   s >= s*:          e = gamma (1 - s)^2 / 2
///   s_lo <= s < s*:   e = e(s*) + 2 (theta(s)^2 - theta(s*)^2)      (E_b = 1/2 W B kappa^2 = F0 L 2 theta^2)
///   s < s_lo:         e = e(s_lo) + gamma ((1 - s)^2 - (1 - s_lo)^2) / 2
struct BucklingLaw {
  Real onset = 0.999;  ///< s*
  Real gamma = 0;      ///< c_b L / F0
  Real s_lo = 0;       ///< lower crossing (0 when gamma >= 4 pi^2: the curve is used down to s = 0)
  Real e_onset = 0;    ///< e(s*)
  Real e_lo = 0;       ///< e(s_lo)
  Real theta_onset = 0, theta_lo = 0;
};
/// Builds the law for an onset s* in (0, 1); throws std::invalid_argument otherwise.
BucklingLaw makeBucklingLaw(Real onset);

/// f*, df*/ds and e of the law at chord deficit u = 1 - s (u <= 0: unit not compressed, all 0).
struct BucklingResponse {
  Real f = 0;       ///< f* / F0
  Real df = 0;      ///< d(f*/F0)/ds  (>= 0)
  Real e = 0;       ///< E / (F0 L)
  bool on_curve = false;  ///< true where the buckling curve (not the linear segment) is used
  BucklingShape shape;
};
BucklingResponse bucklingResponse(Real u, const BucklingLaw& law);

/// Result of one pair term: energy, scalar force f (f_i = f * unit), the unit vector and the block
/// J = df_i/dx_j.
struct PairTermResult {
  Real energy = 0;
  Real f = 0;
  Real r = 0;
  Vec3 unit = Vec3::Zero();
  Mat3 jac = Mat3::Zero();
  bool active = false;  ///< false when the term exerts no force (stretch: r < L; bending: r >= L)
};

/// Tension-only stretch/shear spring, eqs (10)-(12) (with the notes' erratum: x x^T / |x|^2):
///   r >= L:  E = k (r - L)^2 / 2,   f = k (r - L),   J = k u u^T + k (1 - L/r) (I - u u^T)
///   r <  L:  E = 0, f = 0, J = 0.
/// k [N/m]. Exact Jacobian; for r >= L it is positive semi-definite (0 <= 1 - L/r < 1).
bool tensionOnlySpring(const Vec3& xi, const Vec3& xj, Real rest, Real k, bool want_jacobian,
                       PairTermResult* out);

/// Which Jacobian a bending unit contributes (the force is the same for all three).
enum class BendingJacobian {
  /// Eq (7) in full, J = (F0/L) df* u u^T + (f/r)(I - u u^T): the exact derivative of the force, but
  /// indefinite (f < 0), so the implicit system can become singular (used by the tests).
  kExact,
  /// The seed's choice: eq (7) without its negative second term, J = (F0/L) df* u u^T; -J is
  /// positive semi-definite.
  kDropNegative,
  /// kDropNegative with the secant slope where it is steeper: J = (F0/L) max(df*, |f*| / u) u u^T
  /// (u = 1 - r/L). The linearised force then falls to 0 at r = L instead of staying near P_cr while
  /// a unit straightens within one step (an extension of this package, docs/choi_ko.md).
  kSecant,
};
std::string toString(BendingJacobian j);
/// Parses "exact", "drop_negative", "secant"; throws std::invalid_argument otherwise.
BendingJacobian bendingJacobianFromString(const std::string& s);

/// Immediate-buckling bending unit with the linear law above (eqs (3)-(9) and the linear segment):
/// r < L: f = F0 f*(r/L), E = F0 L e(r/L),
///   J = (F0/L) df* u u^T + (f/r) (I - u u^T)      (eq (7), read as df_i/dx_j per the notes)
/// The second term is negative (f < 0); see BendingJacobian for what is kept. r >= L: no force
/// (stretch is type 1's job). F0 [N] = W B / L^3.
bool bucklingUnit(const Vec3& xi, const Vec3& xj, Real rest, Real f0, const BucklingLaw& law,
                  bool want_jacobian, BendingJacobian mode, PairTermResult* out);
/// The block J for a unit with force f (= F0 f*), slope df (= d(f*/F0)/ds) and deficit u, per mode.
/// With kDropNegative / kSecant a negative df (softening hysteresis branch) is clamped to 0.
Mat3 bendingJacobianBlock(const Vec3& unit, Real r, Real rest, Real f0, Real f, Real df, Real u, BendingJacobian mode);

/// Hysteretic bending force from a moment M(X) at signed curvature X = sign * kappa (notes 4.5,
/// virtual work): f = W sign M(X) dkappa/dr. Written with M = Mt X + R (Mt the tangent of the active
/// branch, R the remainder) to avoid cancellation:
///   f/F0  = (Mt/B) g + sign (R L / B) k1,      d(f/F0)/ds = (Mt/B) dg + sign (R L / B) k2,
/// with F0 = W B / L^3 and B the reference rigidity used for F0. For M = B X this is exactly the
/// linear law's buckling curve. The linear segment bounds the magnitude, |f| <= gamma F0 (1 - s)
/// (the residual moment would otherwise give |f| ~ 1/theta as r -> L, notes 4.5), keeping its sign.
/// Outputs in units of F0 (f, df) plus whether the bound was active. The energy is not defined
/// (path dependent) and is left 0.
struct HystereticBendingScalar {
  Real f = 0;
  Real df = 0;     ///< exact d(f/F0)/ds of the returned f (may be negative on softening branches)
  bool clamped = false;
};
HystereticBendingScalar hystereticBending(const BucklingShape& shape, Real u, Real sign, Real moment,
                                          Real tangent, Real rest, Real reference_rigidity,
                                          const BucklingLaw& law);

// ---- hysteresis (moment per unit width [N] vs curvature [1/m]) -----------------------------------

/// Parameters of a Choi–Ko hysteresis model (seed Figs 10, 11; notes section 4). Moments are per unit
/// width [N = N m/m], curvatures in 1/m, stiffnesses in N m.
///  * discrete: n + 1 springs and n slip units: a spring K_0 in parallel with n branches, branch i a
///    spring K_i in series with a slip unit of critical moment sigma_i:
///      M = K_0 X + sum_i K_i (X - p_i),  |K_i (X - p_i)| <= sigma_i  (p_i: slip of unit i);
///  * continuous: n -> infinity with equal springs and yield curvatures spread uniformly over
///    [x_a, x_b] (total branch stiffness k_sum, so |dM'/dX| = K = k_sum / (x_b - x_a) on loading and
///    K/2 on the unloading curve): virgin curve
///      F_v(X) = k0 X + k_sum phi(|X|) sign X,  phi(a) = a (a <= x_a),
///      a - (a - x_a)^2 / (2 (x_b - x_a)) (x_a < a < x_b),  (x_a + x_b)/2 (a >= x_b),
///    and after reversals Masing's rule with memory: from reversal (X_r, F_r) the curve is
///    F_r + 2 F_v((X - X_r)/2); when it reaches the previous reversal point the inner loop closes and
///    the outer branch continues (exactly the response of the infinite slip-unit model).
struct HysteresisSpec {
  enum class Kind { kNone, kDiscrete, kContinuous };
  Kind kind = Kind::kNone;
  std::vector<Real> stiffness;    ///< discrete: K_0 .. K_n [N m] (n + 1 values, all > 0 except K_0 >= 0)
  std::vector<Real> slip_moment;  ///< discrete: sigma_1 .. sigma_n [N] (> 0)
  Real k0 = 0;                    ///< continuous: elastic spring [N m] (>= 0)
  Real k_sum = 0;                 ///< continuous: total stiffness of the slip branches [N m] (> 0)
  Real yield_min = 0;             ///< continuous: x_a [1/m] (>= 0)
  Real yield_max = 0;             ///< continuous: x_b [1/m] (>= x_a, > 0)

  static HysteresisSpec none() { return {}; }
  static HysteresisSpec discrete(std::vector<Real> stiffness, std::vector<Real> slip_moment);
  static HysteresisSpec continuous(Real k0, Real k_sum, Real yield_min, Real yield_max);
  /// Continuous model from KES-B data: B [N m] (slope at large curvature, where every slip unit
  /// slides: k0 = B) and 2HB [N] (moment width of the loop there: k_sum (x_a + x_b) = 2HB), with an
  /// assumed yield range [x_a, x_b] [1/m] (KES does not measure it).
  static HysteresisSpec continuousFromKes(Real bending_rigidity, Real two_hb, Real yield_min, Real yield_max);

  bool enabled() const { return kind != Kind::kNone; }
  int numSlipUnits() const { return static_cast<int>(slip_moment.size()); }
  /// Slope dM/dX at the origin of the virgin curve [N m].
  Real initialSlope() const;
  /// Virgin (first-loading) curve and its slope.
  Real virginMoment(Real x, Real* tangent = nullptr) const;
  bool valid(std::string* error) const;
};

/// State of one hysteresis unit: the committed curvature, plus the slip offsets p_i (discrete) or
/// the stack of reversal points (X, M) (continuous; oldest first).
struct HysteresisState {
  Real x = 0;
  std::vector<Real> slip;                      ///< discrete: p_1 .. p_n
  std::vector<std::array<Real, 2>> reversals;  ///< continuous
  /// At most this many reversal points are kept: beyond it the two most recent ones (the smallest
  /// open loop) are forgotten, a small jump when that loop would have closed (docs/choi_ko.md).
  static constexpr int kMaxReversals = 64;
  /// Fresh state (flat, never bent) for a spec.
  static HysteresisState initial(const HysteresisSpec& spec);
};

/// Moment M(X) for the path committed -> X (monotone), without changing the state; optional tangent
/// dM/dX of the branch in use (discrete: K_0 + springs of non-sliding branches; continuous: the
/// Masing branch's slope). Rate-independent and exact for a monotone path between the two.
Real hysteresisMoment(const HysteresisSpec& spec, const HysteresisState& state, Real x, Real* tangent = nullptr);
/// Commits the path committed -> X to the state.
void hysteresisCommit(const HysteresisSpec& spec, HysteresisState& state, Real x);

/// A single hysteresis unit (spec + state), e.g. for driving a moment-curvature loop in tests.
class HysteresisUnit {
 public:
  explicit HysteresisUnit(HysteresisSpec spec);
  const HysteresisSpec& spec() const { return spec_; }
  const HysteresisState& state() const { return state_; }
  void setState(const HysteresisState& s) { state_ = s; }
  /// Trial moment at X (state unchanged).
  Real moment(Real x, Real* tangent = nullptr) const { return hysteresisMoment(spec_, state_, x, tangent); }
  /// Moves to X and commits; returns the moment there.
  Real drive(Real x);

 private:
  HysteresisSpec spec_;
  HysteresisState state_;
};

}  // namespace choi_ko
}  // namespace textile_handling
