#include "textile_handling/bench/speed_accuracy.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <stdexcept>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/stability_scenes.h"

namespace textile_handling {
namespace {

const std::vector<std::pair<std::string, AccuracyScene>>& sceneNames() {
  static const std::vector<std::pair<std::string, AccuracyScene>> names = {
      {"towel_corner", AccuracyScene::kTowelCorner}, {"towel_edge", AccuracyScene::kTowelEdge},
      {"square_corner", AccuracyScene::kSquareCorner}, {"small_square_corner", AccuracyScene::kSmallSquareCorner},
      {"small_sheet_edge", AccuracyScene::kSmallSheetEdge}, {"table_drape", AccuracyScene::kTableDrape},
      {"pushed_edges", AccuracyScene::kPushedEdges}};
  return names;
}

using Clock = std::chrono::steady_clock;
Real secondsSince(Clock::time_point t0) { return std::chrono::duration<Real>(Clock::now() - t0).count(); }

/// The model's registry spec with the settling options (settle damping, definite-fix Jacobian) under the
/// configuration's own keys.
ClothModelSpec settlingSpec(const AccuracyModel& m) {
  ClothModelSpec s = settlingModelSpec(m.spec.name, 4.0);
  for (const auto& kv : m.spec.options) s.options[kv.first] = kv.second;
  return s;
}

void applyIntegrator(SimulationSettings& s, IntegratorType t, bool reference) {
  s.policy = StepPolicy::kErrorControlled;
  if (reference) {
    s.integrator = IntegratorType::kSemiImplicitEuler;
    s.error_tolerance = 1e-4;
    s.dt_max = 0.01;
    s.solver.relative_tolerance = 1e-6;
    s.solver.warm_start = true;
    return;
  }
  s.integrator = t;
  switch (t) {
    case IntegratorType::kSemiImplicitEuler:
      useFastSolverSettings(s);
      s.error_tolerance = 1e-3;
      break;
    case IntegratorType::kBackwardEulerNewton:
      // Each Newton iteration refines the last, so its linear solves stop early (yarn_step_bench's setting).
      s.error_tolerance = 1e-3;
      s.solver.relative_tolerance = 1e-2;
      s.solver.warm_start = true;
      break;
    case IntegratorType::kRK4:
    case IntegratorType::kBlockDiagonalEuler:
      s.error_tolerance = 1e-5;
      break;
  }
}

TextileOutline squareCloth(const std::string& name, Real side) {
  TextileOutline t;
  t.name = name;
  t.outline = {Vec2(0, 0), Vec2(side, 0), Vec2(side, side), Vec2(0, side)};
  t.named_points = {{"corner_ll", "corner", Vec2(0, 0)},
                    {"corner_lr", "corner", Vec2(side, 0)},
                    {"corner_ur", "corner", Vec2(side, side)},
                    {"corner_ul", "corner", Vec2(0, side)},
                    {"centre", "grasp", Vec2(0.5 * side, 0.5 * side)}};
  return t;
}

// The 16 x 8 cm sheet of small_sheet_edge: its corners, the middle of its left short side and its centre.
TextileOutline smallSheet() {
  TextileOutline t;
  t.name = "small_sheet";
  t.outline = {Vec2(0, 0), Vec2(0.16, 0), Vec2(0.16, 0.08), Vec2(0, 0.08)};
  t.named_points = {{"corner_ll", "corner", Vec2(0, 0)},
                    {"corner_lr", "corner", Vec2(0.16, 0)},
                    {"corner_ur", "corner", Vec2(0.16, 0.08)},
                    {"corner_ul", "corner", Vec2(0, 0.08)},
                    {"short_side_left_mid", "grasp", Vec2(0, 0.04)},
                    {"centre", "grasp", Vec2(0.08, 0.04)}};
  return t;
}

DrapeSceneSpec drapeSpec(AccuracyScene scene, const AccuracyConfig& c) {
  DrapeSceneSpec s;
  switch (scene) {
    case AccuracyScene::kTowelCorner:
      s = benchmarkTowelSpec(c.spacing, "corner_ul", c.model.spec.name);
      break;
    case AccuracyScene::kTowelEdge:
      s = benchmarkTowelSpec(c.spacing, "short_side_left_mid", c.model.spec.name);
      break;
    case AccuracyScene::kSquareCorner:
      s = benchmarkTowelSpec(c.spacing, "corner_ul", c.model.spec.name);
      s.textile = squareCloth("square", 0.30);
      break;
    case AccuracyScene::kSmallSquareCorner:
      s = benchmarkTowelSpec(c.spacing, "corner_ul", c.model.spec.name);
      s.textile = squareCloth("small_square", 0.10);
      break;
    case AccuracyScene::kSmallSheetEdge:
      s = benchmarkTowelSpec(c.spacing, "short_side_left_mid", c.model.spec.name);
      s.textile = smallSheet();
      break;
    case AccuracyScene::kTableDrape:
      s = benchmarkTowelSpec(c.spacing, "corner_ul", c.model.spec.name);
      // Sizes that are whole multiples of every default spacing (3, 2, 1.5, 1, 0.75 cm), so that every grid
      // has the same cloth and table; the region is widened by 1 um against rounding at its edge nodes.
      s.textile = squareCloth("table_cloth", 0.48);
      s.hold.clear();
      s.pinned_regions = {Eigen::Matrix<Real, 4, 1>(0.12 - 1e-6, 0.12 - 1e-6, 0.36 + 1e-6, 0.36 + 1e-6)};
      break;
    case AccuracyScene::kPushedEdges:
      throw std::logic_error("drapeSpec: pushed_edges is not a drape scene");
  }
  s.material = c.model.material;
  s.model = settlingSpec(c.model);
  return s;
}

std::vector<Vec2> namedPointPositions(const TextileOutline& t) {
  std::vector<Vec2> p;
  for (const NamedPoint& n : t.named_points) p.push_back(n.position);
  return p;
}

AccuracyRun runDrape(AccuracyScene scene, const AccuracyConfig& c, const AccuracyRunLimits& limits, bool reference) {
  AccuracyRun out;
  DrapeSceneSpec spec = drapeSpec(scene, c);
  applyIntegrator(spec.settings, c.integrator, reference);
  spec.settings.max_wall_time = reference ? limits.reference_max_wall_s : limits.max_wall_s;
  if (limits.max_sim_time_s > 0) spec.settings.max_time = limits.max_sim_time_s;
  const Clock::time_point t0 = Clock::now();
  const DrapeScene built = buildDrapeScene(spec);
  DrapeSimulation sim(*built.model, built.pins, spec.settings, built.x0, built.v0);
  if (PostStepPass* pass = built.postStepPass()) sim.setPostStepPass(pass);
  const RunResult r = sim.run();
  out.wall_s = secondsSince(t0);
  out.steps = r.steps;
  out.sim_time = r.sim_time;
  out.status = r.diverged ? "diverged" : r.wall_cap_reached ? "wall_cap" : r.rest_reached ? "rest" : "time_cap";
  out.note = r.divergence_reason;
  out.grid = built.grid;
  out.nodes = built.grid.numActive();
  out.positions = sim.positions();
  out.named_points = namedPointPositions(spec.textile);
  out.held_at_one_point = spec.hold.size() == 1 && spec.pinned_regions.empty();
  out.view_centre = scene == AccuracyScene::kTableDrape ? spec.hold_position + Vec3(0, 0, 0.05) : spec.hold_position;
  return out;
}

AccuracyRun runPushedEdges(const AccuracyConfig& c, const AccuracyRunLimits& limits, bool reference) {
  CompressionSceneSpec sc;
  sc.scene = CompressionScene::kPushedEdges;
  sc.spacing = c.spacing;
  StabilityRunSpec run;
  run.model = c.model.spec;
  run.material = c.model.material;
  run.damping = true;
  const IntegratorType t = reference ? IntegratorType::kSemiImplicitEuler : c.integrator;
  run.integrator = t;
  const bool implicit = t == IntegratorType::kSemiImplicitEuler || t == IntegratorType::kBackwardEulerNewton;
  run.dt = reference ? 1e-3 : implicit ? 5e-3 : 2e-4;
  run.solver.relative_tolerance = reference ? 1e-6 : 1e-3;
  run.solver.warm_start = true;
  run.max_wall_time = reference ? limits.reference_max_wall_s : limits.max_wall_s;
  const Clock::time_point t0 = Clock::now();
  const StabilityResult r = runCompressionScene(sc, run);
  AccuracyRun out;
  out.wall_s = secondsSince(t0);
  out.steps = r.steps;
  out.sim_time = r.sim_time;
  out.status = r.wall_cap_reached ? "wall_cap" : r.stable ? "end" : "diverged";
  out.note = r.reason;
  out.grid = r.grid;
  out.nodes = r.nodes;
  out.positions = r.final_positions;
  out.named_points = namedPointPositions(squareCloth("square", sc.side));
  out.view_centre = Vec3(0.5 * sc.side * (1 - sc.push_fraction), 0.5 * sc.side, 0.3);
  return out;
}

}  // namespace

DrapeSceneSpec accuracyDrapeSpec(AccuracyScene scene, const AccuracyConfig& config) {
  if (scene == AccuracyScene::kPushedEdges) throw std::invalid_argument("pushed_edges is a compression scene, not a drape scene");
  DrapeSceneSpec spec = drapeSpec(scene, config);
  applyIntegrator(spec.settings, config.integrator, false);
  return spec;
}

std::vector<bool> speedAccuracyFront(const std::vector<Real>& x, const std::vector<Real>& y) {
  std::vector<bool> front(x.size(), false);
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (!std::isfinite(x[i]) || !std::isfinite(y[i])) continue;
    bool dominated = false;
    for (std::size_t j = 0; j < x.size() && !dominated; ++j)
      dominated = j != i && std::isfinite(x[j]) && std::isfinite(y[j]) && x[j] <= x[i] && y[j] <= y[i] &&
                  (x[j] < x[i] || y[j] < y[i]);
    front[i] = !dominated;
  }
  return front;
}

Real frontMargin(const std::vector<Real>& x, const std::vector<Real>& y, std::size_t row) {
  Real margin = 0;
  for (std::size_t j = 0; j < x.size(); ++j) {
    if (j == row || !std::isfinite(x[j]) || !std::isfinite(y[j]) || !(x[j] > 0) || !(y[j] > 0)) continue;
    margin = std::max(margin, std::min(x[row] / x[j], y[row] / y[j]) - 1);
  }
  return margin;
}

std::string toString(AccuracyScene s) {
  for (const auto& n : sceneNames())
    if (n.second == s) return n.first;
  return "unknown";
}

AccuracyScene accuracySceneFromString(const std::string& s) {
  std::string known;
  for (const auto& n : sceneNames()) {
    if (n.first == s) return n.second;
    known += (known.empty() ? "" : ", ") + n.first;
  }
  throw std::invalid_argument("unknown scene '" + s + "'; known: " + known);
}

std::vector<AccuracyScene> allAccuracyScenes() {
  std::vector<AccuracyScene> v;
  for (const auto& n : sceneNames()) v.push_back(n.second);
  return v;
}

db::DrapeDifferenceOptions AccuracyRun::differenceOptions() const {
  db::DrapeDifferenceOptions o;
  o.named_points = named_points;
  o.align_yaw = held_at_one_point;
  // Hanging towels: the database's own frame (what recognition compares). Smaller scenes: a 0.8 m
  // window at 5 mm per pixel, so that a few centimetres show; the 10 cm square a 0.25 m window.
  if (grid.spacing() > 0 && nodes > 0) {
    const Vec2 extent = grid.node(grid.rows() - 1, grid.cols() - 1) - grid.origin();
    if (extent.maxCoeff() < 0.2) o.frame = vision::CanonicalFrame::fromMetric(0.25, 0.25, 160);
    else if (extent.maxCoeff() < 0.6) o.frame = vision::CanonicalFrame::fromMetric(0.8, 0.8, 160);
  }
  return o;
}

AccuracyRun runAccuracyScene(AccuracyScene scene, const AccuracyConfig& config, const AccuracyRunLimits& limits,
                             bool reference) {
  try {
    if (scene == AccuracyScene::kPushedEdges) return runPushedEdges(config, limits, reference);
    return runDrape(scene, config, limits, reference);
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    AccuracyRun out;
    out.status = "error";
    out.note = e.what();
    return out;
  }
}

}  // namespace textile_handling
