// Tests for textile_handling/sim/material.h: KES curves, cotton, SI helpers, YAML I/O.
#include "textile_handling/sim/material.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <string>
#include <vector>

#ifndef TEXTILE_HANDLING_SOURCE_DIR
#define TEXTILE_HANDLING_SOURCE_DIR "/work/main"
#endif

namespace textile_handling {
namespace {

const std::string kSourceDir = TEXTILE_HANDLING_SOURCE_DIR;

bool relClose(Real a, Real b, Real rel, Real abs_floor = 0.0) {
  return std::abs(a - b) <= rel * std::max(std::abs(a), std::abs(b)) + abs_floor;
}

// Evaluate piece i of a polynomial curve directly from its coefficients.
Real pieceValue(const MaterialCurve& c, std::size_t i, Real x) {
  Real r = 0.0;
  const auto& co = c.coefficients()[i];
  for (std::size_t k = co.size(); k-- > 0;) r = r * x + co[k];
  return r;
}
Real pieceSlope(const MaterialCurve& c, std::size_t i, Real x) {
  Real r = 0.0;
  const auto& co = c.coefficients()[i];
  for (std::size_t k = co.size(); k-- > 1;) r = r * x + static_cast<Real>(k) * co[k];
  return r;
}

// Composite Simpson rule on [a, b] with n (even) intervals.
Real simpson(const std::function<Real(Real)>& f, Real a, Real b, int n) {
  const Real h = (b - a) / n;
  Real s = f(a) + f(b);
  for (int i = 1; i < n; ++i) s += (i % 2 ? 4.0 : 2.0) * f(a + i * h);
  return s * h / 3.0;
}

struct NamedCurve {
  const char* name;
  const MaterialCurve* curve;
};

std::vector<NamedCurve> curvesOf(const Material& m) {
  return {{"shear_warp", &m.shear_warp},
          {"shear_weft", &m.shear_weft},
          {"bend_warp", &m.bend_warp},
          {"bend_weft", &m.bend_weft}};
}

// Sample points covering all pieces of the cotton curves (shear in rad, bending in 1/cm).
std::vector<Real> samplePoints() {
  std::vector<Real> xs;
  for (int i = 0; i <= 400; ++i) xs.push_back(0.0001 * i);  // 0 .. 0.04 (shear kink region)
  for (int i = 0; i <= 600; ++i) xs.push_back(0.01 * i);    // 0 .. 6 (bending range and beyond)
  xs.push_back(0.00873);
  xs.push_back(0.4);
  xs.push_back(0.5);
  xs.push_back(2.52);
  xs.push_back(25.0);
  return xs;
}

// ---------------------------------------------------------------------------
// MaterialCurve
// ---------------------------------------------------------------------------

TEST(MaterialCurve, DefaultIsZeroCurve) {
  const MaterialCurve c;
  std::string err;
  EXPECT_TRUE(c.valid(&err)) << err;
  EXPECT_EQ(c.value(1.3), 0.0);
  EXPECT_EQ(c.slope(1.3), 0.0);
  EXPECT_EQ(c.integral(1.3), 0.0);
}

TEST(MaterialCurve, LinearPolynomialAndTable) {
  const MaterialCurve lin = MaterialCurve::linear(2.5);
  EXPECT_DOUBLE_EQ(lin.value(3.0), 7.5);
  EXPECT_DOUBLE_EQ(lin.slope(3.0), 2.5);
  EXPECT_DOUBLE_EQ(lin.integral(3.0), 0.5 * 2.5 * 9.0);

  // F = x^2 on [0,1), 2x - 1 on [1, inf)  (C1 at 1).
  const MaterialCurve poly = MaterialCurve::polynomial({1.0}, {{0.0, 0.0, 1.0}, {-1.0, 2.0}});
  std::string err;
  ASSERT_TRUE(poly.valid(&err)) << err;
  EXPECT_DOUBLE_EQ(poly.value(0.5), 0.25);
  EXPECT_DOUBLE_EQ(poly.value(3.0), 5.0);
  EXPECT_DOUBLE_EQ(poly.slope(0.5), 1.0);
  EXPECT_DOUBLE_EQ(poly.slope(3.0), 2.0);
  EXPECT_DOUBLE_EQ(poly.integral(0.5), 0.125 / 3.0);
  // int_0^1 x^2 = 1/3, int_1^3 (2x-1) = (9-3) - (1-1) = 6.
  EXPECT_DOUBLE_EQ(poly.integral(3.0), 1.0 / 3.0 + 6.0);

  const MaterialCurve tab = MaterialCurve::table({0.0, 0.5, 1.0}, {0.0, 0.14, 0.2});
  ASSERT_TRUE(tab.valid(&err)) << err;
  EXPECT_DOUBLE_EQ(tab.value(0.25), 0.07);
  EXPECT_DOUBLE_EQ(tab.value(0.75), 0.17);
  EXPECT_DOUBLE_EQ(tab.value(2.0), 0.32);  // linear extrapolation of the last segment
  EXPECT_DOUBLE_EQ(tab.slope(0.25), 0.28);
  EXPECT_DOUBLE_EQ(tab.slope(2.0), 0.12);
  EXPECT_DOUBLE_EQ(tab.integral(0.5), 0.5 * 0.5 * 0.14);
  EXPECT_DOUBLE_EQ(tab.integral(2.0), 0.035 + 0.5 * (0.14 + 0.2) * 0.5 + 0.5 * (0.2 + 0.32) * 1.0);
}

TEST(MaterialCurve, NegativeArgumentIsOddExtension) {
  const Material m = Material::cotton();
  const MaterialCurve tab = MaterialCurve::table({0.0, 0.5, 1.0}, {0.0, 0.14, 0.2});
  for (const MaterialCurve* c : {&m.shear_warp, &m.bend_warp, &tab}) {
    for (Real x : {0.003, 0.3, 1.7, 4.0}) {
      EXPECT_EQ(c->value(-x), -c->value(x));
      EXPECT_EQ(c->slope(-x), c->slope(x));
      EXPECT_EQ(c->integral(-x), c->integral(x));
    }
  }
}

TEST(MaterialCurve, StructurallyBrokenCurveIsInvalidAndEvaluatesToNaN) {
  std::string err;
  const MaterialCurve bad_table = MaterialCurve::table({0.0, 1.0}, {0.0});
  EXPECT_FALSE(bad_table.valid(&err));
  EXPECT_NE(err.find("differ in length"), std::string::npos) << err;
  EXPECT_TRUE(std::isnan(bad_table.value(0.5)));

  const MaterialCurve bad_poly = MaterialCurve::polynomial({1.0}, {{0.0, 1.0}});
  EXPECT_FALSE(bad_poly.valid(&err));
  EXPECT_NE(err.find("piece"), std::string::npos) << err;
  EXPECT_TRUE(std::isnan(bad_poly.slope(0.5)));
  EXPECT_TRUE(std::isnan(bad_poly.integral(0.5)));
}

TEST(MaterialCurve, ValidityChecks) {
  std::string err;
  EXPECT_FALSE(MaterialCurve::polynomial({0.5, 0.5}, {{0.0, 1.0}, {0.0, 1.0}, {0.0, 1.0}}).valid(&err));
  EXPECT_NE(err.find("strictly increasing"), std::string::npos) << err;
  EXPECT_FALSE(MaterialCurve::polynomial({0.0}, {{0.0, 1.0}, {0.0, 1.0}}).valid(&err));
  EXPECT_FALSE(MaterialCurve::polynomial({}, {{1e-9, 1.0}}).valid(&err));
  EXPECT_NE(err.find("F(0)"), std::string::npos) << err;
  EXPECT_TRUE(MaterialCurve::polynomial({}, {{1e-13, 1.0}}).valid(&err)) << err;
  EXPECT_FALSE(MaterialCurve::polynomial({}, {{0.0, NAN}}).valid(&err));
  EXPECT_NE(err.find("not finite"), std::string::npos) << err;
  EXPECT_FALSE(MaterialCurve::polynomial({}, {{}}).valid(&err));
  EXPECT_FALSE(MaterialCurve::table({0.1, 1.0}, {0.0, 1.0}).valid(&err));
  EXPECT_NE(err.find("start at 0"), std::string::npos) << err;
  EXPECT_FALSE(MaterialCurve::table({0.0, 1.0, 1.0}, {0.0, 1.0, 2.0}).valid(&err));
  EXPECT_FALSE(MaterialCurve::table({0.0, 1.0}, {0.01, 1.0}).valid(&err));
  EXPECT_FALSE(MaterialCurve::table({0.0}, {0.0}).valid(&err));
  EXPECT_FALSE(MaterialCurve::table({0.0, INFINITY}, {0.0, 1.0}).valid(&err));
  EXPECT_TRUE(MaterialCurve::table({0.0, 1.0}, {0.0, 1.0}).valid(nullptr));
}

// ---------------------------------------------------------------------------
// Cotton
// ---------------------------------------------------------------------------

TEST(Cotton, ValidAndZeroAtOrigin) {
  const Material m = Material::cotton();
  std::string err;
  EXPECT_TRUE(m.validate(&err)) << err;
  EXPECT_EQ(m.name, "cotton");
  for (const auto& nc : curvesOf(m)) {
    EXPECT_EQ(nc.curve->value(0.0), 0.0) << nc.name;
    EXPECT_EQ(nc.curve->integral(0.0), 0.0) << nc.name;
    EXPECT_GT(nc.curve->slope(0.0), 0.0) << nc.name;
  }
}

TEST(Cotton, CurvesAreC1AtEveryBreakpoint) {
  const Material m = Material::cotton();
  int checked = 0;
  for (const auto& nc : curvesOf(m)) {
    const MaterialCurve& c = *nc.curve;
    ASSERT_EQ(c.kind(), MaterialCurve::Kind::kPolynomial);
    for (std::size_t i = 0; i < c.breakpoints().size(); ++i) {
      const Real b = c.breakpoints()[i];
      const Real vl = pieceValue(c, i, b), vr = pieceValue(c, i + 1, b);
      const Real sl = pieceSlope(c, i, b), sr = pieceSlope(c, i + 1, b);
      EXPECT_TRUE(relClose(vl, vr, 1e-4)) << nc.name << " value at " << b << ": " << vl << " vs " << vr;
      EXPECT_TRUE(relClose(sl, sr, 1e-4)) << nc.name << " slope at " << b << ": " << sl << " vs " << sr;
      // The curve object itself agrees just left / right of the breakpoint.
      const Real eps = 1e-9 * b;
      EXPECT_TRUE(relClose(c.value(b - eps), c.value(b + eps), 1e-4)) << nc.name;
      EXPECT_TRUE(relClose(c.slope(b - eps), c.slope(b + eps), 1e-4)) << nc.name;
      ++checked;
    }
  }
  EXPECT_EQ(checked, 5);
  // Values quoted in the reference notes (section 4.2).
  EXPECT_NEAR(m.shear_warp.value(0.00873), 2.3000, 1e-3);
  EXPECT_NEAR(m.shear_weft.value(0.00873), 2.3000, 1e-3);
  EXPECT_NEAR(m.bend_warp.value(0.4), 0.2300, 1e-4);
  EXPECT_NEAR(m.bend_warp.slope(0.4), 0.29015, 1e-4);
  EXPECT_NEAR(m.bend_warp.value(2.52), 0.7600, 1e-4);
  EXPECT_NEAR(m.bend_weft.value(0.5), 0.1400, 1e-4);
  EXPECT_NEAR(m.bend_weft.slope(0.5), 0.12871, 1e-5);
}

TEST(Cotton, SlopeMatchesCentralDifferences) {
  const Material m = Material::cotton();
  const MaterialCurve tab = MaterialCurve::table({0.0, 0.5, 1.0, 2.0}, {0.0, 0.14, 0.2, 0.3});
  std::vector<NamedCurve> curves = curvesOf(m);
  curves.push_back({"table", &tab});
  for (const auto& nc : curves) {
    std::vector<Real> kinks = {0.0};
    if (nc.curve->kind() == MaterialCurve::Kind::kPolynomial)
      kinks.insert(kinks.end(), nc.curve->breakpoints().begin(), nc.curve->breakpoints().end());
    else
      kinks.insert(kinks.end(), nc.curve->tableX().begin(), nc.curve->tableX().end());
    for (Real x : samplePoints()) {
      const Real h = 1e-6 * std::max(x, 1e-3);
      bool near_kink = false;
      for (Real k : kinks) near_kink = near_kink || std::abs(x - k) < 2.0 * h;
      if (near_kink) continue;
      const Real fd = (nc.curve->value(x + h) - nc.curve->value(x - h)) / (2.0 * h);
      const Real s = nc.curve->slope(x);
      EXPECT_TRUE(relClose(fd, s, 1e-6, 1e-7)) << nc.name << " at x=" << x << ": fd " << fd << " vs " << s;
    }
  }
}

TEST(Cotton, IntegralMatchesQuadrature) {
  const Material m = Material::cotton();
  const MaterialCurve tab = MaterialCurve::table({0.0, 0.5, 1.0, 2.0}, {0.0, 0.14, 0.2, 0.3});
  std::vector<NamedCurve> curves = curvesOf(m);
  curves.push_back({"table", &tab});
  for (const auto& nc : curves) {
    for (Real x : {0.001, 0.00873, 0.02, 0.1, 0.45, 1.0, 2.52, 3.3, 7.0}) {
      const Real q = simpson([&](Real t) { return nc.curve->value(t); }, 0.0, x, 20000);
      const Real a = nc.curve->integral(x);
      EXPECT_TRUE(relClose(q, a, 1e-7, 1e-14)) << nc.name << " at x=" << x << ": quad " << q << " vs " << a;
    }
  }
}

// ---------------------------------------------------------------------------
// SI helpers
// ---------------------------------------------------------------------------

TEST(MaterialSI, UnitConversion) {
  const Material m = Material::cotton();
  // Curvature 100 1/m = 1 1/cm; moment in gf*cm/cm = gf -> N.
  EXPECT_DOUBLE_EQ(m.bendMomentSI(Material::kWarp, 100.0), m.bend_warp.value(1.0) * 9.80665e-3);
  EXPECT_DOUBLE_EQ(m.bendMomentSI(Material::kWeft, 100.0), m.bend_weft.value(1.0) * 9.80665e-3);
  // 1 gf/cm = 9.80665e-3 N / 0.01 m = 0.980665 N/m.
  EXPECT_DOUBLE_EQ(m.shearForceSI(Material::kWarp, 0.1), m.shear_warp.value(0.1) * 0.980665);
  EXPECT_DOUBLE_EQ(m.shearSlopeSI(Material::kWeft, 0.1), m.shear_weft.slope(0.1) * 0.980665);
  EXPECT_DOUBLE_EQ(m.shearEnergyDensitySI(Material::kWarp, 0.1), m.shear_warp.integral(0.1) * 0.980665);

  // SI slopes and energies are consistent derivatives / integrals in SI units.
  for (int dir : {0, 1}) {
    for (Real kappa : {5.0, 30.0, 70.0, 180.0, 400.0}) {  // 1/m
      const Real h = 1e-5 * kappa;
      const Real fd = (m.bendMomentSI(dir, kappa + h) - m.bendMomentSI(dir, kappa - h)) / (2 * h);
      EXPECT_TRUE(relClose(fd, m.bendSlopeSI(dir, kappa), 1e-6)) << dir << " " << kappa;
      const Real q = simpson([&](Real k) { return m.bendMomentSI(dir, k); }, 0.0, kappa, 20000);
      EXPECT_TRUE(relClose(q, m.bendEnergyDensitySI(dir, kappa), 1e-7)) << dir << " " << kappa;
    }
    for (Real th : {0.004, 0.05, 0.14}) {
      const Real q = simpson([&](Real t) { return m.shearForceSI(dir, t); }, 0.0, th, 20000);
      EXPECT_TRUE(relClose(q, m.shearEnergyDensitySI(dir, th), 1e-7)) << dir << " " << th;
    }
  }
}

TEST(MaterialSI, LinearElasticIsExactlyLinear) {
  const Real G = 3.7, B = 2.4e-5;
  const Material m = Material::linearElastic("lin", 0.18, G, B, 5.0e7);
  std::string err;
  ASSERT_TRUE(m.validate(&err)) << err;
  EXPECT_EQ(m.name, "lin");
  EXPECT_EQ(m.areal_density, 0.18);
  EXPECT_EQ(m.tension_stiffness, 5.0e7);
  for (int dir : {0, 1}) {
    for (Real x : {0.0, 1e-4, 0.01, 0.3, 1.0, 2.0, 10.0, 150.0}) {
      EXPECT_DOUBLE_EQ(m.shearForceSI(dir, x), G * x);
      EXPECT_DOUBLE_EQ(m.shearSlopeSI(dir, x), G);
      EXPECT_DOUBLE_EQ(m.shearEnergyDensitySI(dir, x), 0.5 * G * x * x);
      EXPECT_DOUBLE_EQ(m.bendMomentSI(dir, x), B * x);
      EXPECT_DOUBLE_EQ(m.bendSlopeSI(dir, x), B);
      EXPECT_DOUBLE_EQ(m.bendEnergyDensitySI(dir, x), 0.5 * B * x * x);
    }
  }
}

TEST(MaterialValidate, MessagesNameTheField) {
  std::string err;
  Material m;
  EXPECT_FALSE(m.validate(&err));
  EXPECT_NE(err.find("name"), std::string::npos) << err;

  struct Case {
    std::function<void(Material&)> mutate;
    const char* field;
  };
  const std::vector<Case> cases = {
      {[](Material& x) { x.areal_density = 0.0; }, "areal_density"},
      {[](Material& x) { x.areal_density = NAN; }, "areal_density"},
      {[](Material& x) { x.tension_stiffness = -1.0; }, "tension_stiffness"},
      {[](Material& x) { x.tension_stiffness = INFINITY; }, "tension_stiffness"},
      {[](Material& x) { x.drag_coefficient = -0.1; }, "drag_coefficient"},
      {[](Material& x) { x.fluid_density = NAN; }, "fluid_density"},
      {[](Material& x) { x.bend_weft = MaterialCurve::table({0.0, 1.0}, {0.5, 1.0}); }, "bend_weft"},
      {[](Material& x) { x.shear_warp = MaterialCurve::polynomial({0.2, 0.1}, {{0}, {0}, {0}}); },
       "shear_warp"},
  };
  for (const auto& c : cases) {
    Material x = Material::cotton();
    c.mutate(x);
    err.clear();
    EXPECT_FALSE(x.validate(&err)) << c.field;
    EXPECT_NE(err.find(c.field), std::string::npos) << c.field << ": " << err;
  }
}

// ---------------------------------------------------------------------------
// YAML
// ---------------------------------------------------------------------------

void expectSameCurves(const Material& a, const Material& b) {
  const auto ca = curvesOf(a), cb = curvesOf(b);
  for (std::size_t i = 0; i < ca.size(); ++i)
    for (Real x : samplePoints()) {
      EXPECT_EQ(ca[i].curve->value(x), cb[i].curve->value(x)) << ca[i].name << " at " << x;
      EXPECT_EQ(ca[i].curve->slope(x), cb[i].curve->slope(x)) << ca[i].name << " at " << x;
      EXPECT_EQ(ca[i].curve->integral(x), cb[i].curve->integral(x)) << ca[i].name << " at " << x;
    }
}

TEST(MaterialYaml, CottonFileEqualsBuiltin) {
  const Material loaded = loadMaterialYaml(kSourceDir + "/data/materials/cotton.yaml");
  const Material builtin = Material::cotton();
  EXPECT_TRUE(loaded == builtin);
  EXPECT_EQ(loaded.name, builtin.name);
  EXPECT_EQ(loaded.areal_density, builtin.areal_density);
  EXPECT_EQ(loaded.tension_stiffness, builtin.tension_stiffness);
  EXPECT_EQ(loaded.drag_coefficient, builtin.drag_coefficient);
  EXPECT_EQ(loaded.fluid_density, builtin.fluid_density);
  expectSameCurves(loaded, builtin);
}

TEST(MaterialYaml, LinearTestFileLoads) {
  const Material m = loadMaterialYaml(kSourceDir + "/data/materials/linear_test.yaml");
  std::string err;
  EXPECT_TRUE(m.validate(&err)) << err;
  EXPECT_EQ(m.name, "linear_test");
  for (int dir : {0, 1}) {
    EXPECT_NEAR(m.shearSlopeSI(dir, 0.3), 98.0665, 1e-10);
    EXPECT_NEAR(m.shearForceSI(dir, 0.3), 0.3 * 98.0665, 1e-10);
    EXPECT_NEAR(m.bendSlopeSI(dir, 40.0), 9.80665e-6, 1e-18);
    EXPECT_NEAR(m.bendMomentSI(dir, 40.0), 40.0 * 9.80665e-6, 1e-16);
  }
  const Material ref = Material::linearElastic("linear_test", 0.2, 98.0665, 9.80665e-6, 1.0e8);
  for (int dir : {0, 1})
    for (Real x : {0.1, 1.0, 50.0}) {
      EXPECT_NEAR(m.shearForceSI(dir, x), ref.shearForceSI(dir, x), 1e-12 * x * 100);
      EXPECT_NEAR(m.bendMomentSI(dir, x), ref.bendMomentSI(dir, x), 1e-18 * x * 100);
    }
}

TEST(MaterialYaml, RoundTrip) {
  Material weird = Material::linearElastic("odd: name #1 'quoted' \"dq\"", 0.123456789012345, 1.0 / 3.0,
                                           kPi * 1e-6, 7.25e9);
  weird.bend_weft = MaterialCurve::table({0.0, 0.5, 1.0}, {0.0, 0.14, 0.2});
  weird.drag_coefficient = 0.0;
  weird.fluid_density = 1000.0;
  for (const Material& m : {Material::cotton(), Material::linearElastic("lin", 0.2, 5.0, 1e-5, 1e8), weird}) {
    const std::string text = materialToYaml(m);
    Material back;
    ASSERT_NO_THROW(back = parseMaterialYaml(text)) << text;
    EXPECT_TRUE(back == m) << text;
    EXPECT_EQ(back.name, m.name);
    expectSameCurves(back, m);
    EXPECT_EQ(materialToYaml(back), text);
  }
}

TEST(MaterialYaml, OptionalFieldsUseDocumentedDefaults) {
  const std::string text = R"(
name: minimal
areal_density_kg_m2: 0.1
tension_stiffness_N_m: 2e7
shear_warp: {type: linear, slope: 50}
shear_weft: {type: polynomial, pieces: [[0, 40]]}
bend_warp: {type: table, x: [0, 1], y: [0, 0.3]}
bend_weft: {type: polynomial, breakpoints: [0.5], pieces: [[0, 0.43128713, -0.30257426], [0.075643564, 0.12871287]]}
)";
  const Material m = parseMaterialYaml(text);
  EXPECT_EQ(m.drag_coefficient, 1.0);
  EXPECT_EQ(m.fluid_density, 1.2);
  EXPECT_EQ(m.tension_stiffness, 2e7);
  EXPECT_DOUBLE_EQ(m.shear_warp.value(0.2), 10.0);
  EXPECT_DOUBLE_EQ(m.shear_weft.value(0.2), 8.0);
  EXPECT_DOUBLE_EQ(m.bend_warp.value(2.0), 0.6);
}

// A valid YAML document as key -> value lines, to be mutated by the error tests.
std::map<std::string, std::string> baseFields() {
  return {{"name", "cotton"},
          {"areal_density_kg_m2", "0.25"},
          {"tension_stiffness_N_m", "1.0e8"},
          {"drag_coefficient", "1.0"},
          {"fluid_density_kg_m3", "1.2"},
          {"shear_warp", "{type: polynomial, breakpoints: [0.00873], pieces: [[0, 420.54446, -17993.714], [1.3713532, 106.37421]]}"},
          {"shear_weft", "{type: polynomial, breakpoints: [0.00873], pieces: [[0, 412.96917, -17125.983], [1.3052208, 113.94950]]}"},
          {"bend_warp", "{type: polynomial, breakpoints: [0.4, 2.52], pieces: [[0, 0.85984849, -0.71212121], [0.11090909, 0.30530303, -0.018939394], [0.23118183, 0.20984848]]}"},
          {"bend_weft", "{type: table, x: [0, 0.5, 1.0], y: [0, 0.14, 0.2]}"}};
}

std::string toText(const std::map<std::string, std::string>& fields) {
  std::string s;
  for (const auto& [k, v] : fields) s += k + ": " + v + "\n";
  return s;
}

void expectError(const std::string& text, const std::vector<std::string>& must_mention) {
  try {
    parseMaterialYaml(text);
    ADD_FAILURE() << "no MaterialError for:\n" << text;
  } catch (const MaterialError& e) {
    const std::string msg = e.what();
    for (const auto& word : must_mention)
      EXPECT_NE(msg.find(word), std::string::npos) << "message '" << msg << "' lacks '" << word << "'";
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
  }
}

TEST(MaterialYaml, BaseDocumentParses) {
  std::string err;
  const Material m = parseMaterialYaml(toText(baseFields()));
  EXPECT_TRUE(m.validate(&err)) << err;
  EXPECT_EQ(m.bend_weft.kind(), MaterialCurve::Kind::kTable);
}

TEST(MaterialYaml, BadInputsThrowNamingTheField) {
  struct Case {
    std::string key, value;  // value "" removes the key
    std::vector<std::string> mention;
  };
  const std::vector<Case> cases = {
      // NaN / infinity
      {"areal_density_kg_m2", ".nan", {"areal_density_kg_m2", "finite"}},
      {"fluid_density_kg_m3", ".inf", {"fluid_density_kg_m3", "finite"}},
      {"shear_warp", "{type: polynomial, breakpoints: [0.00873], pieces: [[0, .nan], [0, 1]]}",
       {"shear_warp.pieces[0][1]", "finite"}},
      // negative / out of range
      {"areal_density_kg_m2", "-0.25", {"areal_density_kg_m2", "> 0"}},
      {"areal_density_kg_m2", "0", {"areal_density_kg_m2"}},
      {"tension_stiffness_N_m", "0", {"tension_stiffness_N_m"}},
      {"drag_coefficient", "-1", {"drag_coefficient", ">= 0"}},
      {"fluid_density_kg_m3", "-1.2", {"fluid_density_kg_m3"}},
      // missing fields
      {"areal_density_kg_m2", "", {"areal_density_kg_m2", "missing"}},
      {"tension_stiffness_N_m", "", {"tension_stiffness_N_m", "missing"}},
      {"name", "", {"name", "missing"}},
      {"bend_weft", "", {"bend_weft", "missing"}},
      {"shear_warp", "{type: polynomial, breakpoints: [0.1]}", {"shear_warp.pieces", "missing"}},
      {"bend_weft", "{type: table, x: [0, 1]}", {"bend_weft.y", "missing"}},
      {"shear_weft", "{breakpoints: [], pieces: [[0, 1]]}", {"shear_weft.type", "missing"}},
      // wrong types
      {"areal_density_kg_m2", "heavy", {"areal_density_kg_m2", "number"}},
      {"areal_density_kg_m2", "[0.25]", {"areal_density_kg_m2", "number"}},
      {"name", "[a, b]", {"name"}},
      {"shear_warp", "42", {"shear_warp", "curve"}},
      {"shear_warp", "{type: spline, x: [0, 1]}", {"shear_warp.type", "spline"}},
      {"bend_warp", "{type: table, x: 0, y: [0, 1]}", {"bend_warp.x", "list"}},
      {"bend_warp", "{type: linear, slope: [1]}", {"bend_warp.slope", "number"}},
      {"bend_warp", "{type: linear, slope: 1, pieces: [[0, 1]]}", {"bend_warp.pieces", "unknown"}},
      // structurally / numerically invalid curves
      {"bend_warp", "{type: polynomial, breakpoints: [2.52, 0.4], pieces: [[0, 1], [0, 1], [0, 1]]}",
       {"bend_warp", "strictly increasing"}},
      {"bend_warp", "{type: polynomial, breakpoints: [0.4, 0.4], pieces: [[0, 1], [0, 1], [0, 1]]}",
       {"bend_warp", "strictly increasing"}},
      {"bend_warp", "{type: polynomial, breakpoints: [0.4], pieces: [[0, 1]]}", {"bend_warp.pieces", "piece"}},
      {"bend_warp", "{type: polynomial, breakpoints: [0.4], pieces: [[0, 1], []]}", {"bend_warp.pieces[1]"}},
      {"shear_weft", "{type: polynomial, breakpoints: [0.00873], pieces: [[0.5, 412.9], [1.3, 113.9]]}",
       {"shear_weft", "F(0)"}},
      {"bend_weft", "{type: table, x: [0, 0.5, 1.0], y: [0.01, 0.14, 0.2]}", {"bend_weft", "F(0)"}},
      {"bend_weft", "{type: table, x: [0.1, 0.5, 1.0], y: [0, 0.14, 0.2]}", {"bend_weft", "start at 0"}},
      {"bend_weft", "{type: table, x: [0, 0.5, 0.5], y: [0, 0.14, 0.2]}", {"bend_weft", "strictly increasing"}},
      {"bend_weft", "{type: table, x: [0, 0.5], y: [0, 0.14, 0.2]}", {"bend_weft", "length"}},
      // unknown top-level field (typo)
      {"drag_coeficient", "0.5", {"drag_coeficient", "unknown"}},
  };
  for (const auto& c : cases) {
    auto fields = baseFields();
    if (c.value.empty())
      fields.erase(c.key);
    else
      fields[c.key] = c.value;
    SCOPED_TRACE(c.key + ": " + c.value);
    expectError(toText(fields), c.mention);
  }
}

TEST(MaterialYaml, MalformedTextEmptyDocumentDuplicateKeys) {
  expectError("name: [unclosed\nareal_density_kg_m2: 0.25\n", {"<string>", "malformed YAML"});
  expectError("name: cotton\n  areal_density_kg_m2: : 0.25\n\t- x", {"<string>"});
  expectError("", {"<string>", "empty"});
  expectError("- 1\n- 2\n", {"mapping"});
  expectError(toText(baseFields()) + "name: again\n", {"name", "duplicate"});
}

TEST(MaterialYaml, FileErrorsNameThePath) {
  const std::string missing = kSourceDir + "/data/materials/does_not_exist.yaml";
  try {
    loadMaterialYaml(missing);
    ADD_FAILURE() << "no MaterialError for missing file";
  } catch (const MaterialError& e) {
    EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
  }
  // Parse errors from a file name the file.
  const std::string path = ::testing::TempDir() + "/textile_bad_material.yaml";
  {
    FILE* f = std::fopen(path.c_str(), "w");
    ASSERT_NE(f, nullptr);
    const std::string text = "name: bad\nareal_density_kg_m2: -1\n";
    std::fwrite(text.data(), 1, text.size(), f);
    std::fclose(f);
  }
  try {
    loadMaterialYaml(path);
    ADD_FAILURE() << "no MaterialError for bad file";
  } catch (const MaterialError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path), std::string::npos) << msg;
    EXPECT_NE(msg.find("areal_density_kg_m2"), std::string::npos) << msg;
  }
  std::remove(path.c_str());
}

}  // namespace
}  // namespace textile_handling
