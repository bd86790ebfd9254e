// Figures and measured materials of the material lab (lab_material.h).
#include "textile_handling/lab/lab_material.h"

#include <cmath>

#include "lab_specimen.h"

namespace textile_handling {
namespace lab {
namespace {

constexpr Real kNaN = std::numeric_limits<Real>::quiet_NaN();

// The first quarter (0 -> max) of a symmetric cycle as a table curve with F(0) = 0.
MaterialCurve loadingTable(const std::vector<CurvePoint>& cycle) {
  const std::size_t n = (cycle.size() - 1) / 4;
  std::vector<Real> x, y;
  for (std::size_t k = 0; k <= n; ++k) {
    x.push_back(cycle[k].x);
    y.push_back(cycle[k].y - cycle[0].y);
  }
  return MaterialCurve::table(x, y);
}

}  // namespace

Real sampleArealDensity(const LabSample& sample) {
  const Specimen s = makeSpecimen(sample, YarnDirection::kWarp, 0, 4, 4);
  return s.model->totalMass() / s.area;
}

std::vector<LabFigure> labFigures(const LabReport& report) {
  const Material& m = report.sample.material;
  std::vector<LabFigure> out;
  for (const auto& r : report.bending) {
    const std::string dir = toString(r.direction);
    out.push_back({"B", dir, "gf*cm^2/cm", r.B, materialKesB(m, r.direction)});
    out.push_back({"2HB", dir, "gf*cm/cm", r.twoHB, kNaN});
  }
  for (const auto& r : report.shear) {
    const std::string dir = toString(r.direction);
    // The particle model shears every angle with the mean of the two shear curves (docs/simulation.md).
    const Real g = 0.5 * (materialKesG(m, YarnDirection::kWarp) + materialKesG(m, YarnDirection::kWeft));
    out.push_back({"G", dir, "gf/(cm*deg)", r.G, g});
    out.push_back({"2HG", dir, "gf/cm", r.twoHG, kNaN});
    out.push_back({"2HG5", dir, "gf/cm", r.twoHG5, kNaN});
  }
  for (const auto& r : report.tensile) {
    const std::string dir = toString(r.direction);
    // The quartic stretch law F = Y e^4 of the material's tension stiffness.
    const Real fmax = r.cycle.empty() ? 0 : 500 * kGfPerCmToNPerM;
    const Real em = std::pow(fmax / m.tension_stiffness, 0.25);
    out.push_back({"EMT", dir, "%", r.EMT, 100 * em});
    out.push_back({"LT", dir, "-", r.LT, 0.4});
    out.push_back({"WT", dir, "gf*cm/cm^2", r.WT, m.tension_stiffness * std::pow(em, 5) / 5 / kGfPerCmToNPerM});
    out.push_back({"RT", dir, "%", r.RT, 100});
  }
  for (const auto& r : report.cantilever) {
    const std::string dir = toString(r.direction);
    const Real c = materialCantileverBendingLength(m, r.direction);
    out.push_back({"c", dir, "m", r.bending_length_m, c});
    out.push_back({"G_cantilever", dir, "N*m", r.flexural_rigidity_Nm, m.areal_density * kGravity * c * c * c});
  }
  for (const auto& r : report.drape) out.push_back({"DC", "both", "-", r.drape_coefficient, kNaN});
  return out;
}

void writeFiguresCsv(std::ostream& os, const std::vector<LabFigure>& figures) {
  os.precision(8);
  os << "figure,direction,unit,lab,material_file,relative_difference\n";
  for (const auto& f : figures) {
    os << f.name << ',' << f.direction << ',' << f.unit << ',' << f.value << ',';
    if (!std::isnan(f.material_value)) {
      os << f.material_value << ',';
      if (f.material_value != 0) os << (f.value - f.material_value) / f.material_value;
    } else {
      os << ',';
    }
    os << '\n';
  }
}

Material measuredMaterial(const LabReport& report, const std::string& name) {
  Material m = report.sample.material;
  m.name = name;
  m.areal_density = sampleArealDensity(report.sample);
  auto pick = [](const auto& results, YarnDirection want) -> const std::vector<CurvePoint>* {
    for (const auto& r : results)
      if (r.direction == want) return &r.cycle;
    return results.empty() ? nullptr : &results.front().cycle;
  };
  if (const auto* c = pick(report.bending, YarnDirection::kWarp)) m.bend_warp = loadingTable(*c);
  if (const auto* c = pick(report.bending, YarnDirection::kWeft)) m.bend_weft = loadingTable(*c);
  if (const auto* c = pick(report.shear, YarnDirection::kWarp)) m.shear_warp = loadingTable(*c);
  if (const auto* c = pick(report.shear, YarnDirection::kWeft)) m.shear_weft = loadingTable(*c);
  if (!report.tensile.empty()) {
    Real y = 0;
    for (const auto& r : report.tensile) {
      Real fmax = 0;
      for (const auto& p : r.cycle) fmax = std::max(fmax, p.y);
      y += fmax * kGfPerCmToNPerM / std::pow(r.EMT / 100, 4);
    }
    m.tension_stiffness = y / static_cast<Real>(report.tensile.size());
  }
  std::string error;
  if (!m.validate(&error)) throw MaterialLabError("measured material: " + error);
  return m;
}

}  // namespace lab
}  // namespace textile_handling
