// drape_sim: runs one drape scene from YAML and writes the rest shape, a picture and a resumable state.
//
//   drape_sim SCENE.yaml [--out DIR] [--resume STATE] [--until T] [--threads N] [--memory-budget-mb M]
//
// A scene with model: {name: auto} first runs the automatic choice (docs/automatic_configuration.md) and
// prints it. Outputs in DIR (default out/drape_sim): result.yaml (run summary), rest_positions.csv, rest_shape.png,
// state.txt (save file; `--resume DIR/state.txt` continues the run), trajectory.csv when the scene sets
// simulation.trajectory_every. The scene's collision/obstacles sections turn on the post-step passes;
// result.yaml reports their cost per step and the intersecting triangle pairs of the final shape.
// Exit status (docs/simulation.md): 0 rest reached or time cap, 2 bad input or usage, 3 divergence,
// 4 outputs cannot be written, 5 out of memory or another unexpected error.
#include <omp.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <string>

#include "textile_handling/db/automatic_configuration.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/rest_shape_picture.h"
#include "textile_handling/sim/thread_limit.h"
#include "tool_main.h"

using namespace textile_handling;

namespace {

constexpr int kExitBadInput = 2;
constexpr int kExitDiverged = 3;
constexpr int kExitOutput = 4;

int usage(const char* argv0, const std::string& problem = "") {
  if (!problem.empty()) std::cerr << "drape_sim: " << problem << "\n";
  std::cerr << "usage: " << argv0
            << " SCENE.yaml [--out DIR] [--resume STATE] [--until T] [--threads N] [--memory-budget-mb M]\n";
  return kExitBadInput;
}

struct Options {
  std::string scene_path, out_dir = "out/drape_sim", resume;
  Real until = std::numeric_limits<Real>::infinity();
  int threads = 0;                      // 0 = the OpenMP default (capped too)
  std::size_t memory_budget_bytes = 0;  // 0 = half of physical memory
};

// A whole positive number with nothing after it; false otherwise.
bool parsePositive(const std::string& text, double* value) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || errno == ERANGE || !(v > 0) || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

// Parses the command line into `o`; returns an error message, or "" if the arguments are valid.
std::string parseArguments(int argc, char** argv, Options& o) {
  if (argc < 2) return "no scene file given";
  o.scene_path = argv[1];
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return "option " + a + " needs a value";
    const std::string value = argv[++i];
    double number = 0;
    std::string error;
    if (a == "--out") {
      o.out_dir = value;
    } else if (a == "--resume") {
      o.resume = value;
    } else if (a == "--until") {
      if (!parsePositive(value, &number)) return "--until must be a positive number of seconds, got '" + value + "'";
      o.until = number;
    } else if (a == "--threads") {
      if (!parseThreadCount(value, &o.threads, &error)) return error;
    } else if (a == "--memory-budget-mb") {
      if (!parsePositive(value, &number) || number > 1e12)
        return "--memory-budget-mb must be a positive number of MiB, got '" + value + "'";
      o.memory_budget_bytes = static_cast<std::size_t>(number * 1024 * 1024);
    } else {
      return "unknown option " + a;
    }
  }
  return "";
}

void writeSummary(std::ostream& os, const DrapeScene& scene, const RunResult& r, Real depth, long pairs) {
  const auto per_step = [&](Real ms) { return r.steps > 0 ? ms / r.steps : 0.0; };
  os << "textile: " << scene.spec.textile.name << "\n"
     << "hold_point: \"" << (scene.spec.hold.empty() ? std::string("region") : scene.spec.hold.front().label()) << "\"\n"
     << "model: " << scene.model->name() << "\n"
     << "integrator: " << toString(scene.spec.settings.integrator) << "\n"
     << "policy: " << toString(scene.spec.settings.policy) << "\n"
     << "spacing_m: " << scene.spec.spacing << "\n"
     << "particles: " << scene.model->numNodes() << "\n"
     << "rest_reached: " << (r.rest_reached ? "true" : "false") << "\n"
     << "diverged: " << (r.diverged ? "true" : "false") << "\n"
     << "divergence_reason: \"" << r.divergence_reason << "\"\n"
     << "divergence_time_s: " << r.divergence_time << "\n"
     << "sim_time_s: " << r.sim_time << "\n"
     << "steps: " << r.steps << "\n"
     << "rejected_steps: " << r.rejected_steps << "\n"
     << "mean_dt_s: " << r.mean_dt << "\n"
     << "solver_iterations: " << r.solver_iterations << "\n"
     << "wall_time_s: " << r.wall_time << "\n"
     << "kinetic_energy_J: " << r.kinetic_energy << "\n"
     << "potential_energy_J: " << r.potential_energy << "\n"
     << "hanging_depth_m: " << depth << "\n"
     << "self_collision: " << (scene.spec.self_collision ? toString(scene.spec.collision.version) : "off") << "\n"
     << "obstacles: " << (scene.spec.obstacles.planes.size() + scene.spec.obstacles.boxes.size() +
                          scene.spec.obstacles.spheres.size()) << "\n"
     << "collision_events: " << r.post_step_events << "\n"
     << "torn_segments: " << r.torn_segments << "\n"
     << "collision_ms_per_step: " << per_step(r.post_step_ms) << "\n"
     << "assembly_ms_per_step: " << per_step(r.assembly_ms) << "\n"
     << "solve_ms_per_step: " << per_step(r.solve_ms) << "\n"
     << "intersecting_pairs: " << pairs << "\n";
  if (scene.self_collision_pass) {
    // Where the self-collision time goes (ms per accepted step), docs/collision.md.
    const SelfCollisionStats& t = scene.self_collision_pass->totalStats();
    os << "self_collision_breakdown_ms_per_step:\n"
      << "  broad_phase: " << per_step(t.broad_ms) << "\n"
      << "  proximity_detect: " << per_step(t.proximity_detect_ms) << "\n"
      << "  proximity_total: " << per_step(t.proximity_ms) << "\n"
      << "  crossing_detect: " << per_step(t.detect_ms) << "\n"
      << "  resolve: " << per_step(t.resolve_ms) << "\n"
      << "self_collision_candidate_list_builds: " << t.candidate_list_builds << "\n"
      << "self_collision_proximity_list_builds: " << t.proximity_list_builds << "\n"
      << "self_collision_detections_from_proximity_build: " << t.detections_from_proximity_build << "\n";
  }
}

// The rest shape's files; throws OutputError on any failed write.
void writeOutputs(const std::string& out_dir, const DrapeScene& scene, const DrapeSimulation& sim, const RunResult& r,
                  Real depth, long pairs) {
  writeFileAtomically(out_dir + "/result.yaml", [&](std::ostream& f) { writeSummary(f, scene, r, depth, pairs); });
  writeFileAtomically(out_dir + "/rest_positions.csv", [&](std::ostream& f) {
    f << "particle,row,col,x_m,y_m,z_m\n";
    f.precision(9);
    const auto& x = sim.positions();
    for (Index k = 0; k < scene.model->numNodes(); ++k)
      f << k << ',' << scene.grid.compactRows()[k] << ',' << scene.grid.compactCols()[k] << ',' << x[3 * k] << ','
        << x[3 * k + 1] << ',' << x[3 * k + 2] << '\n';
  });
  if (!sim.trajectory().empty()) {
    writeFileAtomically(out_dir + "/trajectory.csv", [&](std::ostream& f) {
      f << "t_s,particle,x_m,y_m,z_m\n";
      for (const auto& fr : sim.trajectory())
        for (Index k = 0; k < scene.model->numNodes(); ++k)
          f << fr.t << ',' << k << ',' << fr.x[3 * k] << ',' << fr.x[3 * k + 1] << ',' << fr.x[3 * k + 2] << '\n';
    });
  }
  sim.save(out_dir + "/state.txt");
  if (!r.diverged) {
    std::string err;
    if (!writeRestShapePicture(out_dir + "/rest_shape.png", ParticleTopology::fromGrid(scene.grid), sim.positions(),
                               {scene.hold_particle}, scene.model->drawnYarns(), 400, &err))
      throw OutputError(err);
  }
}

// model: {name: auto}: the resolution search on the scene itself (automatic_configuration.h); the choice
// and its evidence are printed and the scene runs with it.
void chooseAutomatically(DrapeSceneSpec& spec) {
  db::AutomaticChoiceOptions o;
  o.question = db::yarnScaleQuestionFromString(spec.automatic.question);
  if (!spec.automatic.spacings.empty()) o.spacings = spec.automatic.spacings;
  o.named_point_tolerance_m = spec.automatic.named_point_tolerance_m;
  o.min_mean_iou = spec.automatic.min_mean_iou;
  o.on_progress = [](const std::string& line) { std::cout << "auto: " << line << "\n" << std::flush; };
  DrapeSceneSpec sample = spec;
  sample.automatic = AutomaticModelRequest();
  const db::AutomaticChoice choice = db::chooseConfiguration({sample}, o);
  std::cout << "automatic choice (" << choice.search_wall_s << " s of search):\n" << choice.text();
  choice.applyTo(sample);
  spec = sample;
}

int run(const Options& o) {
  std::string note;
  applyThreadLimit(o.threads, &note);
  if (!note.empty()) std::cout << "drape_sim: note: " << note << "\n";
  DrapeScene scene;
  try {
    DrapeSceneSpec spec = loadDrapeSceneYaml(o.scene_path);
    spec.settings.memory_budget_bytes = o.memory_budget_bytes;
    if (spec.automatic.requested) chooseAutomatically(spec);
    scene = buildDrapeScene(spec);
  } catch (const std::invalid_argument& e) {
    std::cerr << "drape_sim: " << o.scene_path << ": " << e.what() << "\n";
    return kExitBadInput;
  } catch (const db::InvalidInputError& e) {  // the automatic choice's options (model.question, ...)
    std::cerr << "drape_sim: " << o.scene_path << ": " << e.what() << "\n";
    return kExitBadInput;
  }
  // The output directory must be usable before the (possibly long) simulation starts.
  try {
    createDirectories(o.out_dir, 0755);
    checkWritableDirectory(o.out_dir);
  } catch (const OutputError& e) {
    std::cerr << "drape_sim: " << e.what() << "\n";
    return kExitOutput;
  }
  DrapeSimulation sim(*scene.model, scene.pins, scene.spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  if (!o.resume.empty()) {
    try {
      sim.load(o.resume);
    } catch (const std::exception& e) {
      std::cerr << "drape_sim: " << e.what() << "\n";
      return kExitBadInput;
    }
    std::cout << "resumed at t = " << sim.time() << " s\n";
  }
  std::cout << "simulating " << scene.spec.textile.name << " (" << scene.model->numNodes() << " particles, d = "
            << scene.spec.spacing << " m) held at "
            << (scene.spec.hold.empty() ? std::string("region") : scene.spec.hold.front().label()) << " with "
            << toString(scene.spec.settings.integrator) << " / " << toString(scene.spec.settings.policy) << " steps, "
            << omp_get_max_threads() << " threads\n";
  const RunResult r = sim.run(o.until);
  const Real depth = hangingDepth(scene, sim.positions());
  // Independent check of the rest shape: exact triangle-triangle tests over the whole mesh.
  const long pairs = countIntersectingTrianglePairs(scene.triangles(), sim.positions());
  writeSummary(std::cout, scene, r, depth, pairs);
  try {
    writeOutputs(o.out_dir, scene, sim, r, depth, pairs);
  } catch (const OutputError& e) {
    std::cerr << "drape_sim: cannot write outputs: " << e.what() << "\n";
    return kExitOutput;
  }
  std::cout << "outputs in " << o.out_dir << "/ (result.yaml, rest_positions.csv, rest_shape.png, state.txt)\n";
  if (r.diverged) {
    std::cerr << "drape_sim: simulation diverged at t = " << r.divergence_time << " s: " << r.divergence_reason << "\n";
    return kExitDiverged;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  const std::string problem = parseArguments(argc, argv, options);
  if (!problem.empty()) return usage(argv[0], problem);
  return runGuarded("drape_sim", "use a coarser spacing_m or a smaller --memory-budget-mb", [&] { return run(options); });
}
