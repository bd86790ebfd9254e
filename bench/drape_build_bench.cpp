// drape_build_bench: database-build speed, today's dynamic rest shapes against the quasi-static fast
// path (rest_shape_search.h), on the thesis's towel database (6 x 6 hold points in one quadrant).
//
//   drape_build_bench [--out DIR] [--spacings D1,D2,...] [--grid NXxNY] [--holds K] [--mode holds|build|both]
//                     [--workers N] [--repeats R] [--corner-reference] [--settle SPEED,MEAN,DURATION]
//                     [--settle-tolerance M] [--coarse-spacing D] [--finish-iterations N]
//
// holds: every hold point of the grid (or its first K) simulated one after the other on one thread,
//   the two methods interleaved per hold point (dynamic, quasi-static); per hold point the wall times,
//   their ratio and the rest-shape difference: the largest distance between the two rest shapes over the
//   textile's named points (corners, edge midpoints) and over all particles. Rows: DIR/build_holds.csv.
// build: the whole database (views rendered, rows stored, mirrored rows derived) with
//   DrapeDatabaseBuilder, --workers workers (0 = automatic), both methods, alternating, --repeats times
//   each (ABAB...). Rows: DIR/build_whole.csv.
// --corner-reference: one dynamic simulation of the corner hold (0, 0.46) m with the builder's settings
//   on one thread, for each spacing and repeat, interleaved with the build rows (the yardstick:
//   the whole fast build should take no longer than this one simulation).
// DIR/build_speed.png: seconds per hold point against the rest-shape difference, one point per hold
// point and method. Benchmarks, not tests: nothing here asserts timings. Set OMP_WAIT_POLICY=passive.
//
// Exit status: 0 done, 2 usage, 4 outputs cannot be written, 5 unexpected error.
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/textile_symmetry.h"
#include "textile_handling/sim/rest_shape_search.h"
#include "textile_handling/sim/thread_limit.h"
#include "textile_handling/sim/timing.h"

using namespace textile_handling;

namespace {

struct Options {
  std::string out = "bench_out";
  std::vector<Real> spacings = {0.02, 0.01, 0.02 / 3};
  int nx = 6, ny = 6, holds = 0, workers = 0, repeats = 1;
  std::string mode = "holds";
  bool corner_reference = false;
  RestShapeSettings fast;  ///< the quasi-static settings (--settle, --coarse-spacing, --finish-iterations)
};

std::vector<Real> parseList(const std::string& s) {
  std::vector<Real> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

Options parseArgs(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--out") o.out = next();
    else if (a == "--spacings") o.spacings = parseList(next());
    else if (a == "--grid") {
      const std::string g = next();
      const auto x = g.find('x');
      if (x == std::string::npos) throw std::invalid_argument("--grid: expected NXxNY");
      o.nx = std::stoi(g.substr(0, x));
      o.ny = std::stoi(g.substr(x + 1));
    } else if (a == "--holds") o.holds = std::stoi(next());
    else if (a == "--mode") o.mode = next();
    else if (a == "--workers") o.workers = std::stoi(next());
    else if (a == "--repeats") o.repeats = std::stoi(next());
    else if (a == "--corner-reference") o.corner_reference = true;
    else if (a == "--settle") {
      const std::vector<Real> v = parseList(next());
      if (v.size() != 3) throw std::invalid_argument("--settle: SPEED,MEAN_SPEED,DURATION");
      o.fast.settle_speed = v[0];
      o.fast.settle_mean_speed = v[1];
      o.fast.settle_duration = v[2];
    } else if (a == "--settle-tolerance") o.fast.settle_error_tolerance = std::stod(next());
    else if (a == "--coarse-spacing") o.fast.coarse_spacing = std::stod(next());
    else if (a == "--finish-iterations") o.fast.finish.max_iterations = std::stoi(next());
    else throw std::invalid_argument("unknown option " + a);
  }
  o.fast.method = RestShapeMethod::kQuasiStatic;
  o.fast.validate();
  if (o.mode != "holds" && o.mode != "build" && o.mode != "both") throw std::invalid_argument("--mode: holds, build or both");
  for (Real d : o.spacings)
    if (!(d >= 0.004 && d <= 0.1)) throw std::invalid_argument("--spacings: each in [0.004, 0.1] m");
  if (o.nx < 1 || o.ny < 1 || o.holds < 0 || o.workers < 0 || o.repeats < 1) throw std::invalid_argument("bad count");
  return o;
}

db::DrapeBuildConfig baseConfig(const Options& o, Real spacing) {
  db::DrapeBuildConfig c;
  c.textile = presetTextile("towel");
  c.spacing = spacing;
  c.hold_points = db::fundamentalDomainGrid(c.textile, db::detectSymmetry(c.textile), o.nx, o.ny);
  if (o.holds > 0 && static_cast<int>(c.hold_points.size()) > o.holds) c.hold_points.resize(o.holds);
  return c;
}

struct ShapeDistance {
  Real named = 0;  ///< largest named-point distance [m]
  Real all = 0;    ///< largest particle distance [m]
};

ShapeDistance shapeDistance(const DrapeScene& scene, const VecX& a, const VecX& b) {
  ShapeDistance d;
  for (const auto& np : scene.named_particles)
    d.named = std::max(d.named, (a.segment<3>(3 * np.second) - b.segment<3>(3 * np.second)).norm());
  for (Index i = 0; i < a.size() / 3; ++i) d.all = std::max(d.all, (a.segment<3>(3 * i) - b.segment<3>(3 * i)).norm());
  return d;
}

std::string num(double v, int prec = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", prec, v);
  return buf;
}

void holdsMode(const Options& o, std::vector<ChartPoint>* chart) {
  const std::string path = o.out + "/build_holds.csv";
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error("cannot write " + path);
  csv << "spacing_m,particles,hold_x_m,hold_y_m,dynamic_s,dynamic_steps,dynamic_rest,fast_s,fast_method,fast_coarse_steps,"
         "fast_coarse_finish_iterations,fast_finish_iterations,fast_residual,fast_dynamic_phase_s,fast_coarse_finish_s,fast_finish_s,speedup,named_point_distance_m,"
         "max_particle_distance_m\n";
  for (Real d : o.spacings) {
    const db::DrapeBuildConfig c = baseConfig(o, d);
    for (const Vec2& hold : c.hold_points) {
      const DrapeSceneSpec spec = db::DrapeDatabaseBuilder::sceneSpec(c, hold);
      RestShapeSettings dyn;
      dyn.method = RestShapeMethod::kDynamic;
      DrapeScene s_dyn = buildDrapeScene(spec);
      const RestShapeResult r_dyn = findRestShape(s_dyn, dyn);
      DrapeScene s_fast = buildDrapeScene(spec);
      const RestShapeResult r_fast = findRestShape(s_fast, o.fast);
      const ShapeDistance dist = shapeDistance(s_dyn, r_dyn.positions, r_fast.positions);
      csv << num(d) << "," << s_dyn.grid.numActive() << "," << num(hold.x()) << "," << num(hold.y()) << ","
          << num(r_dyn.wall_seconds) << "," << r_dyn.steps << "," << r_dyn.rest_reached << "," << num(r_fast.wall_seconds)
          << ",\"" << r_fast.method_used << "\"," << r_fast.steps << "," << r_fast.coarse_finish.iterations << ","
          << r_fast.finish.iterations << "," << num(r_fast.finish.residual_ratio) << "," << num(r_fast.dynamic.wall_time) << ","
          << num(r_fast.coarse_finish.wall_ms / 1000) << "," << num(r_fast.finish.wall_ms / 1000 + r_fast.finish_run.wall_time) << ","
          << num(r_dyn.wall_seconds / r_fast.wall_seconds) << "," << num(dist.named) << "," << num(dist.all) << "\n"
          << std::flush;
      std::cerr << "d " << num(d, 3) << " hold (" << num(hold.x(), 3) << ", " << num(hold.y(), 3) << "): dynamic "
                << num(r_dyn.wall_seconds, 3) << " s, fast " << num(r_fast.wall_seconds, 3) << " s (" << r_fast.method_used
                << ": dynamic phase " << num(r_fast.dynamic.wall_time, 3) << " s, coarse finish "
                << num(r_fast.coarse_finish.wall_ms / 1000, 3) << " s (" << r_fast.coarse_finish.iterations << " it), finish "
                << num(r_fast.finish.wall_ms / 1000 + r_fast.finish_run.wall_time, 3) << " s (" << r_fast.finish.iterations << " it, "
                << r_fast.finish_run.steps << " steps)), named points " << num(1000 * dist.named, 3) << " mm, all " << num(1000 * dist.all, 3) << " mm\n";
      const std::string series = "d = " + num(100 * d, 2) + " cm";
      chart->push_back({r_dyn.wall_seconds, std::max(1e-5, dist.named), "", series + " dynamic"});
      chart->push_back({r_fast.wall_seconds, std::max(1e-5, dist.named), "", series + " quasi-static"});
    }
  }
}

double cornerReference(Real d) {
  db::DrapeBuildConfig c;
  c.spacing = d;
  c.textile = presetTextile("towel");
  DrapeScene s = buildDrapeScene(db::DrapeDatabaseBuilder::sceneSpec(c, Vec2(0.0, 0.46)));
  RestShapeSettings dyn;
  dyn.method = RestShapeMethod::kDynamic;
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const RestShapeResult r = findRestShape(s, dyn);
  omp_set_num_threads(saved);
  return r.wall_seconds;
}

void buildMode(const Options& o) {
  const std::string path = o.out + "/build_whole.csv";
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error("cannot write " + path);
  csv << "spacing_m,repeat,method,hold_points,simulated,failed,workers,threads_per_simulation,wall_s,"
         "simulation_s_sum,corner_reference_s\n";
  for (Real d : o.spacings) {
    for (int rep = 0; rep < o.repeats; ++rep) {
      for (RestShapeMethod m : {RestShapeMethod::kDynamic, RestShapeMethod::kQuasiStatic}) {
        db::DrapeBuildConfig c = baseConfig(o, d);
        c.rest_shape = o.fast;
        c.rest_shape.method = m;
        c.workers = o.workers;
        db::DrapeBuildPass pass;
        c.on_pass_start = [&pass](const db::DrapeBuildPass& p) { pass = p; };
        const std::string file = o.out + "/build_tmp.sqlite";
        for (const char* ext : {"", "-wal", "-shm"}) std::filesystem::remove(file + ext);
        db::DrapeBuildReport rep_out;
        {
          db::HangingDrapeDatabase database(file);
          db::DrapeDatabaseBuilder builder(database, c);
          rep_out = builder.build();
        }
        for (const char* ext : {"", "-wal", "-shm"}) std::filesystem::remove(file + ext);
        const double corner = o.corner_reference ? cornerReference(d) : 0.0;
        csv << num(d) << "," << rep << "," << toString(m) << "," << rep_out.planned << "," << rep_out.simulated_now << ","
            << rep_out.failed_now << "," << pass.workers << "," << pass.threads_per_simulation << ","
            << num(rep_out.wall_seconds) << "," << num(rep_out.simulation_seconds) << "," << num(corner) << "\n"
            << std::flush;
        std::cerr << "d " << num(d, 3) << " " << toString(m) << ": " << rep_out.planned << " rows in "
                  << num(rep_out.wall_seconds, 4) << " s (" << pass.workers << " x " << pass.threads_per_simulation
                  << "), corner reference " << num(corner, 4) << " s\n";
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parseArgs(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "drape_build_bench: " << e.what() << "\n";
    return 2;
  }
  try {
    std::filesystem::create_directories(o.out);
    std::vector<ChartPoint> chart;
    if (o.mode != "build") holdsMode(o, &chart);
    if (o.mode != "holds") buildMode(o);
    if (!chart.empty()) {
      std::string err;
      if (!writeLogLogChart(o.out + "/build_speed.png", chart, "wall time per hold point [s], one thread",
                            "largest named-point distance to the dynamic rest shape [m]",
                            "Rest shapes: dynamic vs quasi-static (towel, 6x6 quadrant grid)", &err))
        std::cerr << "drape_build_bench: chart: " << err << "\n";
    }
  } catch (const std::runtime_error& e) {
    std::cerr << "drape_build_bench: " << e.what() << "\n";
    return 4;
  } catch (const std::exception& e) {
    std::cerr << "drape_build_bench: " << e.what() << "\n";
    return 5;
  }
  return 0;
}
