#include "textile_handling/sim/rest_shape_search.h"

#include <chrono>
#include <optional>
#include <cmath>
#include <sstream>

#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/edge_length_relaxation.h"
#include "textile_handling/sim/grid_prolongation.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {

std::string toString(RestShapeMethod m) { return m == RestShapeMethod::kDynamic ? "dynamic" : "quasi_static"; }

RestShapeMethod restShapeMethodFromString(const std::string& s) {
  if (s == "dynamic") return RestShapeMethod::kDynamic;
  if (s == "quasi_static") return RestShapeMethod::kQuasiStatic;
  throw SimError("unknown rest-shape method '" + s + "' (expected dynamic or quasi_static)");
}

void RestShapeSettings::validate() const {
  auto nonNegative = [](Real v, const char* field) {
    if (!(v >= 0) || !std::isfinite(v)) throw SimError(std::string("rest shape: ") + field + " must be finite and >= 0");
  };
  nonNegative(coarse_spacing, "coarse_spacing");
  nonNegative(settle_speed, "settle_speed");
  nonNegative(settle_mean_speed, "settle_mean_speed");
  nonNegative(settle_duration, "settle_duration");
  nonNegative(settle_error_tolerance, "settle_error_tolerance");
  if (!(prolonged_min_edge_ratio >= 0 && prolonged_min_edge_ratio <= 1))
    throw SimError("rest shape: prolonged_min_edge_ratio must be in [0, 1] (0 = off)");
  if (!(prolonged_max_edge_ratio >= 1 && std::isfinite(prolonged_max_edge_ratio)))
    throw SimError("rest shape: prolonged_max_edge_ratio must be finite and >= 1");
  const StaticEquilibriumSettings& f = finish;  // the solver's own checks, named here for the caller
  if (f.max_iterations < 1 || f.max_backtracks < 0 || !(f.force_tolerance > 0) || !std::isfinite(f.force_tolerance) ||
      !(f.min_time_scale > 0) || !(f.min_time_scale <= f.initial_time_scale) || !(f.initial_time_scale <= f.max_time_scale) ||
      !std::isfinite(f.max_time_scale))
    throw SimError("rest shape: finish settings out of range (iterations >= 1, tolerances > 0, min <= initial <= max time scale)");
}

std::string RestShapeSettings::text() const {
  if (method == RestShapeMethod::kDynamic) return "";
  std::ostringstream o;
  o.precision(17);
  o << "rest_method: quasi_static coarse_spacing: " << coarse_spacing << " settle: " << settle_speed << " "
    << settle_mean_speed << " " << settle_duration << " " << settle_error_tolerance << " finish: " << finish.force_tolerance << " "
    << finish.max_iterations << " " << finish.initial_time_scale << " prolonged_edge_ratios: " << prolonged_min_edge_ratio
    << " " << prolonged_max_edge_ratio << " coarse_static_finish: " << (coarse_static_finish ? 1 : 0);
  return o.str();
}

bool quasiStaticApplies(const DrapeScene& scene) {
  return scene.pins.waypoint_times.empty() && scene.postStepPass() == nullptr && scene.spec.pinned_regions.empty() &&
         !scene.spec.hold.empty();
}

namespace {

using Clock = std::chrono::steady_clock;

struct DynamicRun {
  RunResult result;
  VecX state;
};

DynamicRun runDynamic(DrapeScene& scene, const SimulationSettings& settings) {
  DrapeSimulation sim(*scene.model, scene.pins, settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  DynamicRun out;
  out.result = sim.run();
  out.state = sim.state();
  return out;
}

SimulationSettings settleSettings(const SimulationSettings& s, const RestShapeSettings& r) {
  SimulationSettings out = s;
  out.rest_speed = r.settle_speed;
  out.rest_mean_speed = r.settle_mean_speed;
  out.rest_duration = r.settle_duration;
  if (r.settle_error_tolerance > 0) out.error_tolerance = r.settle_error_tolerance;
  out.trajectory_every = 0;
  return out;
}

// The scene's textile on the coarse grid, holding the textile points of the scene's pinned particles.
DrapeSceneSpec coarseSpec(const DrapeScene& scene, Real spacing) {
  DrapeSceneSpec c = scene.spec;
  c.spacing = spacing;
  c.hold.clear();
  for (Index p : scene.pins.nodes) {
    HoldPoint h;
    h.position = scene.grid.activePosition(p);
    c.hold.push_back(h);
  }
  return c;
}

void addRun(RestShapeResult* r, const RunResult& run) {
  r->steps += run.steps;
  r->rejected_steps += run.rejected_steps;
  r->sim_time += run.sim_time;
}

// The quasi-static stages; false (with the reason in *why) if one failed.
bool quasiStatic(DrapeScene& scene, const RestShapeSettings& rs, RestShapeResult* res, std::string* why) {
  const SimulationSettings settle = settleSettings(scene.spec.settings, rs);
  VecX x = scene.x0;
  bool coarse_done = false;
  if (rs.coarse_spacing >= 1.5 * scene.spec.spacing) {
    std::optional<DrapeScene> coarse;
    try {
      coarse.emplace(buildDrapeScene(coarseSpec(scene, rs.coarse_spacing)));
    } catch (const SimError&) {
      coarse.reset();  // e.g. too few coarse particles: settle on the scene's own grid
    }
    if (coarse) {
      DynamicRun run = runDynamic(*coarse, settle);
      res->dynamic = run.result;
      addRun(res, run.result);
      if (run.result.diverged) {
        *why = "coarse dynamic phase diverged: " + run.result.divergence_reason;
        return false;
      }
      if (rs.coarse_static_finish)
        res->coarse_finish = solveStaticEquilibrium(*coarse->model, coarse->pins, run.result.sim_time, run.state, rs.finish);
      // An unconverged coarse finish still is a better start than the settling state; go on.
      VecX fine = prolongPositions(coarse->grid, coarse->model->positionsOf(run.state), scene.grid);
      const Index held = scene.pins.nodes.front();
      const Vec3 shift = scene.pins.position(0, 0) - Vec3(fine.segment<3>(3 * held));
      for (Index i = 0; i < scene.grid.numActive(); ++i) fine.segment<3>(3 * i) += shift;
      if (rs.prolonged_min_edge_ratio > 0)
        res->relaxation = relaxEdgeLengths(scene.grid, fine, scene.pins.nodes, rs.prolonged_min_edge_ratio,
                                           rs.prolonged_max_edge_ratio, 200);
      scene.model->setPositions(fine, x);
      res->coarse_level = true;
      coarse_done = true;
    }
  }
  Real t = 0;
  if (!coarse_done) {
    DynamicRun run = runDynamic(scene, settle);
    res->dynamic = run.result;
    addRun(res, run.result);
    if (run.result.diverged) {
      *why = "dynamic phase diverged: " + run.result.divergence_reason;
      return false;
    }
    x = run.state;
    t = run.result.sim_time;
  }
  if (rs.fine_finish == FineFinish::kDynamic && coarse_done) {
    // The scene's own dynamics and rest detection from the prolonged coarse equilibrium, at rest.
    DrapeSimulation sim(*scene.model, scene.pins, scene.spec.settings, x, VecX::Zero(x.size()));
    const RunResult r = sim.run();
    res->finish_run = r;
    addRun(res, r);
    if (!r.rest_reached) {
      *why = r.diverged ? "fine dynamic finish diverged: " + r.divergence_reason : "fine dynamic finish found no rest";
      return false;
    }
    x = sim.state();
  } else {
    res->finish = solveStaticEquilibrium(*scene.model, scene.pins, t, x, rs.finish);
    if (!res->finish.converged) {
      *why = res->finish.failure;
      return false;
    }
  }
  const Real stretch = scene.model->maxEdgeStretch(x);
  if (!(stretch <= scene.spec.settings.max_edge_stretch)) {
    *why = "equilibrium stretches an edge to " + std::to_string(stretch) + " times its rest length";
    return false;
  }
  res->state = x;
  return true;
}

}  // namespace

RestShapeResult findRestShape(DrapeScene& scene, const RestShapeSettings& settings) {
  settings.validate();
  const auto t0 = Clock::now();
  RestShapeResult res;
  std::string why;
  if (settings.method == RestShapeMethod::kQuasiStatic && quasiStaticApplies(scene)) {
    if (quasiStatic(scene, settings, &res, &why)) {
      res.rest_reached = true;
      res.method_used = "quasi_static";
    }
  }
  if (!res.rest_reached) {
    // The reference method, also the fallback. After a failed attempt the model's internal state may
    // have moved: the fallback runs on a fresh scene (one without post-step passes, or no attempt).
    std::optional<DrapeScene> fresh;
    if (!why.empty()) fresh.emplace(buildDrapeScene(scene.spec));
    DrapeScene& target = fresh ? *fresh : scene;
    DynamicRun run = runDynamic(target, scene.spec.settings);
    if (why.empty()) res.dynamic = run.result;
    addRun(&res, run.result);
    res.state = run.state;
    res.rest_reached = run.result.rest_reached;
    res.diverged = run.result.diverged;
    if (run.result.diverged)
      res.failure = "diverged at t = " + std::to_string(run.result.divergence_time) + " s: " + run.result.divergence_reason;
    else if (!run.result.rest_reached)
      res.failure = "no rest within max_time " + std::to_string(scene.spec.settings.max_time) + " s";
    res.method_used = why.empty() ? "dynamic" : "dynamic (quasi-static finish failed: " + why + ")";
    if (fresh) scene.model = std::move(fresh->model);
  }
  res.positions = scene.model->positionsOf(res.state);
  res.wall_seconds = secondsSince(t0);
  return res;
}

}  // namespace textile_handling
