// drape_bench: speed and accuracy of every integrator / time-step policy on the thesis towel.
//
//   drape_bench [--out DIR] [--quick] [--threads N]
//
// For the 64x46 cm cotton towel at d = 1 cm (and d = 0.5 cm unless --quick), held at a corner and at
// the middle of a short side, each configuration runs from the flat released sheet to rest. Its rest
// shape is compared with a reference computed at the same resolution with the semi-implicit
// integrator at a small fixed time step. Writes DIR/sim_benchmark.csv and DIR/sim_benchmark.png
// (wall time against error, log-log, one point per configuration). This is a benchmark, not a test:
// nothing here asserts timings.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "textile_handling/sim/bench_chart.h"
#include "textile_handling/sim/drape_scene.h"

using namespace textile_handling;

namespace {

struct Config {
  IntegratorType integrator;
  StepPolicy policy;
};

struct Row {
  std::string model, integrator, policy, hold;
  Real spacing = 0;
  Index particles = 0;
  long steps = 0, rejected = 0;
  Real sim_s = 0, wall_s = 0, ms_per_step = 0, mean_err = 0, max_err = 0;
  bool rest = false, diverged = false;
  std::string note;
};

DrapeSceneSpec towelSpec(Real spacing, const std::string& hold) {
  DrapeSceneSpec s;
  s.textile = presetTextile("towel");
  s.material = Material::cotton();
  s.spacing = spacing;
  s.hold = {HoldPoint{hold, Vec2::Zero()}};
  s.hold_position = Vec3(0, 0, 1.0);
  // Same settling damping for every configuration: it shortens the swinging, not the rest shape.
  s.model_options.settle_damping = 4.0;
  s.model_options.jacobian = JacobianMode::kDefiniteFix;
  s.settings.max_time = 8.0;
  s.settings.dt_max = 0.02;
  s.settings.error_tolerance = 1e-3;
  return s;
}

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

}  // namespace

int main(int argc, char** argv) {
  std::string out_dir = "out/bench";
  bool quick = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) out_dir = argv[++i];
    else if (a == "--quick") quick = true;
    else if (a == "--threads" && i + 1 < argc) omp_set_num_threads(std::atoi(argv[++i]));
    else {
      std::cerr << "usage: drape_bench [--out DIR] [--quick] [--threads N]\n";
      return 2;
    }
  }
  std::filesystem::create_directories(out_dir);
  const std::vector<Real> spacings = quick ? std::vector<Real>{0.01} : std::vector<Real>{0.01, 0.005};
  const std::vector<std::string> holds = {"corner_ul", "short_side_left_mid"};
  const std::vector<Config> configs = {
      {IntegratorType::kSemiImplicitEuler, StepPolicy::kErrorControlled},
      {IntegratorType::kSemiImplicitEuler, StepPolicy::kThesis},
      {IntegratorType::kBlockDiagonalEuler, StepPolicy::kErrorControlled},
      {IntegratorType::kBlockDiagonalEuler, StepPolicy::kThesis},
      {IntegratorType::kRK4, StepPolicy::kErrorControlled},
  };
  std::vector<Row> rows;
  std::cout << "drape_bench: " << omp_get_max_threads() << " threads\n";
  for (Real d : spacings) {
    for (const auto& hold : holds) {
      // Reference: semi-implicit Euler at a small fixed step, same resolution and rest criteria.
      DrapeSceneSpec ref_spec = towelSpec(d, hold);
      ref_spec.settings.integrator = IntegratorType::kSemiImplicitEuler;
      ref_spec.settings.policy = StepPolicy::kFixed;
      ref_spec.settings.dt = 1e-3;
      ref_spec.settings.solver.relative_tolerance = 1e-8;
      ref_spec.settings.solver.max_iterations = 5000;
      DrapeScene ref_scene = buildDrapeScene(ref_spec);
      DrapeSimulation ref(*ref_scene.model, ref_scene.pins, ref_spec.settings, ref_scene.x0, ref_scene.v0);
      const RunResult rr = ref.run();
      std::printf("reference d=%.3f %-20s rest=%d steps=%ld wall=%.1fs%s\n", d, hold.c_str(), rr.rest_reached, rr.steps,
                  rr.wall_time, rr.diverged ? (" DIVERGED: " + rr.divergence_reason).c_str() : "");
      for (const auto& c : configs) {
        DrapeSceneSpec spec = towelSpec(d, hold);
        spec.settings.integrator = c.integrator;
        spec.settings.policy = c.policy;
        spec.settings.dt = c.integrator == IntegratorType::kRK4 ? 1e-4 : 1e-3;
        DrapeScene scene = buildDrapeScene(spec);
        DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
        const RunResult r = sim.run();
        Row row;
        row.model = scene.model->name();
        row.integrator = toString(c.integrator);
        row.policy = toString(c.policy);
        row.hold = hold;
        row.spacing = d;
        row.particles = scene.model->numNodes();
        row.steps = r.steps;
        row.rejected = r.rejected_steps;
        row.sim_s = r.sim_time;
        row.wall_s = r.wall_time;
        row.ms_per_step = r.steps > 0 ? 1e3 * r.wall_time / r.steps : 0;
        row.rest = r.rest_reached;
        row.diverged = r.diverged;
        row.note = r.diverged ? r.divergence_reason : (r.rest_reached ? "" : "time cap");
        if (!r.diverged) shapeError(sim.positions(), ref.positions(), &row.mean_err, &row.max_err);
        else row.mean_err = row.max_err = std::nan("");
        std::printf("  %-15s %-6s steps=%6ld rej=%5ld sim=%5.2fs wall=%7.2fs %6.2fms/step err mean=%.4f max=%.4f m%s\n",
                    row.integrator.c_str(), row.policy.c_str(), row.steps, row.rejected, row.sim_s, row.wall_s,
                    row.ms_per_step, row.mean_err, row.max_err, row.rest ? "" : (" (" + row.note + ")").c_str());
        rows.push_back(row);
      }
    }
  }
  const std::string csv = out_dir + "/sim_benchmark.csv";
  {
    std::ofstream f(csv);
    f << "model,integrator,policy,spacing_m,particles,hold,steps,rejected_steps,sim_time_s,wall_s,ms_per_step,"
         "mean_err_m,max_err_m,rest_reached,diverged,note\n";
    for (const auto& r : rows)
      f << r.model << ',' << r.integrator << ',' << r.policy << ',' << r.spacing << ',' << r.particles << ',' << r.hold
        << ',' << r.steps << ',' << r.rejected << ',' << r.sim_s << ',' << r.wall_s << ',' << r.ms_per_step << ','
        << r.mean_err << ',' << r.max_err << ',' << (r.rest ? "true" : "false") << ','
        << (r.diverged ? "true" : "false") << ",\"" << r.note << "\"\n";
  }
  std::vector<ChartPoint> points;
  for (const auto& r : rows) {
    if (r.diverged) continue;
    char label[96];
    std::snprintf(label, sizeof label, "%s/%s d=%.1fcm %s", r.integrator.c_str(), r.policy.c_str(), 100 * r.spacing,
                  r.hold == "corner_ul" ? "corner" : "side");
    points.push_back({r.wall_s, std::max(r.mean_err, 1e-6), label, r.integrator + "/" + r.policy});
  }
  std::string err;
  if (!writeLogLogChart(out_dir + "/sim_benchmark.png", points, "wall time to rest [s]", "mean rest-shape error [m]",
                        "drape_bench: towel 64x46 cm, cotton", &err))
    std::cerr << "drape_bench: " << err << "\n";
  std::cout << "wrote " << csv << " and " << out_dir << "/sim_benchmark.png\n";
  return 0;
}
