// Textile material model: Kawabata (KES) shear and bending curves plus the
// scalar parameters of the cloth simulator (density, stretch law, drag).
//
// Unit conventions
//   * The curves are stored in the units in which KES data are published:
//       shear force per unit length   [gf/cm]     vs. shear angle  [rad]
//       bending moment per unit width [gf*cm/cm]  vs. curvature    [1/cm]
//     (the thesis fed the bending *angle* in rad into the bending curve; we
//     feed the curvature in 1/cm, which is what the KES-B abscissa measures).
//   * Everything a simulator needs is available in SI through the *SI helper
//     methods of Material (N/m, N*m/m = N, J/m^2), which do the conversion
//     with kGramForce from types.h.
//
// yaml-cpp is used only in material.cpp; this header stays light.
// See docs/materials.md for the YAML file format.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

// Thrown by the YAML loader / parser on any malformed, missing or invalid input.
// The message names the source (file path or "<string>") and the offending field.
class MaterialError : public std::runtime_error {
 public:
  explicit MaterialError(const std::string& what) : std::runtime_error(what) {}
};

// A single-valued material curve y = F(x), meant for x >= 0 (callers pass |angle|
// or |curvature|). Units are those of the owning Material field.
//
// Two representations:
//   * Polynomial: breakpoints b_0 = 0 < b_1 < ... < b_{n-1}; piece i is used on
//     [b_i, b_{i+1}) and the last piece extends to +infinity. Each piece has its
//     own coefficient vector in ascending powers of the *absolute* x:
//     F(x) = c0 + c1 x + c2 x^2 + ...
//   * Table: samples (x_k, y_k) with x_0 = 0 < x_1 < ...; piecewise-linear
//     interpolation, and linear extrapolation of the last segment beyond x_last.
//
// Negative x: the curve is extended as an odd function, F(-x) = -F(x) (so the
// slope is even and the integral is even). Callers passing |x| are unaffected;
// callers passing a signed angle get the signed force / moment.
//
// value(), slope() and integral() do not allocate (a short linear scan over the
// pieces). Evaluating a curve that is structurally inconsistent (e.g. table x and
// y of different lengths; see valid()) returns NaN.
class MaterialCurve {
 public:
  enum class Kind { kPolynomial, kTable };

  // The zero curve F(x) = 0 (one polynomial piece with coefficients {0}).
  MaterialCurve();

  // Piecewise polynomial. `breakpoints_after_zero` are b_1 < b_2 < ... (b_0 = 0 is
  // implicit); `coefficients` holds breakpoints_after_zero.size() + 1 pieces, each
  // in ascending powers of x. Never throws; check valid() afterwards.
  static MaterialCurve polynomial(std::vector<Real> breakpoints_after_zero,
                                  std::vector<std::vector<Real>> coefficients);
  // Piecewise-linear table through (x[k], y[k]); x[0] must be 0 and x strictly
  // increasing (at least two samples). Never throws; check valid() afterwards.
  static MaterialCurve table(std::vector<Real> x, std::vector<Real> y);
  // The straight line F(x) = slope * x (a one-piece polynomial {0, slope}).
  static MaterialCurve linear(Real slope);

  // F(x), in the curve's y unit.
  Real value(Real x) const;
  // dF/dx at x, in (y unit)/(x unit). At a breakpoint the right-hand piece is used.
  Real slope(Real x) const;
  // Integral of F from 0 to x, in (y unit)*(x unit); analytic for both forms.
  Real integral(Real x) const;

  // True if the curve is well-formed: polynomial breakpoints finite, > 0 and
  // strictly increasing, one non-empty coefficient vector per piece, all
  // coefficients finite, F(0) == 0 within 1e-12 (absolute); table: x and y of
  // equal length >= 2, all finite, x[0] == 0, x strictly increasing,
  // |y[0]| <= 1e-12. On failure writes a human-readable reason to *error (if non-null).
  // Continuity across breakpoints is not checked.
  bool valid(std::string* error) const;

  Kind kind() const { return kind_; }
  // Polynomial form: breakpoints without the implicit leading 0 (as passed to polynomial()).
  const std::vector<Real>& breakpoints() const { return breakpoints_; }
  // Polynomial form: one coefficient vector per piece, ascending powers.
  const std::vector<std::vector<Real>>& coefficients() const { return coefficients_; }
  // Table form: sample abscissae and ordinates.
  const std::vector<Real>& tableX() const { return table_x_; }
  const std::vector<Real>& tableY() const { return table_y_; }

  // Exact equality of representation and all numbers (not of the function).
  friend bool operator==(const MaterialCurve& a, const MaterialCurve& b);
  friend bool operator!=(const MaterialCurve& a, const MaterialCurve& b) { return !(a == b); }

 private:
  void buildCache();
  // Evaluation on x >= 0 (the odd extension is applied by the public methods).
  Real valuePos(Real x) const;
  Real slopePos(Real x) const;
  Real integralPos(Real x) const;

  Kind kind_ = Kind::kPolynomial;
  std::vector<Real> breakpoints_;                 // polynomial: b_1..b_{n-1}
  std::vector<std::vector<Real>> coefficients_;   // polynomial: n pieces
  std::vector<Real> table_x_, table_y_;           // table samples

  // Evaluation cache (built by the factories; empty if structurally inconsistent).
  std::vector<Real> starts_;      // piece/segment start abscissae (starts_[0] = 0)
  std::vector<Real> flat_;        // polynomial: all coefficients, concatenated
  std::vector<int> offsets_;      // polynomial: piece i coefficients are flat_[offsets_[i] .. offsets_[i+1])
  std::vector<Real> seg_slope_;   // table: slope of segment i (last one is extrapolated)
  std::vector<Real> cum_;         // integral of F from 0 to starts_[i]
};

// Material parameters of one textile. Direction index: 0 = warp, 1 = weft.
//
// A default-constructed Material has the cotton scalar defaults below, zero
// curves and an empty name (so it does not validate() until named); use
// Material::cotton() for the thesis cotton.
struct Material {
  static constexpr int kWarp = 0;
  static constexpr int kWeft = 1;

  // Human-readable identifier, non-empty.
  std::string name;
  // Mass per unit area [kg/m^2]. Not given by the thesis; 0.25 kg/m^2 (250 g/m^2,
  // a medium-weight woven cotton such as a tablecloth) is our cotton default.
  Real areal_density = 0.25;

  // KES shear force per unit length [gf/cm] vs. shear angle [rad] (x >= 0).
  MaterialCurve shear_warp, shear_weft;
  // KES bending moment per unit width [gf*cm/cm] vs. curvature [1/cm] (x >= 0).
  // NOTE: the thesis evaluated these curves at the bending angle in rad; we use
  // curvature (the KES-B abscissa), see docs/materials.md.
  MaterialCurve bend_warp, bend_weft;

  // Constant Y [N/m] of the quintic stretch law: membrane force per unit width
  // = Y * strain^4 (energy density Y/5 * strain^5). A reparametrisation of the
  // thesis's hand-tuned Breen constant C0, which the thesis never reports.
  // Default 1e8 N/m (a strain of 1% then gives 1 N/m).
  Real tension_stiffness = 1.0e8;
  // Drag coefficient c_w [-] of the isotropic quadratic drag -1/2 rho c_w A |v| v.
  Real drag_coefficient = 1.0;
  // Density rho of the surrounding fluid [kg/m^3]; 1.2 = air at 20 C
  // (the thesis treats it as a free parameter).
  Real fluid_density = 1.2;

  // Shear curve for dir (0 warp, 1 weft), gf/cm vs rad.
  const MaterialCurve& shearCurve(int dir) const { return dir == kWarp ? shear_warp : shear_weft; }
  // Bending curve for dir (0 warp, 1 weft), gf*cm/cm vs 1/cm.
  const MaterialCurve& bendCurve(int dir) const { return dir == kWarp ? bend_warp : bend_weft; }

  // Shear force per unit length [N/m] at shear angle angle_rad [rad].
  Real shearForceSI(int dir, Real angle_rad) const;
  // d(shear force per length)/d(angle) [N/m/rad].
  Real shearSlopeSI(int dir, Real angle_rad) const;
  // Bending moment per unit width [N*m/m = N] at curvature curvature_per_m [1/m].
  Real bendMomentSI(int dir, Real curvature_per_m) const;
  // d(moment per width)/d(curvature) [N*m] at curvature_per_m [1/m].
  Real bendSlopeSI(int dir, Real curvature_per_m) const;
  // Shear energy per unit area [J/m^2] = integral_0^angle shearForceSI d(theta).
  Real shearEnergyDensitySI(int dir, Real angle_rad) const;
  // Bending energy per unit area [J/m^2] = integral_0^kappa bendMomentSI d(kappa), kappa in 1/m.
  Real bendEnergyDensitySI(int dir, Real curvature_per_m) const;

  // Checks name non-empty, every scalar finite, areal_density > 0,
  // tension_stiffness > 0, drag_coefficient >= 0, fluid_density >= 0 and all four
  // curves valid(). On failure writes a message naming the field to *error (if non-null).
  bool validate(std::string* error) const;

  // The thesis cotton (KES data of Breen 1994, reference notes section 4.2), with
  // the corrected warp-bending coefficient -0.71212121 and the x^2 term of the
  // middle warp-bending piece; scalar defaults as above; name "cotton".
  static Material cotton();

  // A material with linear curves such that, exactly in SI,
  //   shearForceSI(dir, theta)  = shear_modulus_N_per_m * theta        [N/m]
  //   bendMomentSI(dir, kappa)  = bending_rigidity_Nm * kappa          [N]
  // for both directions. areal_density [kg/m^2], tension_stiffness [N/m];
  // drag_coefficient and fluid_density take the defaults above.
  static Material linearElastic(std::string name, Real areal_density, Real shear_modulus_N_per_m,
                                Real bending_rigidity_Nm, Real tension_stiffness);
};

// `curve` with every value (table entries or polynomial coefficients) multiplied by `factor`.
MaterialCurve scaledCurve(const MaterialCurve& curve, Real factor);

// `base` with both bending curves times `bending`, both shear curves times `shear` and the areal
// density times `density`, named `name` (material variation of database members and held-out
// benchmark drapes). Throws std::invalid_argument naming the factor if one is not finite and > 0.
Material scaledMaterial(const Material& base, Real bending, Real shear, Real density, const std::string& name);

// Exact equality of every field (curves compared with MaterialCurve::operator==).
bool operator==(const Material& a, const Material& b);
inline bool operator!=(const Material& a, const Material& b) { return !(a == b); }

// Conversion factors between the stored KES units and SI.
// 1 gf/cm = kGramForce / 0.01 N/m.
constexpr Real kGfPerCmToNPerM = kGramForce / 0.01;
// 1 gf*cm/cm = kGramForce N*m/m (= N).
constexpr Real kGfCmPerCmToN = kGramForce;
// Curvature: 1/m -> 1/cm.
constexpr Real kPerMeterToPerCm = 0.01;

// Longest list in a material YAML document (curve breakpoints, pieces, coefficients of a piece, table
// points): far above any measured KES curve, and it bounds the work of parsing and evaluating curves.
constexpr std::size_t kMaxMaterialListLength = 1024;

// Reads and parses a material YAML file (format: docs/materials.md). Files larger than
// kMaxYamlDocumentBytes (1 MiB, text_input.h) and files that are not regular files are refused
// before they are read.
// Throws MaterialError (message contains the path and the field) on I/O errors,
// malformed YAML, missing/unknown fields, wrong types, non-finite or out-of-range
// values, or invalid curves.
Material loadMaterialYaml(const std::string& path);
// Parses material YAML text; same errors as loadMaterialYaml (source "<string>").
Material parseMaterialYaml(const std::string& text);
// Serialises a material to YAML text that parseMaterialYaml reads back to an
// identical Material (numbers written with round-trip precision).
std::string materialToYaml(const Material& material);

}  // namespace textile_handling
