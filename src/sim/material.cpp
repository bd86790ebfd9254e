// Material curves, the cotton material of the thesis, and YAML I/O.
#include "textile_handling/sim/material.h"

#include "textile_handling/sim/text_input.h"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace textile_handling {

namespace {

constexpr Real kZeroTolerance = 1e-12;

std::string fmt(Real v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
  return std::string(buf, res.ptr);
}

// Horner evaluation of c[0] + c[1] x + ... (n coefficients starting at c).
inline Real horner(const Real* c, int n, Real x) {
  Real r = 0.0;
  for (int k = n - 1; k >= 0; --k) r = r * x + c[k];
  return r;
}
// Derivative of the polynomial above.
inline Real hornerDerivative(const Real* c, int n, Real x) {
  Real r = 0.0;
  for (int k = n - 1; k >= 1; --k) r = r * x + static_cast<Real>(k) * c[k];
  return r;
}
// Antiderivative (zero at x = 0) of the polynomial above.
inline Real hornerAntiderivative(const Real* c, int n, Real x) {
  Real r = 0.0;
  for (int k = n - 1; k >= 0; --k) r = r * x + c[k] / static_cast<Real>(k + 1);
  return r * x;
}

}  // namespace

// ---------------------------------------------------------------------------
// MaterialCurve
// ---------------------------------------------------------------------------

MaterialCurve::MaterialCurve() : coefficients_{{0.0}} { buildCache(); }

MaterialCurve MaterialCurve::polynomial(std::vector<Real> breakpoints_after_zero,
                                        std::vector<std::vector<Real>> coefficients) {
  MaterialCurve c;
  c.kind_ = Kind::kPolynomial;
  c.breakpoints_ = std::move(breakpoints_after_zero);
  c.coefficients_ = std::move(coefficients);
  c.buildCache();
  return c;
}

MaterialCurve MaterialCurve::table(std::vector<Real> x, std::vector<Real> y) {
  MaterialCurve c;
  c.kind_ = Kind::kTable;
  c.coefficients_.clear();
  c.table_x_ = std::move(x);
  c.table_y_ = std::move(y);
  c.buildCache();
  return c;
}

MaterialCurve MaterialCurve::linear(Real slope) { return polynomial({}, {{0.0, slope}}); }

void MaterialCurve::buildCache() {
  starts_.clear();
  flat_.clear();
  offsets_.clear();
  seg_slope_.clear();
  cum_.clear();
  if (kind_ == Kind::kPolynomial) {
    if (coefficients_.size() != breakpoints_.size() + 1) return;
    for (const auto& piece : coefficients_)
      if (piece.empty()) return;
    starts_.push_back(0.0);
    starts_.insert(starts_.end(), breakpoints_.begin(), breakpoints_.end());
    offsets_.push_back(0);
    for (const auto& piece : coefficients_) {
      flat_.insert(flat_.end(), piece.begin(), piece.end());
      offsets_.push_back(static_cast<int>(flat_.size()));
    }
    cum_.assign(starts_.size(), 0.0);
    for (std::size_t i = 1; i < starts_.size(); ++i) {
      const Real* c = flat_.data() + offsets_[i - 1];
      const int n = offsets_[i] - offsets_[i - 1];
      cum_[i] = cum_[i - 1] + hornerAntiderivative(c, n, starts_[i]) -
                hornerAntiderivative(c, n, starts_[i - 1]);
    }
  } else {
    if (table_x_.size() != table_y_.size() || table_x_.size() < 2) return;
    const std::size_t nseg = table_x_.size() - 1;
    starts_.assign(table_x_.begin(), table_x_.begin() + static_cast<std::ptrdiff_t>(nseg));
    seg_slope_.resize(nseg);
    cum_.assign(nseg, 0.0);
    for (std::size_t i = 0; i < nseg; ++i) {
      seg_slope_[i] = (table_y_[i + 1] - table_y_[i]) / (table_x_[i + 1] - table_x_[i]);
      if (i > 0)
        cum_[i] = cum_[i - 1] + 0.5 * (table_y_[i - 1] + table_y_[i]) * (table_x_[i] - table_x_[i - 1]);
    }
  }
}

namespace {
// Index of the piece/segment containing x >= 0: the last i with starts[i] <= x.
inline std::size_t findPiece(const std::vector<Real>& starts, Real x) {
  std::size_t i = 0;
  const std::size_t n = starts.size();
  while (i + 1 < n && x >= starts[i + 1]) ++i;
  return i;
}
}  // namespace

Real MaterialCurve::valuePos(Real x) const {
  if (starts_.empty()) return std::numeric_limits<Real>::quiet_NaN();
  const std::size_t i = findPiece(starts_, x);
  if (kind_ == Kind::kPolynomial)
    return horner(flat_.data() + offsets_[i], offsets_[i + 1] - offsets_[i], x);
  return table_y_[i] + seg_slope_[i] * (x - table_x_[i]);
}

Real MaterialCurve::slopePos(Real x) const {
  if (starts_.empty()) return std::numeric_limits<Real>::quiet_NaN();
  const std::size_t i = findPiece(starts_, x);
  if (kind_ == Kind::kPolynomial)
    return hornerDerivative(flat_.data() + offsets_[i], offsets_[i + 1] - offsets_[i], x);
  return seg_slope_[i];
}

Real MaterialCurve::integralPos(Real x) const {
  if (starts_.empty()) return std::numeric_limits<Real>::quiet_NaN();
  const std::size_t i = findPiece(starts_, x);
  if (kind_ == Kind::kPolynomial) {
    const Real* c = flat_.data() + offsets_[i];
    const int n = offsets_[i + 1] - offsets_[i];
    return cum_[i] + hornerAntiderivative(c, n, x) - hornerAntiderivative(c, n, starts_[i]);
  }
  const Real dx = x - table_x_[i];
  return cum_[i] + dx * (table_y_[i] + 0.5 * seg_slope_[i] * dx);
}

Real MaterialCurve::value(Real x) const { return x < 0.0 ? -valuePos(-x) : valuePos(x); }
Real MaterialCurve::slope(Real x) const { return slopePos(std::abs(x)); }
Real MaterialCurve::integral(Real x) const { return integralPos(std::abs(x)); }

bool MaterialCurve::valid(std::string* error) const {
  auto fail = [error](const std::string& msg) {
    if (error) *error = msg;
    return false;
  };
  if (kind_ == Kind::kPolynomial) {
    if (coefficients_.size() != breakpoints_.size() + 1)
      return fail("polynomial needs one coefficient vector per piece: " +
                  std::to_string(breakpoints_.size()) + " breakpoint(s) after 0 require " +
                  std::to_string(breakpoints_.size() + 1) + " piece(s), got " +
                  std::to_string(coefficients_.size()));
    for (std::size_t i = 0; i < breakpoints_.size(); ++i) {
      const Real b = breakpoints_[i];
      if (!std::isfinite(b)) return fail("breakpoints[" + std::to_string(i) + "] is not finite");
      const Real prev = i == 0 ? 0.0 : breakpoints_[i - 1];
      if (!(b > prev))
        return fail("breakpoints must be > 0 and strictly increasing, but breakpoints[" +
                    std::to_string(i) + "] = " + fmt(b) + " <= " + fmt(prev));
    }
    for (std::size_t i = 0; i < coefficients_.size(); ++i) {
      if (coefficients_[i].empty())
        return fail("pieces[" + std::to_string(i) + "] has no coefficients");
      for (std::size_t k = 0; k < coefficients_[i].size(); ++k)
        if (!std::isfinite(coefficients_[i][k]))
          return fail("pieces[" + std::to_string(i) + "][" + std::to_string(k) + "] is not finite");
    }
    if (std::abs(coefficients_[0][0]) > kZeroTolerance)
      return fail("curve must pass through 0: F(0) = pieces[0][0] = " + fmt(coefficients_[0][0]) +
                  " (must be 0 within 1e-12)");
    return true;
  }
  if (table_x_.size() != table_y_.size())
    return fail("table x and y differ in length (" + std::to_string(table_x_.size()) + " vs " +
                std::to_string(table_y_.size()) + ")");
  if (table_x_.size() < 2)
    return fail("table needs at least 2 samples, got " + std::to_string(table_x_.size()));
  for (std::size_t i = 0; i < table_x_.size(); ++i) {
    if (!std::isfinite(table_x_[i])) return fail("table x[" + std::to_string(i) + "] is not finite");
    if (!std::isfinite(table_y_[i])) return fail("table y[" + std::to_string(i) + "] is not finite");
  }
  if (table_x_[0] != 0.0) return fail("table x must start at 0, got x[0] = " + fmt(table_x_[0]));
  for (std::size_t i = 1; i < table_x_.size(); ++i)
    if (!(table_x_[i] > table_x_[i - 1]))
      return fail("table x must be strictly increasing, but x[" + std::to_string(i) + "] = " +
                  fmt(table_x_[i]) + " <= x[" + std::to_string(i - 1) + "] = " + fmt(table_x_[i - 1]));
  if (std::abs(table_y_[0]) > kZeroTolerance)
    return fail("curve must pass through 0: F(0) = y[0] = " + fmt(table_y_[0]) +
                " (must be 0 within 1e-12)");
  return true;
}

bool operator==(const MaterialCurve& a, const MaterialCurve& b) {
  if (a.kind_ != b.kind_) return false;
  if (a.kind_ == MaterialCurve::Kind::kPolynomial)
    return a.breakpoints_ == b.breakpoints_ && a.coefficients_ == b.coefficients_;
  return a.table_x_ == b.table_x_ && a.table_y_ == b.table_y_;
}

// ---------------------------------------------------------------------------
// Material
// ---------------------------------------------------------------------------

Real Material::shearForceSI(int dir, Real angle_rad) const {
  return kGfPerCmToNPerM * shearCurve(dir).value(angle_rad);
}
Real Material::shearSlopeSI(int dir, Real angle_rad) const {
  return kGfPerCmToNPerM * shearCurve(dir).slope(angle_rad);
}
Real Material::bendMomentSI(int dir, Real curvature_per_m) const {
  return kGfCmPerCmToN * bendCurve(dir).value(curvature_per_m / 100.0);
}
Real Material::bendSlopeSI(int dir, Real curvature_per_m) const {
  // d/dkappa_SI [G * M(kappa_SI / 100)] = G * M'(kappa_SI / 100) / 100.
  return kGfCmPerCmToN * bendCurve(dir).slope(curvature_per_m / 100.0) / 100.0;
}
Real Material::shearEnergyDensitySI(int dir, Real angle_rad) const {
  return kGfPerCmToNPerM * shearCurve(dir).integral(angle_rad);
}
Real Material::bendEnergyDensitySI(int dir, Real curvature_per_m) const {
  // int_0^k G M(s/100) ds = 100 G int_0^{k/100} M(u) du.
  return 100.0 * kGfCmPerCmToN * bendCurve(dir).integral(curvature_per_m / 100.0);
}

bool Material::validate(std::string* error) const {
  auto fail = [error](const std::string& msg) {
    if (error) *error = msg;
    return false;
  };
  if (name.empty()) return fail("name must not be empty");
  if (!std::isfinite(areal_density) || !(areal_density > 0.0))
    return fail("areal_density must be finite and > 0 [kg/m^2], got " + fmt(areal_density));
  if (!std::isfinite(tension_stiffness) || !(tension_stiffness > 0.0))
    return fail("tension_stiffness must be finite and > 0 [N/m], got " + fmt(tension_stiffness));
  if (!std::isfinite(drag_coefficient) || !(drag_coefficient >= 0.0))
    return fail("drag_coefficient must be finite and >= 0, got " + fmt(drag_coefficient));
  if (!std::isfinite(fluid_density) || !(fluid_density >= 0.0))
    return fail("fluid_density must be finite and >= 0 [kg/m^3], got " + fmt(fluid_density));
  const std::pair<const char*, const MaterialCurve*> curves[] = {
      {"shear_warp", &shear_warp}, {"shear_weft", &shear_weft},
      {"bend_warp", &bend_warp},   {"bend_weft", &bend_weft}};
  for (const auto& [field, curve] : curves) {
    std::string why;
    if (!curve->valid(&why)) return fail(std::string(field) + ": " + why);
  }
  return true;
}

Material Material::cotton() {
  Material m;
  m.name = "cotton";
  // Shear force [gf/cm] vs shear angle [rad]; reference notes section 4.2.
  m.shear_warp = MaterialCurve::polynomial({0.00873}, {{0.0, 420.54446, -17993.714},
                                                       {1.3713532, 106.37421}});
  m.shear_weft = MaterialCurve::polynomial({0.00873}, {{0.0, 412.96917, -17125.983},
                                                       {1.3052208, 113.94950}});
  // Bending moment [gf*cm/cm] vs curvature [1/cm]; -0.71212121 is the corrected
  // coefficient (OCR: -0.712212123), and the middle piece has the x^2 term.
  m.bend_warp = MaterialCurve::polynomial({0.4, 2.52}, {{0.0, 0.85984849, -0.71212121},
                                                        {0.11090909, 0.30530303, -0.018939394},
                                                        {0.23118183, 0.20984848}});
  m.bend_weft = MaterialCurve::polynomial({0.5}, {{0.0, 0.43128713, -0.30257426},
                                                  {0.075643564, 0.12871287}});
  return m;
}

Material Material::linearElastic(std::string name, Real areal_density, Real shear_modulus_N_per_m,
                                 Real bending_rigidity_Nm, Real tension_stiffness) {
  Material m;
  m.name = std::move(name);
  m.areal_density = areal_density;
  m.tension_stiffness = tension_stiffness;
  // shearForceSI = kGfPerCmToNPerM * s * theta  =>  s = G / kGfPerCmToNPerM  [gf/cm/rad].
  const MaterialCurve shear = MaterialCurve::linear(shear_modulus_N_per_m / kGfPerCmToNPerM);
  // bendMomentSI = kGfCmPerCmToN * s * kappa/100  =>  s = 100 B / kGfCmPerCmToN  [gf*cm/cm per 1/cm].
  const MaterialCurve bend = MaterialCurve::linear(100.0 * bending_rigidity_Nm / kGfCmPerCmToN);
  m.shear_warp = m.shear_weft = shear;
  m.bend_warp = m.bend_weft = bend;
  return m;
}

MaterialCurve scaledCurve(const MaterialCurve& c, Real k) {
  if (c.kind() == MaterialCurve::Kind::kTable) {
    std::vector<Real> y = c.tableY();
    for (Real& v : y) v *= k;
    return MaterialCurve::table(c.tableX(), y);
  }
  std::vector<std::vector<Real>> coef = c.coefficients();
  for (auto& piece : coef)
    for (Real& v : piece) v *= k;
  return MaterialCurve::polynomial(c.breakpoints(), coef);
}

Material scaledMaterial(const Material& base, Real bending, Real shear, Real density, const std::string& name) {
  const std::pair<const char*, Real> factors[] = {{"bending", bending}, {"shear", shear}, {"density", density}};
  for (const auto& [what, k] : factors)
    if (!(std::isfinite(k) && k > 0))
      throw std::invalid_argument(std::string("material scale factor '") + what + "' must be finite and > 0, got " +
                                  std::to_string(k));
  Material m = base;
  m.name = name;
  m.bend_warp = scaledCurve(base.bend_warp, bending);
  m.bend_weft = scaledCurve(base.bend_weft, bending);
  m.shear_warp = scaledCurve(base.shear_warp, shear);
  m.shear_weft = scaledCurve(base.shear_weft, shear);
  m.areal_density = base.areal_density * density;
  return m;
}

bool operator==(const Material& a, const Material& b) {
  return a.name == b.name && a.areal_density == b.areal_density &&
         a.shear_warp == b.shear_warp && a.shear_weft == b.shear_weft &&
         a.bend_warp == b.bend_warp && a.bend_weft == b.bend_weft &&
         a.tension_stiffness == b.tension_stiffness && a.drag_coefficient == b.drag_coefficient &&
         a.fluid_density == b.fluid_density;
}

// ---------------------------------------------------------------------------
// YAML
// ---------------------------------------------------------------------------

namespace {

// Top-level keys of the material file.
constexpr const char* kKeyName = "name";
constexpr const char* kKeyDensity = "areal_density_kg_m2";
constexpr const char* kKeyTension = "tension_stiffness_N_m";
constexpr const char* kKeyDrag = "drag_coefficient";
constexpr const char* kKeyFluid = "fluid_density_kg_m3";
constexpr const char* kCurveKeys[4] = {"shear_warp", "shear_weft", "bend_warp", "bend_weft"};

class Parser {
 public:
  explicit Parser(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& msg,
                         const YAML::Node* node = nullptr) const {
    std::string where;
    if (node && node->IsDefined() && !node->Mark().is_null())
      where = " (line " + std::to_string(node->Mark().line + 1) + ")";
    throw MaterialError(source_ + ": field '" + field + "'" + where + ": " + msg);
  }

  // Checks that `map` only has keys from `allowed` and no key twice.
  void checkKeys(const YAML::Node& map, const std::string& prefix,
                 const std::set<std::string>& allowed) const {
    std::set<std::string> seen;
    for (const auto& kv : map) {
      const YAML::Node& key = kv.first;
      if (!key.IsScalar()) fail(prefix.empty() ? "<key>" : prefix, "keys must be plain strings", &key);
      const std::string k = key.Scalar();
      const std::string full = prefix.empty() ? k : prefix + "." + k;
      if (!allowed.count(k)) {
        std::string list;
        for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
        fail(full, "unknown field (allowed: " + list + ")", &key);
      }
      if (!seen.insert(k).second) fail(full, "duplicate field", &key);
    }
  }

  // Lists are bounded before anything is copied (kMaxMaterialListLength, docs/materials.md).
  void checkListLength(const YAML::Node& node, const std::string& field) const {
    if (node.size() > kMaxMaterialListLength)
      fail(field, "has " + std::to_string(node.size()) + " items, more than the limit of " +
                      std::to_string(kMaxMaterialListLength), &node);
  }

  Real number(const YAML::Node& node, const std::string& field) const {
    if (!node.IsDefined() || node.IsNull()) fail(field, "missing value (expected a number)", &node);
    if (!node.IsScalar()) fail(field, "expected a number, got a " + typeName(node), &node);
    Real v = 0.0;
    try {
      v = node.as<Real>();
    } catch (const YAML::Exception&) {
      fail(field, "expected a number, got '" + node.Scalar() + "'", &node);
    }
    if (!std::isfinite(v)) fail(field, "must be finite, got " + node.Scalar(), &node);
    return v;
  }

  std::vector<Real> numberList(const YAML::Node& node, const std::string& field) const {
    if (!node.IsDefined() || node.IsNull()) fail(field, "missing value (expected a list of numbers)", &node);
    if (!node.IsSequence())
      fail(field, "expected a list of numbers, got a " + typeName(node), &node);
    checkListLength(node, field);
    std::vector<Real> out;
    out.reserve(node.size());
    for (std::size_t i = 0; i < node.size(); ++i) {
      const YAML::Node item = node[i];
      out.push_back(number(item, field + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  MaterialCurve curve(const YAML::Node& node, const std::string& field) const {
    if (!node.IsMap())
      fail(field, "expected a curve mapping {type: polynomial|table|linear, ...}, got a " +
                      typeName(node), &node);
    const YAML::Node type_node = node["type"];
    if (!type_node.IsDefined()) fail(field + ".type", "missing field (polynomial, table or linear)", &node);
    if (!type_node.IsScalar()) fail(field + ".type", "expected a string", &type_node);
    const std::string type = type_node.Scalar();
    MaterialCurve c;
    if (type == "polynomial") {
      checkKeys(node, field, {"type", "breakpoints", "pieces"});
      std::vector<Real> bp;
      if (node["breakpoints"].IsDefined()) bp = numberList(node["breakpoints"], field + ".breakpoints");
      const YAML::Node pieces = node["pieces"];
      if (!pieces.IsDefined()) fail(field + ".pieces", "missing field", &node);
      if (!pieces.IsSequence())
        fail(field + ".pieces", "expected a list of coefficient lists, got a " + typeName(pieces), &pieces);
      checkListLength(pieces, field + ".pieces");
      std::vector<std::vector<Real>> coeffs;
      for (std::size_t i = 0; i < pieces.size(); ++i) {
        const std::string pf = field + ".pieces[" + std::to_string(i) + "]";
        const YAML::Node piece = pieces[i];
        coeffs.push_back(numberList(piece, pf));
        if (coeffs.back().empty()) fail(pf, "a piece needs at least one coefficient", &piece);
      }
      if (coeffs.size() != bp.size() + 1)
        fail(field + ".pieces", "expected " + std::to_string(bp.size() + 1) + " piece(s) for " +
                                    std::to_string(bp.size()) + " breakpoint(s), got " +
                                    std::to_string(coeffs.size()), &pieces);
      c = MaterialCurve::polynomial(std::move(bp), std::move(coeffs));
    } else if (type == "table") {
      checkKeys(node, field, {"type", "x", "y"});
      if (!node["x"].IsDefined()) fail(field + ".x", "missing field", &node);
      if (!node["y"].IsDefined()) fail(field + ".y", "missing field", &node);
      c = MaterialCurve::table(numberList(node["x"], field + ".x"), numberList(node["y"], field + ".y"));
    } else if (type == "linear") {
      checkKeys(node, field, {"type", "slope"});
      if (!node["slope"].IsDefined()) fail(field + ".slope", "missing field", &node);
      c = MaterialCurve::linear(number(node["slope"], field + ".slope"));
    } else {
      fail(field + ".type", "unknown curve type '" + type + "' (expected polynomial, table or linear)",
           &type_node);
    }
    std::string why;
    if (!c.valid(&why)) fail(field, "invalid curve: " + why, &node);
    return c;
  }

  Material material(const YAML::Node& root) const {
    if (!root.IsDefined() || root.IsNull()) fail("<document>", "empty document, expected a mapping");
    if (!root.IsMap()) fail("<document>", "expected a mapping at top level, got a " + typeName(root), &root);
    checkKeys(root, "", {kKeyName, kKeyDensity, kKeyTension, kKeyDrag, kKeyFluid, kCurveKeys[0],
                         kCurveKeys[1], kCurveKeys[2], kCurveKeys[3]});
    Material m;
    const YAML::Node name = root[kKeyName];
    if (!name.IsDefined()) fail(kKeyName, "missing required field");
    if (!name.IsScalar() || name.Scalar().empty()) fail(kKeyName, "expected a non-empty string", &name);
    m.name = name.Scalar();

    auto required = [&](const char* key) {
      const YAML::Node n = root[key];
      if (!n.IsDefined()) fail(key, "missing required field");
      return number(n, key);
    };
    auto optional = [&](const char* key, Real fallback) {
      const YAML::Node n = root[key];
      return n.IsDefined() ? number(n, key) : fallback;
    };
    m.areal_density = required(kKeyDensity);
    if (!(m.areal_density > 0.0)) fail(kKeyDensity, "must be > 0 [kg/m^2], got " + fmt(m.areal_density), nullptr);
    m.tension_stiffness = required(kKeyTension);
    if (!(m.tension_stiffness > 0.0))
      fail(kKeyTension, "must be > 0 [N/m], got " + fmt(m.tension_stiffness));
    const Material defaults;
    m.drag_coefficient = optional(kKeyDrag, defaults.drag_coefficient);
    if (!(m.drag_coefficient >= 0.0)) fail(kKeyDrag, "must be >= 0, got " + fmt(m.drag_coefficient));
    m.fluid_density = optional(kKeyFluid, defaults.fluid_density);
    if (!(m.fluid_density >= 0.0)) fail(kKeyFluid, "must be >= 0 [kg/m^3], got " + fmt(m.fluid_density));

    MaterialCurve* targets[4] = {&m.shear_warp, &m.shear_weft, &m.bend_warp, &m.bend_weft};
    for (int i = 0; i < 4; ++i) {
      const YAML::Node n = root[kCurveKeys[i]];
      if (!n.IsDefined()) fail(kCurveKeys[i], "missing required curve");
      *targets[i] = curve(n, kCurveKeys[i]);
    }
    std::string why;
    if (!m.validate(&why)) throw MaterialError(source_ + ": invalid material: " + why);
    return m;
  }

  Material parseText(const std::string& text) const {
    const std::string too_large = textSizeError("material text", text.size(), kMaxYamlDocumentBytes);
    if (!too_large.empty()) throw MaterialError(source_ + ": " + too_large);
    YAML::Node root;
    try {
      root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
      throw MaterialError(source_ + ": malformed YAML: " + e.what());
    }
    try {
      return material(root);
    } catch (const MaterialError&) {
      throw;
    } catch (const YAML::Exception& e) {  // defensive: should not happen
      throw MaterialError(source_ + ": YAML error: " + e.what());
    }
  }

 private:
  static std::string typeName(const YAML::Node& n) {
    switch (n.Type()) {
      case YAML::NodeType::Null: return "null";
      case YAML::NodeType::Scalar: return "scalar";
      case YAML::NodeType::Sequence: return "list";
      case YAML::NodeType::Map: return "mapping";
      default: return "undefined node";
    }
  }

  std::string source_;
};

std::string listToYaml(const std::vector<Real>& v) {
  std::string s = "[";
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + fmt(v[i]);
  return s + "]";
}

std::string curveToYaml(const MaterialCurve& c) {
  if (c.kind() == MaterialCurve::Kind::kTable)
    return "{type: table, x: " + listToYaml(c.tableX()) + ", y: " + listToYaml(c.tableY()) + "}";
  std::string s = "{type: polynomial, breakpoints: " + listToYaml(c.breakpoints()) + ", pieces: [";
  for (std::size_t i = 0; i < c.coefficients().size(); ++i)
    s += (i ? ", " : "") + listToYaml(c.coefficients()[i]);
  return s + "]}";
}

}  // namespace

Material parseMaterialYaml(const std::string& text) { return Parser("<string>").parseText(text); }

Material loadMaterialYaml(const std::string& path) {
  std::string text, error;
  if (!readBoundedTextFile(path, kMaxYamlDocumentBytes, &text, &error))
    throw MaterialError(path + ": cannot read material file: " + error);
  return Parser(path).parseText(text);
}

std::string materialToYaml(const Material& m) {
  YAML::Emitter name_out;
  name_out << m.name;  // quotes the name where YAML needs it
  std::ostringstream o;
  o << "# Textile material; format and units: docs/materials.md\n"
    << kKeyName << ": " << name_out.c_str() << "\n"
    << kKeyDensity << ": " << fmt(m.areal_density) << "  # kg/m^2\n"
    << kKeyTension << ": " << fmt(m.tension_stiffness)
    << "  # N/m; membrane force per width = Y * strain^4\n"
    << kKeyDrag << ": " << fmt(m.drag_coefficient) << "  # c_w, dimensionless\n"
    << kKeyFluid << ": " << fmt(m.fluid_density) << "  # kg/m^3\n"
    << "# KES shear force per unit length [gf/cm] vs shear angle [rad]\n"
    << "shear_warp: " << curveToYaml(m.shear_warp) << "\n"
    << "shear_weft: " << curveToYaml(m.shear_weft) << "\n"
    << "# KES bending moment per unit width [gf*cm/cm] vs curvature [1/cm]\n"
    << "bend_warp: " << curveToYaml(m.bend_warp) << "\n"
    << "bend_weft: " << curveToYaml(m.bend_weft) << "\n";
  return o.str();
}

}  // namespace textile_handling
