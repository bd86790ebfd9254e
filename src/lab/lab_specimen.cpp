// Specimens and the kinematic cycle of the material lab (lab_specimen.h).
#include "lab_specimen.h"

#include <cmath>
#include <string>

#include "textile_handling/sim/cloth_topology.h"

namespace textile_handling {
namespace lab {
namespace {

// Bounds the work of one specimen: far above what a lab test needs (a 25 mm x 0.5 m strip at 1 mm).
constexpr long kMaxSpecimenNodes = 200000;
constexpr int kMaxSpecimenCellsPerSide = 20000;

}  // namespace

std::string toString(YarnDirection d) { return d == YarnDirection::kWarp ? "warp" : "weft"; }

YarnDirection yarnDirectionFromString(const std::string& s) {
  if (s == "warp") return YarnDirection::kWarp;
  if (s == "weft") return YarnDirection::kWeft;
  throw MaterialLabError("direction '" + s + "' must be warp or weft");
}

int cellsFor(Real length, Real spacing, int min_cells, const char* field) {
  if (!std::isfinite(spacing) || !(spacing > 0))
    throw MaterialLabError("sample spacing must be finite and > 0 (got " + std::to_string(spacing) + ")");
  if (!std::isfinite(length) || !(length > 0)) throw MaterialLabError(std::string(field) + " must be finite and > 0");
  const Real n = std::round(length / spacing);
  if (!(n <= kMaxSpecimenCellsPerSide))
    throw MaterialLabError(std::string(field) + " is " + std::to_string(n) + " grid cells at d = " + std::to_string(spacing) +
                           " m, above the lab's " + std::to_string(kMaxSpecimenCellsPerSide));
  return std::max(min_cells, static_cast<int>(n));
}

Specimen makeSpecimen(const LabSample& sample, YarnDirection direction, Real a_min, int cells_a, int cells_b) {
  const Real d = sample.spacing;
  if (!std::isfinite(d) || !(d > 0)) throw MaterialLabError("sample spacing must be finite and > 0 (got " + std::to_string(d) + ")");
  if (cells_a < 1 || cells_b < 1) throw MaterialLabError("a specimen needs at least one cell each way");
  if (static_cast<long>(cells_a + 1) * (cells_b + 1) > kMaxSpecimenNodes)
    throw MaterialLabError("specimen of " + std::to_string(cells_a + 1) + " x " + std::to_string(cells_b + 1) +
                           " nodes is above the lab's limit of " + std::to_string(kMaxSpecimenNodes));
  std::string error;
  if (!sample.material.validate(&error)) throw MaterialLabError("sample material: " + error);

  Specimen s;
  s.direction = direction;
  s.a_min = a_min;
  s.a_max = a_min + cells_a * d;
  const bool warp = direction == YarnDirection::kWarp;
  const Real la = cells_a * d, lb = cells_b * d;
  // The rectangle in the textile frame, counter-clockwise.
  const Real x0 = warp ? a_min : 0, y0 = warp ? 0 : a_min;
  const Real w = warp ? la : lb, h = warp ? lb : la;
  TextileOutline outline;
  outline.name = "lab_specimen";
  outline.outline = {Vec2(x0, y0), Vec2(x0 + w, y0), Vec2(x0 + w, y0 + h), Vec2(x0, y0 + h)};
  s.grid = ParticleGrid::rasterize(outline, d, &error);
  if (s.grid.empty()) throw MaterialLabError("specimen rasterisation failed: " + error);
  const ParticleTopology topology = ParticleTopology::fromGrid(s.grid);
  s.model = ClothModelRegistry::instance().create(sample.model, topology, sample.material);

  const Index n = s.grid.numActive();
  VecX p(3 * n);
  s.a.resize(n);
  s.b.resize(n);
  for (Index i = 0; i < n; ++i) {
    const Vec2 q = s.grid.activePosition(i);
    s.a[i] = warp ? q.x() : q.y();
    s.b[i] = warp ? q.y() : q.x();
    p.segment<3>(3 * i) = Vec3(q.x(), q.y(), 0);
  }
  s.x_rest = VecX::Zero(s.model->numDofs());
  s.model->setPositions(p, s.x_rest);
  s.area = la * lb;
  return s;
}

LabSample settlingSample(const LabSample& sample) {
  LabSample s = sample;
  const ClothModelDescriptor& d = ClothModelRegistry::instance().find(s.model.name);
  if (d.hasOptionKey("settle_damping_per_s") && !s.model.options.count("settle_damping_per_s"))
    s.model.set("settle_damping_per_s", Real(4));
  if (d.hasOptionKey("jacobian") && !s.model.options.count("jacobian")) s.model.set("jacobian", "definite_fix");
  return s;
}

std::vector<Real> symmetricCycle(Real max, int steps_per_quarter) {
  const int n = steps_per_quarter;
  std::vector<Real> q;
  q.reserve(4 * n + 1);
  for (int k = 0; k <= n; ++k) q.push_back(max * k / n);
  for (int k = 1; k <= 2 * n; ++k) q.push_back(max * (n - k) / n);
  for (int k = 1; k <= n; ++k) q.push_back(max * (k - n) / n);
  return q;
}

Real generalisedForce(Specimen& specimen, const SpecimenMap& map, Real q, Real dq) {
  ClothModel& model = *specimen.model;
  const Index n = model.numNodes();
  const bool warp = specimen.direction == YarnDirection::kWarp;
  auto stateAt = [&](Real value) {
    VecX p(3 * n);
    for (Index i = 0; i < n; ++i) {
      const Vec3 t = map(specimen.a[i], specimen.b[i], value);
      // Test frame (a, b, z) to textile frame; the weft frame is a reflection, which no energy notices.
      p.segment<3>(3 * i) = warp ? t : Vec3(t.y(), t.x(), t.z());
    }
    VecX x = specimen.x_rest;
    model.setPositions(p, x);
    return x;
  };
  const VecX x = stateAt(q);
  const VecX plus = stateAt(q + dq), minus = stateAt(q - dq);
  const VecX dxdq = (plus - minus) / (2 * dq);
  const Real dgravity = (model.gravitationalEnergy(plus) - model.gravitationalEnergy(minus)) / (2 * dq);
  VecX f(model.numDofs());
  VecX v = VecX::Zero(model.numDofs());
  model.computeForces(x, v, f, nullptr);
  model.acceptStep(x, v);
  return -(f.dot(dxdq) + dgravity);
}

InteriorResponse::InteriorResponse(const LabSample& sample, YarnDirection direction, int cells_a, int cells_b,
                                   bool centred) {
  for (const int fb : {1, 2})
    for (const int fa : {1, 2}) {
      const int ca = fa * cells_a;
      specimens_.push_back(makeSpecimen(sample, direction, centred ? -0.5 * ca * sample.spacing : 0, ca, fb * cells_b));
    }
  area_ = specimens_.front().area;
}

Real InteriorResponse::at(const SpecimenMap& map, Real q, Real dq) {
  Real r[4];
  for (int k = 0; k < 4; ++k) r[k] = generalisedForce(specimens_[k], map, q, dq);
  // Order (a, b): (1, 1), (2, 1), (1, 2), (2, 2).
  return (r[3] - r[2] - r[1] + r[0]) / area_;
}

}  // namespace lab
}  // namespace textile_handling
