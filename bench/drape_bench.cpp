// drape_bench: speed and accuracy of every integrator / time-step policy on the thesis towel.
//
//   drape_bench [--out DIR] [--quick] [--threads N] [--max-wall S] [--no-stability] [--only TEXT] [--spacing D]
//
// For the 64x46 cm cotton towel at d = 1 cm (and d = 0.5 cm unless --quick), held at a corner and at
// the middle of a short side, each configuration runs from the flat released sheet to rest. Its rest
// shape is compared with a reference computed at the same resolution with the semi-implicit
// integrator at a small fixed time step (1 ms, CG tolerance 1e-6, warm start), with the same model and
// collision setting.
// Writes DIR/sim_benchmark.csv and DIR/sim_benchmark.png (wall time against error, log-log, one point
// per configuration). This is a benchmark, not a test: nothing here asserts timings.
//
// Choi-Ko rows (model choi_ko) run the same towel scenes against their own small-step reference and
// report, in diff_from_particle_m, the mean distance of their rest shape from the particle model's
// reference rest shape. DIR/stability.csv: the compression scenes of stability_scenes.h for both models,
// a range of fixed steps, with and without damping (--no-stability skips it).
//
// At d = 0.5 cm only the particle-model configurations without collision run. --spacing D runs one
// resolution only. CSV rows are written as each run finishes.
//
// Every run is capped at --max-wall seconds of wall time (default 300): an explicit integrator at
// d = 0.5 cm would otherwise run for hours; a capped row says so in its note.
//
// Exit status: 0 done, 2 bad input or usage (also a scene over the memory budget), 4 outputs cannot
// be written, 5 out of memory or another unexpected error.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <new>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/bench/stability_scan.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/thread_limit.h"

using namespace textile_handling;

namespace {

/// One benchmarked configuration: a name for the chart and a change to the base scene.
struct Config {
  std::string label;
  std::function<void(DrapeSceneSpec&)> apply;
};

struct Row {
  std::string model, integrator, policy, solver, hold, collision, note;
  Real spacing = 0, error_tolerance = 0;
  Index particles = 0;
  long steps = 0, rejected = 0, collision_events = 0, intersecting_pairs = -1;
  Real sim_s = 0, wall_s = 0, ms_per_step = 0, assembly_ms = 0, solve_ms = 0, collision_ms = 0, cg_its = 0;
  Real mean_err = 0, max_err = 0, diff_from_particle = std::nan("");
  bool rest = false, diverged = false;
};

void shapeError(const VecX& a, const VecX& b, Real* mean, Real* max) {
  const Index n = static_cast<Index>(a.size() / 3);
  Real sum = 0, worst = 0;
  for (Index i = 0; i < n; ++i) {
    const Real e = (a.segment<3>(3 * i) - b.segment<3>(3 * i)).norm();
    sum += e;
    worst = std::max(worst, e);
  }
  *mean = sum / std::max<Index>(n, 1);
  *max = worst;
}

std::string solverLabel(const DrapeSceneSpec& s) {
  if (s.settings.integrator == IntegratorType::kRK4) return "none";
  if (s.settings.integrator == IntegratorType::kBlockDiagonalEuler) return "block_3x3";
  char buf[96];
  if (s.settings.integrator == IntegratorType::kBackwardEulerNewton) {
    std::snprintf(buf, sizeof buf, "newton%d_tol%g_pcr_block_jacobi_tol%g", s.settings.solver.newton_max_iterations,
                  s.settings.solver.newton_tolerance, s.settings.solver.relative_tolerance);
    return buf;
  }
  if (s.settings.solver.kind == LinearSolverKind::kDirect) return "direct_ldlt";
  std::snprintf(buf, sizeof buf, "cg_%s_tol%g%s", toString(s.settings.solver.preconditioner).c_str(),
                s.settings.solver.relative_tolerance, s.settings.solver.warm_start ? "_warm" : "");
  return buf;
}

struct Run {
  RunResult result;
  VecX x;
  long pairs = 0;
};

Run simulate(const DrapeSceneSpec& spec) {
  DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  Run r;
  r.result = sim.run();
  r.x = sim.positions();
  r.pairs = countIntersectingTrianglePairs(scene.triangles(), r.x);
  return r;
}

/// One CSV row; rows are appended as they finish, so an interrupted run keeps what it measured.
void writeCsvRow(std::ostream& f, const Row& r) {
  f << r.model << ',' << r.integrator << ',' << r.policy << ',' << r.error_tolerance << ',' << r.solver << ',' << r.collision << ','
    << r.spacing << ',' << r.particles << ',' << r.hold << ',' << r.steps << ',' << r.rejected << ',' << r.sim_s << ','
    << r.wall_s << ',' << r.ms_per_step << ',' << r.assembly_ms << ',' << r.solve_ms << ',' << r.collision_ms << ','
    << r.collision_events << ',' << r.cg_its << ',' << r.mean_err << ',' << r.max_err << ',' << r.diff_from_particle
    << ',' << r.intersecting_pairs << ',' << (r.rest ? "true" : "false") << ',' << (r.diverged ? "true" : "false")
    << ',' << omp_get_max_threads() << ",\"" << r.note << "\"\n";
  f.flush();
}

constexpr const char* kCsvHeader =
    "model,integrator,policy,error_tolerance_m,solver,collision,spacing_m,particles,hold,steps,rejected_steps,sim_time_s,wall_s,"
    "ms_per_step,assembly_ms_per_step,solve_ms_per_step,collision_ms_per_step,collision_events,cg_its_per_step,"
    "mean_err_m,max_err_m,diff_from_particle_m,intersecting_pairs,rest_reached,diverged,threads,note\n";

constexpr int kExitBadInput = 2;
constexpr int kExitOutput = 4;
constexpr int kExitInternal = 5;

// Throws OutputError if an earlier write to `f` failed (a full disk must not look like a finished run).
void checkWritten(const std::ostream& f, const std::string& path) {
  if (!f) throw OutputError("cannot write " + path + " (disk full or I/O error)");
}

int benchMain(int argc, char** argv) {
  std::string out_dir = "out/bench";
  bool quick = false, stability = true;
  std::string only;  // run only the configurations whose label contains this (and their references)
  Real max_wall = 300;
  Real only_spacing = 0;  // --spacing: run this resolution only
  int threads = 0;        // 0 = the OpenMP default (capped too)
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) out_dir = argv[++i];
    else if (a == "--quick") quick = true;
    else if (a == "--threads" && i + 1 < argc) {
      std::string error;
      if (!parseThreadCount(argv[++i], &threads, &error)) {
        std::cerr << "drape_bench: " << error << "\n";
        return kExitBadInput;
      }
    }
    else if (a == "--max-wall" && i + 1 < argc) max_wall = std::atof(argv[++i]);
    else if (a == "--no-stability") stability = false;
    else if (a == "--only" && i + 1 < argc) only = argv[++i];
    else if (a == "--spacing" && i + 1 < argc) only_spacing = std::atof(argv[++i]);
    else {
      std::cerr << "usage: drape_bench [--out DIR] [--quick] [--threads N] [--max-wall S] [--no-stability] [--only TEXT] [--spacing D]\n";
      return 2;
    }
  }
  if (!(max_wall > 0)) {
    std::cerr << "drape_bench: --max-wall must be positive\n";
    return 2;
  }
  std::string note;
  applyThreadLimit(threads, &note);
  if (!note.empty()) std::cout << "drape_bench: note: " << note << "\n";
  createDirectories(out_dir, 0755);
  checkWritableDirectory(out_dir);
  std::vector<Real> spacings = quick ? std::vector<Real>{0.01} : std::vector<Real>{0.01, 0.005};
  if (only_spacing > 0) spacings = {only_spacing};
  const std::string csv = out_dir + "/sim_benchmark.csv";
  std::ofstream csv_file(csv);
  csv_file << kCsvHeader << std::flush;
  checkWritten(csv_file, csv);
  const std::vector<std::string> holds = {"corner_ul", "short_side_left_mid"};
  auto integ = [](IntegratorType it, StepPolicy p, Real dt0) {
    return [=](DrapeSceneSpec& s) {
      s.settings.integrator = it;
      s.settings.policy = p;
      s.settings.dt = dt0;
    };
  };
  const std::vector<Config> configs = {
      {"semi_implicit/error fast", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kErrorControlled, 1e-3)(s);
         useFastSolverSettings(s.settings);
       }},
      {"semi_implicit/error", integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kErrorControlled, 1e-3)},
      {"semi_implicit/thesis", integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kThesis, 1e-3)},
      // The explicit and block-diagonal integrators need a tight error tolerance: at the implicit
      // runs' 1e-3 m their step hovers above the stability limit and energy grows until the
      // divergence check stops them (measured: t < 0.15 s at d = 1 cm; docs/simulation.md).
      {"block_diagonal/error tol 1e-5", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kBlockDiagonalEuler, StepPolicy::kErrorControlled, 1e-4)(s);
         s.settings.error_tolerance = 1e-5;
       }},
      // The thesis rule from the thesis's mean step (1e-4 s).
      {"block_diagonal/thesis", integ(IntegratorType::kBlockDiagonalEuler, StepPolicy::kThesis, 1e-4)},
      {"backward_euler_newton/error", integ(IntegratorType::kBackwardEulerNewton, StepPolicy::kErrorControlled, 1e-3)},
      // Inexact Newton: loose PCR solves, Newton's residual test still bounds every step.
      {"backward_euler_newton/error pcr 0.1", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kBackwardEulerNewton, StepPolicy::kErrorControlled, 1e-3)(s);
         s.settings.solver.relative_tolerance = 0.1;
       }},
      {"backward_euler_newton/thesis", integ(IntegratorType::kBackwardEulerNewton, StepPolicy::kThesis, 1e-3)},
      {"rk4/error tol 1e-5", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kRK4, StepPolicy::kErrorControlled, 1e-4)(s);
         s.settings.error_tolerance = 1e-5;
       }},
      {"semi_implicit/error fast + v3", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kErrorControlled, 1e-3)(s);
         useFastSolverSettings(s.settings);
         s.self_collision = true;
       }},
      {"choi_ko semi_implicit/error fast", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kErrorControlled, 1e-3)(s);
         useFastSolverSettings(s.settings);
         s.model = settlingModelSpec("choi_ko", 4.0);
         s.settings.max_time = 30.0;
       }},
      {"choi_ko backward_euler_newton/error", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kBackwardEulerNewton, StepPolicy::kErrorControlled, 1e-3)(s);
         s.model = settlingModelSpec("choi_ko", 4.0);
         s.settings.max_time = 30.0;
       }},
      {"choi_ko semi_implicit/fixed 10 ms, no damping", [&](DrapeSceneSpec& s) {
         integ(IntegratorType::kSemiImplicitEuler, StepPolicy::kFixed, 0.01)(s);
         s.model = settlingModelSpec("choi_ko", 0.0);
         s.settings.max_time = 30.0;
       }},
  };
  // At d = 0.5 cm only the particle model without collision runs (every integrator): the collision
  // target and the Choi-Ko comparison are defined at d = 1 cm, and each extra d = 0.5 cm reference costs
  // many minutes.
  auto selected = [&](const Config& c, Real d) {
    if (!only.empty() && c.label.find(only) == std::string::npos) return false;
    if (d >= 0.0099) return true;
    DrapeSceneSpec probe = benchmarkTowelSpec(d, "corner_ul");
    c.apply(probe);
    return probe.model.name == "particle_kes" && !probe.self_collision;
  };
  std::vector<Row> rows;
  std::cout << "drape_bench: " << omp_get_max_threads() << " threads, wall cap " << max_wall << " s per run\n";
  for (Real d : spacings) {
    for (const auto& hold : holds) {
      // References (one per collision setting), semi-implicit Euler at a small fixed step.
      // Keyed by (model, collision).
      std::map<std::pair<std::string, bool>, Run> refs;
      for (const auto& key : std::vector<std::pair<std::string, bool>>{
               {"particle_kes", false}, {"particle_kes", true}, {"choi_ko", false}}) {
        const bool collide = key.second;
        // Skip references no selected configuration needs (choi_ko rows need both models').
        bool needed = false;
        for (const auto& c : configs) {
          if (needed || !selected(c, d)) continue;
          DrapeSceneSpec probe = benchmarkTowelSpec(d, hold);
          c.apply(probe);
          needed = (probe.model.name == key.first && probe.self_collision == collide) ||
                   (probe.model.name != "particle_kes" && key.first == "particle_kes" && !collide);
        }
        if (!needed) continue;
        DrapeSceneSpec ref_spec = benchmarkTowelSpec(d, hold);
        ref_spec.model = settlingModelSpec(key.first, 4.0);
        ref_spec.self_collision = collide;
        // The Choi-Ko towel settles slowly (about 20 s simulated at d = 1 cm; docs/choi_ko.md).
        if (key.first == "choi_ko") ref_spec.settings.max_time = 30.0;
        ref_spec.settings.integrator = IntegratorType::kSemiImplicitEuler;
        ref_spec.settings.policy = StepPolicy::kFixed;
        ref_spec.settings.dt = 1e-3;
        // 1e-6 relative residual with a warm start: far below the step's own error at dt = 1 ms.
        ref_spec.settings.solver.relative_tolerance = 1e-6;
        ref_spec.settings.solver.warm_start = true;
        ref_spec.settings.solver.max_iterations = 5000;
        ref_spec.settings.max_wall_time = 3 * max_wall;
        refs[key] = simulate(ref_spec);
        const RunResult& rr = refs[key].result;
        std::printf("reference %s d=%.3f %-20s collision=%s rest=%d steps=%ld wall=%.1fs pairs=%ld%s\n", key.first.c_str(),
                    d, hold.c_str(), collide ? "v3" : "off", rr.rest_reached, rr.steps, rr.wall_time, refs[key].pairs,
                    rr.diverged ? (" DIVERGED: " + rr.divergence_reason).c_str() : "");
        std::fflush(stdout);
      }
      for (const auto& c : configs) {
        if (!selected(c, d)) continue;
        DrapeSceneSpec spec = benchmarkTowelSpec(d, hold);
        c.apply(spec);
        spec.settings.max_wall_time = max_wall;
        const Run run = simulate(spec);
        const RunResult& r = run.result;
        const Run& ref = refs[{spec.model.name, spec.self_collision}];
        Row row;
        row.model = spec.model.name;
        row.integrator = toString(spec.settings.integrator);
        row.policy = toString(spec.settings.policy);
        row.solver = solverLabel(spec);
        row.error_tolerance = spec.settings.policy == StepPolicy::kErrorControlled ? spec.settings.error_tolerance : 0;
        row.hold = hold;
        row.collision = spec.self_collision ? "v3" : "off";
        row.spacing = d;
        row.particles = static_cast<Index>(run.x.size() / 3);
        row.steps = r.steps;
        row.rejected = r.rejected_steps;
        row.sim_s = r.sim_time;
        row.wall_s = r.wall_time;
        const Real steps = std::max<Real>(1, static_cast<Real>(r.steps));
        row.ms_per_step = 1e3 * r.wall_time / steps;
        row.assembly_ms = r.assembly_ms / steps;
        row.solve_ms = r.solve_ms / steps;
        row.collision_ms = r.post_step_ms / steps;
        row.collision_events = r.post_step_events;
        row.cg_its = static_cast<Real>(r.solver_iterations) / steps;
        row.intersecting_pairs = run.pairs;
        row.rest = r.rest_reached;
        row.diverged = r.diverged;
        row.note = r.diverged ? "diverged at t=" + std::to_string(r.divergence_time) + ": " + r.divergence_reason
                   : r.rest_reached ? ""
                   : r.wall_cap_reached ? "wall-time cap"
                                        : "simulated-time cap";
        if (!ref.result.rest_reached) row.note += std::string(row.note.empty() ? "" : "; ") + "reference not at rest";
        if (!r.diverged) {
          shapeError(run.x, ref.x, &row.mean_err, &row.max_err);
          if (spec.model.name != "particle_kes") {
            Real worst = 0;
            shapeError(run.x, refs[{"particle_kes", false}].x, &row.diff_from_particle, &worst);
          }
        } else {
          row.mean_err = row.max_err = std::nan("");
        }
        std::printf("  %-30s steps=%6ld rej=%5ld sim=%5.2fs wall=%7.2fs %6.2fms/step (asm %.2f solve %.2f coll %.2f, "
                    "%.1f its) err mean=%.4f max=%.4f m pairs=%ld %s\n",
                    c.label.c_str(), row.steps, row.rejected, row.sim_s, row.wall_s, row.ms_per_step, row.assembly_ms,
                    row.solve_ms, row.collision_ms, row.cg_its, row.mean_err, row.max_err, row.intersecting_pairs,
                    row.note.c_str());
        std::fflush(stdout);
        rows.push_back(row);
        writeCsvRow(csv_file, row);
        checkWritten(csv_file, csv);
      }
    }
  }
  std::cout << "wrote " << csv << "\n";
  std::vector<ChartPoint> points;
  for (const auto& r : rows) {
    if (r.diverged) continue;
    char label[128];
    std::snprintf(label, sizeof label, "d=%.1fcm %s%s%s", 100 * r.spacing, r.hold == "corner_ul" ? "corner" : "side",
                  r.collision == "off" ? "" : " v3", r.rest ? "" : " (no rest)");
    const std::string fast = r.solver.find("warm") != std::string::npos ? " fast" : "";
    const std::string model = r.model == "particle_kes" ? "" : r.model + " ";
    points.push_back({std::max(r.wall_s, 1e-3), std::max(r.mean_err, 1e-6), label,
                      model + r.integrator + "/" + r.policy + fast});
  }
  std::string err;
  if (!writeLogLogChart(out_dir + "/sim_benchmark.png", points, "wall time to rest [s]", "mean rest-shape error [m]",
                        "drape_bench: towel 64x46 cm, cotton", &err))
    throw OutputError(err);
  std::cout << "wrote " << csv << " and " << out_dir << "/sim_benchmark.png\n";

  if (stability) {
    // Largest stable fixed step of each model in the compression scenes, with and without damping.
    const std::vector<Real> dts = {0.05, 0.02, 0.01, 0.005, 0.002, 0.001};
    std::vector<StabilityRow> all;
    for (const auto scene_kind : {CompressionScene::kPushedEdges, CompressionScene::kLoweredOntoTable}) {
      CompressionSceneSpec scene;
      scene.scene = scene_kind;
      scene.spacing = 0.02;
      for (const std::string model : {"choi_ko", "particle_kes", "particle_kes/definite_fix"}) {
        for (bool damping : {false, true}) {
          StabilityRunSpec run;
          run.model = ClothModelSpec(model == "choi_ko" ? "choi_ko" : "particle_kes");
          run.damping = damping;
          if (model == "particle_kes/definite_fix") run.model.set("jacobian", "definite_fix");
          const auto stability_rows = scanStability(scene, run, dts, model);
          std::printf("stability %-26s %-18s damping=%d largest stable dt = %.3f s\n", model.c_str(),
                      toString(scene_kind).c_str(), damping, largestStableDt(stability_rows));
          std::fflush(stdout);
          all.insert(all.end(), stability_rows.begin(), stability_rows.end());
        }
      }
    }
    writeFileAtomically(out_dir + "/stability.csv", [&](std::ostream& f) { writeStabilityCsv(f, all); });
    std::cout << "wrote " << out_dir << "/stability.csv\n";
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Nothing escapes main: each failure class has its own exit status.
  try {
    return benchMain(argc, argv);
  } catch (const OutputError& e) {
    std::cerr << "drape_bench: cannot write outputs: " << e.what() << "\n";
    return kExitOutput;
  } catch (const std::invalid_argument& e) {
    std::cerr << "drape_bench: " << e.what() << "\n";
    return kExitBadInput;
  } catch (const std::bad_alloc&) {
    std::cerr << "drape_bench: out of memory\n";
  } catch (const std::exception& e) {
    std::cerr << "drape_bench: unexpected error: " << e.what() << "\n";
  }
  return kExitInternal;
}
