// Drape coefficient of a circular sample on a support disc, on any cloth model (material_lab.h).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <string>

#include "lab_specimen.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/drape_simulation.h"

namespace textile_handling {
namespace lab {
namespace {

constexpr int kCircleVertices = 256;
// Bounds the raster of the shadow (a 30 cm sample at 1 mm is 0.36 M pixels).
constexpr long kMaxShadowPixels = 20000000;

// Area [m^2] covered by the vertical projection of the grid's cells (two triangles each) at `positions`,
// on a raster of `pixel` [m]; with `only` non-empty, of the cells whose four nodes it flags.
Real shadowArea(const ParticleGrid& grid, const VecX& positions, Real pixel, const std::vector<char>& only = {}) {
  const Index n = grid.numActive();
  Real x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (Index i = 0; i < n; ++i) {
    x0 = std::min(x0, positions[3 * i]);
    x1 = std::max(x1, positions[3 * i]);
    y0 = std::min(y0, positions[3 * i + 1]);
    y1 = std::max(y1, positions[3 * i + 1]);
  }
  const long w = static_cast<long>(std::ceil((x1 - x0) / pixel)) + 1, h = static_cast<long>(std::ceil((y1 - y0) / pixel)) + 1;
  if (!(w > 0 && h > 0 && w * h <= kMaxShadowPixels))
    throw MaterialLabError("drape.shadow_pixel_m: the shadow raster would have more than 2e7 pixels");
  std::vector<char> covered(static_cast<std::size_t>(w * h), 0);
  auto fill = [&](Index a, Index b, Index c) {
    const Vec2 p[3] = {Vec2(positions[3 * a], positions[3 * a + 1]), Vec2(positions[3 * b], positions[3 * b + 1]),
                       Vec2(positions[3 * c], positions[3 * c + 1])};
    const Real det = (p[1] - p[0]).x() * (p[2] - p[0]).y() - (p[1] - p[0]).y() * (p[2] - p[0]).x();
    if (std::abs(det) < 1e-30) return;
    const long i0 = static_cast<long>(std::floor((std::min({p[0].x(), p[1].x(), p[2].x()}) - x0) / pixel));
    const long i1 = static_cast<long>(std::ceil((std::max({p[0].x(), p[1].x(), p[2].x()}) - x0) / pixel));
    const long j0 = static_cast<long>(std::floor((std::min({p[0].y(), p[1].y(), p[2].y()}) - y0) / pixel));
    const long j1 = static_cast<long>(std::ceil((std::max({p[0].y(), p[1].y(), p[2].y()}) - y0) / pixel));
    for (long j = std::max(0L, j0); j <= std::min(h - 1, j1); ++j)
      for (long i = std::max(0L, i0); i <= std::min(w - 1, i1); ++i) {
        const Vec2 q(x0 + (i + 0.5) * pixel, y0 + (j + 0.5) * pixel);
        const Vec2 r = q - p[0];
        const Real u = (r.x() * (p[2] - p[0]).y() - r.y() * (p[2] - p[0]).x()) / det;
        const Real v = ((p[1] - p[0]).x() * r.y() - (p[1] - p[0]).y() * r.x()) / det;
        if (u >= 0 && v >= 0 && u + v <= 1) covered[static_cast<std::size_t>(j * w + i)] = 1;
      }
  };
  for (Index r = 0; r + 1 < grid.rows(); ++r)
    for (Index c = 0; c + 1 < grid.cols(); ++c) {
      const Index a = grid.activeIndex(r, c), b = grid.activeIndex(r, c + 1), d = grid.activeIndex(r + 1, c),
                  e = grid.activeIndex(r + 1, c + 1);
      if (a < 0 || b < 0 || d < 0 || e < 0) continue;
      if (!only.empty() && !(only[a] && only[b] && only[d] && only[e])) continue;
      fill(a, b, e);
      fill(a, e, d);
    }
  long count = 0;
  for (const char k : covered) count += k;
  return static_cast<Real>(count) * pixel * pixel;
}

void checkProtocol(const DrapeCoefficientProtocol& p) {
  auto positive = [](Real v, const char* field) {
    if (!std::isfinite(v) || !(v > 0)) throw MaterialLabError(std::string(field) + " must be finite and > 0");
  };
  positive(p.sample_diameter_m, "drape.sample_diameter_m");
  positive(p.disc_diameter_m, "drape.disc_diameter_m");
  positive(p.max_time_s, "drape.max_time_s");
  positive(p.shadow_pixel_m, "drape.shadow_pixel_m");
  if (!(p.disc_diameter_m < p.sample_diameter_m)) throw MaterialLabError("drape.disc_diameter_m must be below drape.sample_diameter_m");
  if (!std::isfinite(p.spacing_m) || p.spacing_m < 0) throw MaterialLabError("drape.spacing_m must be finite and >= 0");
  if (!std::isfinite(p.perturbation_m) || p.perturbation_m < 0) throw MaterialLabError("drape.perturbation_m must be finite and >= 0");
  if (p.max_time_s > 600) throw MaterialLabError("drape.max_time_s must be <= 600");
}

}  // namespace

DrapeCoefficientResult runDrapeCoefficient(const LabSample& sample_in, const DrapeCoefficientProtocol& protocol) {
  checkProtocol(protocol);
  LabSample sample = settlingSample(sample_in);
  if (protocol.spacing_m > 0) sample.spacing = protocol.spacing_m;
  const Real d = sample.spacing;
  const Real radius = 0.5 * protocol.sample_diameter_m, disc = 0.5 * protocol.disc_diameter_m;
  const int cells = cellsFor(protocol.sample_diameter_m, d, 4, "drape.sample_diameter_m");
  if (disc < 1.5 * d) throw MaterialLabError("drape.disc_diameter_m must hold more than one node (>= 3 grid spacings)");
  std::string error;
  if (!sample.material.validate(&error)) throw MaterialLabError("sample material: " + error);
  if (static_cast<long>(cells + 1) * (cells + 1) > 200000)
    throw MaterialLabError("drape: " + std::to_string(cells) + " cells across is above the lab's limit; raise drape.spacing_m");

  // The circle, centred on a grid node (the origin), as the textile outline.
  TextileOutline outline;
  outline.name = "drape_sample";
  for (int k = 0; k < kCircleVertices; ++k) {
    const Real a = 2 * kPi * k / kCircleVertices;
    outline.outline.emplace_back(radius * std::cos(a), radius * std::sin(a));
  }
  DrapeCoefficientResult result;
  ParticleGrid grid = ParticleGrid::rasterize(outline, d, &error);
  if (grid.empty()) throw MaterialLabError("drape: rasterisation failed: " + error);
  std::unique_ptr<ClothModel> model =
      ClothModelRegistry::instance().create(sample.model, ParticleTopology::fromGrid(grid), sample.material);
  const Index n = grid.numActive();
  // Centre of the sample: the mean of its nodes (the rasterised circle is symmetric about it).
  Vec2 centre = Vec2::Zero();
  for (Index i = 0; i < n; ++i) centre += grid.activePosition(i);
  centre /= static_cast<Real>(n);
  std::mt19937 rng(protocol.seed);
  std::uniform_real_distribution<Real> noise(-1, 1);
  VecX p(3 * n);
  PinnedNodes pins;
  std::vector<char> on_disc_flags(static_cast<std::size_t>(n), 0);
  for (Index i = 0; i < n; ++i) {
    const Vec2 q = grid.activePosition(i) - centre;
    const bool on_disc = q.norm() <= disc;
    p.segment<3>(3 * i) = Vec3(q.x(), q.y(), on_disc ? 0 : protocol.perturbation_m * noise(rng));
    if (on_disc) {
      on_disc_flags[static_cast<std::size_t>(i)] = 1;
      pins.nodes.push_back(i);
      pins.anchors.push_back(p.segment<3>(3 * i));
    }
  }
  VecX x0 = VecX::Zero(model->numDofs());
  model->setPositions(p, x0);
  SimulationSettings settings;
  settings.max_time = protocol.max_time_s;
  settings.dt = 1e-3;
  settings.dt_max = 0.0125;
  settings.error_tolerance = 1e-3;
  settings.solver.relative_tolerance = 0.03;
  settings.solver.warm_start = true;
  DrapeSimulation sim(*model, pins, settings, x0, VecX::Zero(model->numDofs()));
  const auto start = std::chrono::steady_clock::now();
  const RunResult run = sim.run();
  result.wall_time_s = std::chrono::duration<Real>(std::chrono::steady_clock::now() - start).count();
  if (run.diverged) throw MaterialLabError("drape: the settle diverged at t = " + std::to_string(run.divergence_time) + " s: " + run.divergence_reason);
  result.nodes = n;
  result.rest_reached = run.rest_reached;
  result.sim_time_s = run.sim_time;
  result.steps = run.steps;
  // The disc's shadow measured as the sample's: the cells held on it (a limp sample then reads 0).
  result.disc_area_m2 = shadowArea(grid, p, protocol.shadow_pixel_m, on_disc_flags);
  result.sample_area_m2 = shadowArea(grid, p, protocol.shadow_pixel_m);
  result.shadow_area_m2 = shadowArea(grid, sim.positions(), protocol.shadow_pixel_m);
  result.drape_coefficient = (result.shadow_area_m2 - result.disc_area_m2) / (result.sample_area_m2 - result.disc_area_m2);
  return result;
}

}  // namespace lab
}  // namespace textile_handling
