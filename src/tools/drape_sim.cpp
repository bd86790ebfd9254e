// drape_sim: runs one drape scene from YAML and writes the rest shape, a picture and a resumable state.
//
//   drape_sim SCENE.yaml [--out DIR] [--resume STATE] [--until T] [--threads N]
//
// Outputs in DIR (default out/drape_sim): result.yaml (run summary), rest_positions.csv, rest_shape.png,
// state.txt (save file; `--resume DIR/state.txt` continues the run), trajectory.csv when the scene sets
// simulation.trajectory_every. The scene's collision/obstacles sections turn on the post-step passes;
// result.yaml reports their cost per step and the intersecting triangle pairs of the final shape.
// Exit status: 0 rest reached or time cap, 2 bad input, 3 divergence.
#include <omp.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/rest_shape_picture.h"

using namespace textile_handling;

namespace {

int usage(const char* argv0) {
  std::cerr << "usage: " << argv0 << " SCENE.yaml [--out DIR] [--resume STATE] [--until T] [--threads N]\n";
  return 2;
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

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage(argv[0]);
  std::string scene_path = argv[1], out_dir = "out/drape_sim", resume;
  Real until = std::numeric_limits<Real>::infinity();
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage(argv[0]);
    if (a == "--out") out_dir = argv[++i];
    else if (a == "--resume") resume = argv[++i];
    else if (a == "--until") until = std::atof(argv[++i]);
    else if (a == "--threads") omp_set_num_threads(std::atoi(argv[++i]));
    else return usage(argv[0]);
  }
  DrapeScene scene;
  try {
    scene = buildDrapeScene(loadDrapeSceneYaml(scene_path));
  } catch (const std::exception& e) {
    std::cerr << "drape_sim: " << e.what() << "\n";
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) {
    std::cerr << "drape_sim: cannot create " << out_dir << ": " << ec.message() << "\n";
    return 2;
  }
  DrapeSimulation sim(*scene.model, scene.pins, scene.spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  if (!resume.empty()) {
    try {
      sim.load(resume);
    } catch (const std::exception& e) {
      std::cerr << "drape_sim: " << e.what() << "\n";
      return 2;
    }
    std::cout << "resumed at t = " << sim.time() << " s\n";
  }
  std::cout << "simulating " << scene.spec.textile.name << " (" << scene.model->numNodes() << " particles, d = "
            << scene.spec.spacing << " m) held at "
            << (scene.spec.hold.empty() ? std::string("region") : scene.spec.hold.front().label()) << " with "
            << toString(scene.spec.settings.integrator) << " / " << toString(scene.spec.settings.policy) << " steps, "
            << omp_get_max_threads() << " threads\n";
  const RunResult r = sim.run(until);
  const Real depth = hangingDepth(scene, sim.positions());
  // Independent check of the rest shape: exact triangle-triangle tests over the whole mesh.
  const long pairs = countIntersectingTrianglePairs(scene.triangles(), sim.positions());
  writeSummary(std::cout, scene, r, depth, pairs);
  {
    std::ofstream f(out_dir + "/result.yaml");
    writeSummary(f, scene, r, depth, pairs);
  }
  {
    std::ofstream f(out_dir + "/rest_positions.csv");
    f << "particle,row,col,x_m,y_m,z_m\n";
    f.precision(9);
    const auto& x = sim.positions();
    for (Index k = 0; k < scene.model->numNodes(); ++k)
      f << k << ',' << scene.grid.compactRows()[k] << ',' << scene.grid.compactCols()[k] << ',' << x[3 * k] << ','
        << x[3 * k + 1] << ',' << x[3 * k + 2] << '\n';
  }
  if (!sim.trajectory().empty()) {
    std::ofstream f(out_dir + "/trajectory.csv");
    f << "t_s,particle,x_m,y_m,z_m\n";
    for (const auto& fr : sim.trajectory())
      for (Index k = 0; k < scene.model->numNodes(); ++k)
        f << fr.t << ',' << k << ',' << fr.x[3 * k] << ',' << fr.x[3 * k + 1] << ',' << fr.x[3 * k + 2] << '\n';
  }
  try {
    sim.save(out_dir + "/state.txt");
  } catch (const std::exception& e) {
    std::cerr << "drape_sim: " << e.what() << "\n";
  }
  if (!r.diverged) {
    std::string err;
    if (!writeRestShapePicture(out_dir + "/rest_shape.png", ParticleTopology::fromGrid(scene.grid), sim.positions(),
                               {scene.hold_particle}, 400, &err))
      std::cerr << "drape_sim: " << err << "\n";
  }
  std::cout << "outputs in " << out_dir << "/ (result.yaml, rest_positions.csv, rest_shape.png, state.txt)\n";
  if (r.diverged) {
    std::cerr << "drape_sim: simulation diverged at t = " << r.divergence_time << " s: " << r.divergence_reason << "\n";
    return 3;
  }
  return 0;
}
