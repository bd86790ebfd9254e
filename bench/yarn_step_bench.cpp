// yarn_step_bench: cost per time step of the yarn_woven model against the number of crossings, on 1
// and 2 threads, and the largest stable step (docs/yarn_model.md, "Cost per step").
//
//   yarn_step_bench [--out DIR] [--sides N1,N2,...] [--steps K] [--dt S] [--integrator NAME]
//                   [--repeats R] [--stable-side N] [--stable-time S] [--stable-dts D1,D2,...]
//                   [--linear-tolerance T] [--accept-tolerance T] [--newton-tolerance T]
//                   [--preconditioner two_level|block_jacobi] [--smoothing-steps S] [--smoothing-weight W]
//                   [--warm-start 0|1]
//                   [--self-collision 0|1] [--reference-tolerance T] [--model-option KEY=VALUE ...]
//
// Cost: a square sheet of N x N crossings of the default fabric (1 yarn/mm, every yarn simulated), hung
// from its two upper corners and released flat, one untimed step (it allocates the Jacobians and the
// solver's structures) and then K timed fixed steps of --dt (default 1 ms, the source's step) with
// --integrator (default semi_implicit). The solver options set the SolverSettings fields of the same
// names (defaults: the settings' own; --linear-tolerance is the relative residual of CG / PCR);
// --self-collision 1 runs the scene's v3 self-collision pass after every step; --model-option sets a
// yarn_woven key (docs/yarn_model.md), e.g. exact_hessian=true (repeatable).
// For every size, one reference run with the linear tolerance --reference-tolerance (default 1e-10;
// 0 = none) gives the accuracy figure: the largest node distance from it after the same steps. Then
// one and two threads run interleaved (1, 2, 1, 2, ...) --repeats times; each row gives the wall time
// per step and per crossing-step, the split into assembly (forces, Jacobians and the system), solve
// and collisions per step, the forces alone and the Jacobians' extra time per evaluation (median of 3
// at the final state; the forces alone reuse the Rayleigh damping's stiffness matrix of the state's
// first evaluation, so the clamped stiffness matrix is part of the Jacobians' time), solver and Newton
// iterations per step, and the distance from the reference.
// Stable step: the --stable-side sheet hung the same way for --stable-time seconds at each fixed step
// of --stable-dts; stable = no divergence. --stable-side 0 skips it.
//
// Writes DIR/step_cost.csv, DIR/stable_step.csv and DIR/step_cost.png (microseconds per crossing-step
// against crossings); prints the median per size and thread count and the largest stable step.
// Benchmarks, not tests: timings vary up to 3x between machines and hours; compare the interleaved
// thread counts as ratios. Set OMP_WAIT_POLICY=passive. Exit: 0 done, 2 usage, 4 output, 5 error.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/drape_simulation.h"

using namespace textile_handling;

namespace {

std::vector<double> parseList(const std::string& text) {
  std::vector<double> v;
  std::stringstream s(text);
  std::string item;
  while (std::getline(s, item, ',')) v.push_back(std::atof(item.c_str()));
  return v;
}

// N x N crossings at 1 mm, held at its two upper corners, flat at release.
Real g_linear_tolerance = 0;  // --linear-tolerance (0: the solver's default)
Real g_accept_tolerance = 0;  // --accept-tolerance (0: the solver's default)
Real g_newton_tolerance = 0;  // --newton-tolerance (0: the solver's default)
std::string g_preconditioner;  // --preconditioner (empty: the solver's default)
bool g_warm_start = false;     // --warm-start 1
int g_smoothing_steps = -1;    // --smoothing-steps (-1: the solver's default)
Real g_smoothing_weight = 0;   // --smoothing-weight (0: the solver's default)
bool g_self_collision = false; // --self-collision 1: the scene's v3 pass after every step
std::map<std::string, std::string> g_model_options;  // --model-option key=value (repeatable)

DrapeSceneSpec sheetSpec(int side_crossings, IntegratorType integrator, Real dt, Real until) {
  const Real L = 1e-3, side = (side_crossings - 1) * L;
  TextileOutline t;
  t.name = "yarn_sheet";
  t.outline = {Vec2(0, 0), Vec2(side, 0), Vec2(side, side), Vec2(0, side)};
  DrapeSceneSpec s;
  s.textile = t;
  s.spacing = L;
  s.hold = {HoldPoint{"", Vec2(0, side)}, HoldPoint{"", Vec2(side, side)}};
  s.model = ClothModelSpec("yarn_woven", g_model_options);
  s.settings.integrator = integrator;
  s.settings.policy = StepPolicy::kFixed;
  s.settings.dt = dt;
  s.settings.max_time = until;
  s.settings.rest_duration = 1e9;
  s.settings.memory_budget_bytes = 8e9;
  if (g_linear_tolerance > 0) s.settings.solver.relative_tolerance = g_linear_tolerance;
  if (g_accept_tolerance > 0) s.settings.solver.accept_tolerance = g_accept_tolerance;
  if (g_newton_tolerance > 0) s.settings.solver.newton_tolerance = g_newton_tolerance;
  if (!g_preconditioner.empty()) s.settings.solver.preconditioner = preconditionerFromString(g_preconditioner);
  s.settings.solver.warm_start = g_warm_start;
  if (g_smoothing_steps >= 0) s.settings.solver.smoothing_steps = g_smoothing_steps;
  if (g_smoothing_weight > 0) s.settings.solver.smoothing_weight = g_smoothing_weight;
  s.self_collision = g_self_collision;
  if (g_self_collision) s.collision.version = SelfCollisionVersion::kRollback;
  return s;
}

struct CostRow {
  int side = 0, threads = 0, repeat = 0;
  long crossings = 0, steps = 0;
  double wall_ms_per_step = 0, us_per_crossing_step = 0, assembly_ms = 0, solve_ms = 0, iterations = 0;
  double newton_iterations = 0;
  double forces_ms = 0, jacobians_ms = 0, collisions_ms = 0;  // per evaluation / per step
  double max_deviation_m = -1;  // largest node distance from the reference run; -1 = no reference
  bool diverged = false;
  std::string reason;
};

// Positions of the sheet after `steps` steps of the reference run (solver tolerance `tolerance`).
VecX referencePositions(int side, int steps, Real dt, IntegratorType integrator, Real tolerance) {
  DrapeSceneSpec spec = sheetSpec(side, integrator, dt, (steps + 1) * dt * (1 + 1e-9));
  spec.settings.solver.relative_tolerance = tolerance;
  spec.settings.solver.max_iterations = 20000;
  spec.settings.solver.accept_tolerance = 0;
  DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  const RunResult r = sim.run();
  if (r.diverged) throw std::runtime_error("the reference run (tolerance " + std::to_string(tolerance) + ") failed: " + r.divergence_reason);
  return sim.positions();
}

// One evaluation of the forces alone, and the extra time the Jacobians take (forces with Jacobians
// minus forces alone), at state x with zero velocity: the median of 3 each [ms].
void splitForcesAndJacobians(ClothModel& model, const VecX& x, double* forces_ms, double* jacobians_ms) {
  const VecX v = VecX::Zero(x.size());
  VecX f;
  ForceJacobians jac = model.makeJacobians();
  std::vector<double> alone, with;
  for (int k = 0; k < 3; ++k) {
    auto t0 = std::chrono::steady_clock::now();
    model.computeForces(x, v, f, nullptr);
    alone.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    t0 = std::chrono::steady_clock::now();
    model.computeForces(x, v, f, &jac);
    with.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  std::sort(alone.begin(), alone.end());
  std::sort(with.begin(), with.end());
  *forces_ms = alone[1];
  *jacobians_ms = std::max(0.0, with[1] - alone[1]);
}

CostRow measure(int side, int threads, int repeat, int steps, Real dt, IntegratorType integrator, const VecX& reference) {
  omp_set_num_threads(threads);
  const DrapeSceneSpec spec = sheetSpec(side, integrator, dt, (steps + 1) * dt * (1 + 1e-9));
  DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  // The first step allocates the Jacobians and the solver's structures once per run: it is left out.
  const RunResult first = sim.run(dt * (1 + 1e-9));
  const auto t0 = std::chrono::steady_clock::now();
  const RunResult r = first.diverged ? first : sim.run();
  const double wall = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  CostRow row;
  row.side = side, row.threads = threads, row.repeat = repeat;
  row.crossings = scene.model->numNodes();
  row.steps = std::max<long>(r.steps - first.steps, 1);
  row.wall_ms_per_step = wall / row.steps;
  row.us_per_crossing_step = 1e3 * row.wall_ms_per_step / row.crossings;
  row.assembly_ms = (r.assembly_ms - first.assembly_ms) / row.steps;
  row.solve_ms = (r.solve_ms - first.solve_ms) / row.steps;
  row.iterations = static_cast<double>(r.solver_iterations - first.solver_iterations) / row.steps;
  row.newton_iterations = static_cast<double>(r.newton_iterations - first.newton_iterations) / row.steps;
  row.collisions_ms = (r.post_step_ms - first.post_step_ms) / row.steps;
  splitForcesAndJacobians(*scene.model, sim.state(), &row.forces_ms, &row.jacobians_ms);
  if (reference.size() == sim.positions().size() && !r.diverged)
    row.max_deviation_m = (sim.positions() - reference).reshaped(3, reference.size() / 3).colwise().norm().maxCoeff();
  row.diverged = r.diverged;
  row.reason = r.divergence_reason;
  return row;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  std::string out = "out/yarn_step_bench", integrator_name = "semi_implicit";
  std::vector<double> sides = {32, 64, 128, 250}, stable_dts = {0.001, 0.002, 0.005, 0.01, 0.02, 0.05};
  int steps = 10, repeats = 3, stable_side = 25;
  Real dt = 1e-3, stable_time = 0.5, reference_tolerance = 1e-10;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::cerr << "yarn_step_bench: " << a << " needs a value (see the header of bench/yarn_step_bench.cpp)\n";
      return 2;
    }
    const std::string v = argv[++i];
    if (a == "--out") out = v;
    else if (a == "--sides") sides = parseList(v);
    else if (a == "--steps") steps = std::atoi(v.c_str());
    else if (a == "--dt") dt = std::atof(v.c_str());
    else if (a == "--integrator") integrator_name = v;
    else if (a == "--repeats") repeats = std::atoi(v.c_str());
    else if (a == "--stable-side") stable_side = std::atoi(v.c_str());
    else if (a == "--stable-time") stable_time = std::atof(v.c_str());
    else if (a == "--stable-dts") stable_dts = parseList(v);
    else if (a == "--linear-tolerance") g_linear_tolerance = std::atof(v.c_str());
    else if (a == "--accept-tolerance") g_accept_tolerance = std::atof(v.c_str());
    else if (a == "--newton-tolerance") g_newton_tolerance = std::atof(v.c_str());
    else if (a == "--preconditioner") g_preconditioner = v;
    else if (a == "--warm-start") g_warm_start = std::atoi(v.c_str()) != 0;
    else if (a == "--smoothing-steps") g_smoothing_steps = std::atoi(v.c_str());
    else if (a == "--smoothing-weight") g_smoothing_weight = std::atof(v.c_str());
    else if (a == "--self-collision") g_self_collision = std::atoi(v.c_str()) != 0;
    else if (a == "--reference-tolerance") reference_tolerance = std::atof(v.c_str());
    else if (a == "--model-option") {
      const auto eq = v.find('=');
      if (eq == std::string::npos || eq == 0) {
        std::cerr << "yarn_step_bench: --model-option needs key=value\n";
        return 2;
      }
      g_model_options[v.substr(0, eq)] = v.substr(eq + 1);
    }
    else {
      std::cerr << "yarn_step_bench: unknown option " << a << "\n";
      return 2;
    }
  }
  bool sides_ok = !sides.empty();
  for (double side : sides) sides_ok = sides_ok && side >= 2 && side <= 2000 && side == std::floor(side);
  if (!sides_ok || steps < 1 || repeats < 1 || !(dt > 0) || (stable_side != 0 && (stable_side < 2 || stable_side > 2000)) ||
      !(stable_time > 0) || stable_dts.empty() ||
      !std::all_of(stable_dts.begin(), stable_dts.end(), [](double h) { return h > 0; })) {
    std::cerr << "yarn_step_bench: sides must be whole numbers in 2..2000, --stable-side 0 or 2..2000, --steps and "
                 "--repeats >= 1, --dt, --stable-time and every --stable-dts value > 0\n";
    return 2;
  }
  IntegratorType integrator;
  try {
    integrator = integratorFromString(integrator_name);
  } catch (const std::exception& e) {
    std::cerr << "yarn_step_bench: " << e.what() << "\n";
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  std::ofstream cost(out + "/step_cost.csv"), stable(out + "/stable_step.csv");
  if (!cost || !stable) {
    std::cerr << "yarn_step_bench: cannot write into " << out << "\n";
    return 4;
  }
  cost << "side,crossings,threads,repeat,integrator,dt_s,steps,wall_ms_per_step,us_per_crossing_step,assembly_ms_per_step,"
          "solve_ms_per_step,forces_ms,jacobians_ms,collisions_ms_per_step,solver_iterations_per_step,newton_iterations_per_step,"
          "max_deviation_m,diverged\n";
  std::vector<ChartPoint> chart;
  try {
    for (double side_value : sides) {
      const int side = static_cast<int>(side_value);
      std::map<int, std::vector<double>> per_thread;
      const VecX reference = reference_tolerance > 0 ? referencePositions(side, steps, dt, integrator, reference_tolerance) : VecX();
      for (int r = 0; r < repeats; ++r)
        for (int threads : {1, 2}) {
          const CostRow row = measure(side, threads, r, steps, dt, integrator, reference);
          cost << row.side << ',' << row.crossings << ',' << row.threads << ',' << row.repeat << ',' << integrator_name << ','
               << dt << ',' << row.steps << ',' << row.wall_ms_per_step << ',' << row.us_per_crossing_step << ','
               << row.assembly_ms << ',' << row.solve_ms << ',' << row.forces_ms << ',' << row.jacobians_ms << ','
               << row.collisions_ms << ',' << row.iterations << ',' << row.newton_iterations << ','
               << row.max_deviation_m << ',' << (row.diverged ? 1 : 0) << '\n';
          cost.flush();
          per_thread[threads].push_back(row.us_per_crossing_step);
          std::printf("side %d (%ld crossings), %d thread(s), repeat %d: %.3g us per crossing-step (assembly %.3g ms, solve "
                      "%.3g ms, collisions %.3g ms per step; forces %.3g ms, Jacobians %.3g ms per evaluation; %.1f solver "
                      "and %.2f Newton iterations per step, %.3g m from the reference)%s\n",
                      side, row.crossings, threads, r, row.us_per_crossing_step, row.assembly_ms, row.solve_ms,
                      row.collisions_ms, row.forces_ms, row.jacobians_ms, row.iterations,
                      row.newton_iterations, row.max_deviation_m,
                      row.diverged ? (" DIVERGED: " + row.reason).c_str() : "");
          std::fflush(stdout);
          chart.push_back({static_cast<double>(row.crossings), row.us_per_crossing_step, "",
                           std::to_string(threads) + " thread" + (threads > 1 ? "s" : "")});
        }
      std::vector<double> ratios;
      for (int r = 0; r < repeats; ++r) ratios.push_back(per_thread[2][r] / per_thread[1][r]);
      std::sort(ratios.begin(), ratios.end());
      std::printf("side %d: median %.3g (1 thread) and %.3g (2 threads) us per crossing-step; 2/1 thread ratio "
                  "min %.3g median %.3g max %.3g\n",
                  side, median(per_thread[1]), median(per_thread[2]), ratios.front(), median(ratios), ratios.back());
    }
    omp_set_num_threads(1);
    stable << "side,crossings,dt_s,sim_time_s,stable,reason\n";
    if (stable_side > 0) {  // 0: no stable-step scan
      double largest = 0;
      for (double h : stable_dts) {
        const DrapeSceneSpec spec = sheetSpec(stable_side, integrator, h, stable_time);
        DrapeScene scene = buildDrapeScene(spec);
        DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
        const RunResult r = sim.run();
        stable << stable_side << ',' << scene.model->numNodes() << ',' << h << ',' << r.sim_time << ',' << (r.diverged ? 0 : 1)
               << ",\"" << r.divergence_reason << "\"\n";
        if (!r.diverged) largest = std::max(largest, h);
        std::printf("stable step: %d x %d crossings at dt %g s: %s\n", stable_side, stable_side, h,
                    r.diverged ? ("diverged: " + r.divergence_reason).c_str() : "stable");
      }
      std::printf("largest stable step of the %d x %d sheet over %g s: %g s\n", stable_side, stable_side, stable_time, largest);
    }
  } catch (const std::exception& e) {
    std::cerr << "yarn_step_bench: " << e.what() << "\n";
    return 5;
  }
  std::string error;
  if (!writeLogLogChart(out + "/step_cost.png", chart, "crossings", "microseconds per crossing-step",
                        "yarn_woven: cost per step (" + integrator_name + ")", &error)) {
    std::cerr << "yarn_step_bench: " << error << "\n";
    return 4;
  }
  return 0;
}
