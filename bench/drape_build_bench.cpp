// drape_build_bench: database-build speed, reference dynamic rest shapes against a fast path (the
// builder's defaults, cheaper dynamic settings, or the quasi-static method of rest_shape_search.h), on
// the thesis's towel database (6 x 6 hold points in one quadrant).
//
// The reference arm is the builder's dynamic run with the linear systems solved tightly (CG relative
// tolerance 1e-6, cold start; --reference-cg-tolerance T and --reference-cg-warm-start change them, e.g. to
// the demo's and replay tests' 0.001 warm): error-controlled steps of 0.1 mm, dt_max 40 ms, no self-collision. The
// fast arm starts from DrapeBuildConfig::defaultSimulationSettings() (the same tight solves) and applies
// the --fast* options, e.g. --fast-cg-tolerance 0.001 --fast-cg-warm-start.
//
//   drape_build_bench [--out DIR] [--spacings D1,D2,...] [--grid NXxNY] [--holds K] [--mode holds|build|both]
//                     [--workers N] [--repeats R] [--corner-reference] [--settle SPEED,MEAN,DURATION]
//                     [--settle-tolerance M] [--coarse-spacing D] [--no-coarse-finish] [--finish-iterations N] [--polish N]
//                     [--fast dynamic|quasi_static] [--fast-cg-tolerance T] [--fast-cg-warm-start]
//                     [--fast-cg-cold-start]
//                     [--fast-error-tolerance M] [--fast-dt-max S] [--shard K/S]
//                     [--fast-build-only] [--reference-cg-tolerance T] [--reference-cg-warm-start]
//   drape_build_bench --chart-from DIR/build_holds.csv --out DIR   (redraws the chart of stored rows)
//
// holds: every hold point of the grid (or its first K) simulated one after the other on one thread,
//   the two methods interleaved per hold point (dynamic, quasi-static); per hold point the wall times,
//   their ratio and the rest-shape difference: the largest distance between the two rest shapes over the
//   textile's named points (corners, edge midpoints) and over all particles. Rows: DIR/build_holds.csv.
// build: the whole database (views rendered, rows stored, mirrored rows derived) with
//   DrapeDatabaseBuilder, --workers workers (0 = automatic), both methods, alternating, --repeats times
//   each (ABAB...). Rows: DIR/build_whole.csv. --fast-build-only: only the fast arm's builds.
// --corner-reference: one dynamic simulation of the corner hold (0, 0.46) m with the reference settings
//   on one thread, for each spacing and repeat, interleaved with the build rows (the yardstick:
//   the whole fast build should take no longer than this one simulation).
// --fast METHOD: the fast arm's rest-shape method (default quasi_static); --fast-* change the fast arm's
//   simulation settings from the builder's defaults (CG relative tolerance and warm start, step error
//   tolerance, largest step); --fast-cg-cold-start turns the warm start off.
// --shard K/S: only every S-th hold point from the K-th (0-based), to split one grid over processes.
// --polish N: finish both arms' rest shapes with up to N tight Newton iterations before comparing.
// DIR/build_whole.png: whole-build wall time against spacing per method, with the corner reference.
// DIR/build_speed.png: seconds per hold point against the rest-shape difference (named points, up to a
// mirror), one point per hold point and method. Benchmarks, not tests: nothing here asserts timings. Set OMP_WAIT_POLICY=passive.
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
  bool fast_build_only = false;  ///< --fast-build-only: build mode runs only the fast arm (and the corner reference)
  int shard = 0, shards = 1;  ///< --shard K/S: only the hold points k with k % S == K (split a run over processes)
  std::string mode = "holds";
  bool corner_reference = false;
  RestShapeSettings fast;  ///< the quasi-static settings (--settle, --coarse-spacing, --finish-iterations)
  std::string chart_from;  ///< --chart-from CSV: only redraw the chart of a stored build_holds.csv
  int polish = 0;          ///< --polish N: also finish both rest shapes with up to N tight Newton iterations
  // The fast arm's simulation settings, where they differ from the builder's (0 / false: unchanged).
  Real fast_cg_tolerance = 0;     ///< --fast-cg-tolerance T
  bool fast_cg_warm_start = false;  ///< --fast-cg-warm-start
  bool fast_cg_cold_start = false;  ///< --fast-cg-cold-start
  Real fast_error_tolerance = 0;  ///< --fast-error-tolerance M
  Real fast_dt_max = 0;           ///< --fast-dt-max S
  // The reference arm's CG solves (default tight: 1e-6, cold start).
  Real reference_cg_tolerance = 1e-6;  ///< --reference-cg-tolerance T
  bool reference_cg_warm_start = false;  ///< --reference-cg-warm-start
  std::string fast_label;  ///< fastLabel()
};

// The fast arm's simulation settings: the builder's defaults, with the --fast-* overrides.
void applyFastSimulation(const Options& o, SimulationSettings& s) {
  s.solver = db::DrapeBuildConfig::defaultSimulationSettings().solver;
  if (o.fast_cg_cold_start) s.solver.warm_start = false;
  if (o.fast_cg_tolerance > 0) s.solver.relative_tolerance = o.fast_cg_tolerance;
  if (o.fast_cg_warm_start) s.solver.warm_start = true;
  if (o.fast_error_tolerance > 0) s.error_tolerance = o.fast_error_tolerance;
  if (o.fast_dt_max > 0) s.dt_max = o.fast_dt_max;
}

std::vector<Real> parseList(const std::string& s) {
  std::vector<Real> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(std::stod(item));
  return out;
}

Options parseArgs(int argc, char** argv) {
  Options o;
  std::string fast_method = "quasi_static";
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
    else if (a == "--shard") {
      const std::string v = next();
      const auto slash = v.find('/');
      if (slash == std::string::npos) throw std::invalid_argument("--shard: expected K/S");
      o.shard = std::stoi(v.substr(0, slash));
      o.shards = std::stoi(v.substr(slash + 1));
      if (o.shards < 1 || o.shard < 0 || o.shard >= o.shards) throw std::invalid_argument("--shard: 0 <= K < S");
    }
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
    else if (a == "--no-coarse-finish") o.fast.coarse_static_finish = false;
    else if (a == "--chart-from") o.chart_from = next();
    else if (a == "--polish") o.polish = std::stoi(next());
    else if (a == "--finish-iterations") o.fast.finish.max_iterations = std::stoi(next());
    else if (a == "--fast") fast_method = next();
    else if (a == "--fast-cg-tolerance") o.fast_cg_tolerance = std::stod(next());
    else if (a == "--fast-cg-warm-start") o.fast_cg_warm_start = true;
    else if (a == "--fast-cg-cold-start") o.fast_cg_cold_start = true;
    else if (a == "--fast-build-only") o.fast_build_only = true;
    else if (a == "--fast-error-tolerance") o.fast_error_tolerance = std::stod(next());
    else if (a == "--fast-dt-max") o.fast_dt_max = std::stod(next());
    else if (a == "--reference-cg-tolerance") o.reference_cg_tolerance = std::stod(next());
    else if (a == "--reference-cg-warm-start") o.reference_cg_warm_start = true;
    else throw std::invalid_argument("unknown option " + a);
  }
  o.fast.method = restShapeMethodFromString(fast_method);
  o.fast.validate();
  if (o.mode != "holds" && o.mode != "build" && o.mode != "both") throw std::invalid_argument("--mode: holds, build or both");
  for (Real d : o.spacings)
    if (!(d >= 0.004 && d <= 0.1)) throw std::invalid_argument("--spacings: each in [0.004, 0.1] m");
  if (o.nx < 1 || o.ny < 1 || o.holds < 0 || o.workers < 0 || o.repeats < 1) throw std::invalid_argument("bad count");
  if (!(o.reference_cg_tolerance > 0 && o.reference_cg_tolerance < 1))
    throw std::invalid_argument("--reference-cg-tolerance: in (0, 1)");
  return o;
}

// The reference arm's simulation settings: the builder's, with tight cold-started CG solves unless
// --reference-cg-* say otherwise.
SimulationSettings referenceSettings(const Options& o) {
  SimulationSettings s = db::DrapeBuildConfig::defaultSimulationSettings();
  s.solver.relative_tolerance = o.reference_cg_tolerance;
  s.solver.warm_start = o.reference_cg_warm_start;
  return s;
}

db::DrapeBuildConfig baseConfig(const Options& o, Real spacing) {
  db::DrapeBuildConfig c;
  c.settings = referenceSettings(o);
  c.textile = presetTextile("towel");
  c.spacing = spacing;
  c.hold_points = db::fundamentalDomainGrid(c.textile, db::detectSymmetry(c.textile), o.nx, o.ny);
  if (o.shards > 1) {
    std::vector<Vec2> mine;
    for (size_t k = 0; k < c.hold_points.size(); ++k)
      if (static_cast<int>(k % o.shards) == o.shard) mine.push_back(c.hold_points[k]);
    c.hold_points = mine;
  }
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

// The named-point distance of b to the nearest mirror image of a among the textile mirrors that fix
// the hold point (a hold on a symmetry axis has two mirror-image equilibria, equally physical); the
// plain distance when no mirror fixes it.
Real mirrorAwareNamedDistance(const DrapeScene& scene, const Vec2& hold, const VecX& a, const VecX& b) {
  Real best = shapeDistance(scene, a, b).named;
  const db::TextileSymmetry sym = db::detectSymmetry(scene.spec.textile);
  const Vec3 hold_world = a.segment<3>(3 * scene.hold_particle);
  for (db::MirrorKind m : sym.mirrors()) {
    if (m == db::MirrorKind::kIdentity) continue;
    const bool flips_x = m == db::MirrorKind::kMirrorX || m == db::MirrorKind::kMirrorXY;
    const bool flips_y = m == db::MirrorKind::kMirrorY || m == db::MirrorKind::kMirrorXY;
    if ((flips_x && std::abs(hold.x() - sym.cx) > 1e-6) || (flips_y && std::abs(hold.y() - sym.cy) > 1e-6)) continue;
    const std::vector<Index> perm = db::mirrorPermutation(scene.grid, sym, m);
    if (perm.empty()) continue;
    best = std::min(best, shapeDistance(scene, db::mirrorPositions(a, perm, m, hold_world), b).named);
  }
  return best;
}

std::string num(double v, int prec = 6) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*g", prec, v);
  return buf;
}

// The fast arm's name in rows and charts: "quasi-static", or "dynamic" with its overrides.
std::string fastLabel(const Options& o) {
  std::string label = o.fast.method == RestShapeMethod::kQuasiStatic ? "quasi-static" : "dynamic";
  SimulationSettings s = db::DrapeBuildConfig::defaultSimulationSettings();
  applyFastSimulation(o, s);
  label += ", CG " + num(s.solver.relative_tolerance, 3) + (s.solver.warm_start ? " warm" : " cold");
  if (o.fast_error_tolerance > 0) label += ", steps " + num(1000 * o.fast_error_tolerance, 3) + " mm";
  if (o.fast_dt_max > 0) label += ", dt_max " + num(1000 * o.fast_dt_max, 3) + " ms";
  return label;
}

void holdsMode(const Options& o, std::vector<ChartPoint>* chart) {
  const std::string path = o.out + "/build_holds.csv";
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error("cannot write " + path);
  csv << "spacing_m,particles,hold_x_m,hold_y_m,dynamic_s,dynamic_steps,dynamic_rest,fast_s,fast_method,fast_coarse_steps,"
         "fast_coarse_finish_iterations,fast_finish_iterations,fast_residual,fast_dynamic_phase_s,fast_coarse_finish_s,fast_finish_s,speedup,named_point_distance_m,"
         "max_particle_distance_m,dynamic_polish_move_m,fast_polish_move_m,polished_named_distance_m,"
         "dynamic_polish_converged,fast_polish_converged,dynamic_polish_s,mirror_aware_named_distance_m\n";
  for (Real d : o.spacings) {
    const db::DrapeBuildConfig c = baseConfig(o, d);
    for (const Vec2& hold : c.hold_points) {
      const DrapeSceneSpec spec = db::DrapeDatabaseBuilder::sceneSpec(c, hold);
      RestShapeSettings dyn;
      dyn.method = RestShapeMethod::kDynamic;
      DrapeScene s_dyn = buildDrapeScene(spec);
      const RestShapeResult r_dyn = findRestShape(s_dyn, dyn);
      DrapeSceneSpec fast_spec = spec;
      applyFastSimulation(o, fast_spec.settings);
      DrapeScene s_fast = buildDrapeScene(fast_spec);
      const RestShapeResult r_fast = findRestShape(s_fast, o.fast);
      const ShapeDistance dist = shapeDistance(s_dyn, r_dyn.positions, r_fast.positions);
      const Real mirror_named = mirrorAwareNamedDistance(s_dyn, hold, r_dyn.positions, r_fast.positions);
      // The tight reference: each rest shape finished to 1e-4 of a node's weight by Newton iterations
      // (rest detection stops while soft modes still creep).
      ShapeDistance dyn_move, fast_move, polished;
      bool dyn_ok = false, fast_ok = false;
      double polish_s = 0;
      if (o.polish > 0) {
        StaticEquilibriumSettings tight;
        tight.force_tolerance = 1e-4;
        tight.max_iterations = o.polish;
        VecX xd = r_dyn.state, xf = r_fast.state;
        const StaticEquilibriumResult pd = solveStaticEquilibrium(*s_dyn.model, s_dyn.pins, 0, xd, tight);
        const StaticEquilibriumResult pf = solveStaticEquilibrium(*s_fast.model, s_fast.pins, 0, xf, tight);
        dyn_ok = pd.converged;
        fast_ok = pf.converged;
        polish_s = pd.wall_ms / 1000;
        const VecX pdx = s_dyn.model->positionsOf(xd), pfx = s_fast.model->positionsOf(xf);
        dyn_move = shapeDistance(s_dyn, r_dyn.positions, pdx);
        fast_move = shapeDistance(s_dyn, r_fast.positions, pfx);
        polished = shapeDistance(s_dyn, pdx, pfx);
        std::cerr << "  polished: dynamic moved " << num(1000 * dyn_move.named, 3) << " mm (" << pd.iterations << " it, "
                  << (pd.converged ? "converged" : pd.failure) << "), fast moved " << num(1000 * fast_move.named, 3)
                  << " mm (" << pf.iterations << " it), polished shapes " << num(1000 * polished.named, 3) << " mm apart\n";
      }
      csv << num(d) << "," << s_dyn.grid.numActive() << "," << num(hold.x()) << "," << num(hold.y()) << ","
          << num(r_dyn.wall_seconds) << "," << r_dyn.steps << "," << r_dyn.rest_reached << "," << num(r_fast.wall_seconds)
          << ",\"" << (o.fast.method == RestShapeMethod::kDynamic ? o.fast_label : r_fast.method_used) << "\"," << r_fast.steps << "," << r_fast.coarse_finish.iterations << ","
          << r_fast.finish.iterations << "," << num(r_fast.finish.residual_ratio) << "," << num(r_fast.dynamic.wall_time) << ","
          << num(r_fast.coarse_finish.wall_ms / 1000) << "," << num(r_fast.finish.wall_ms / 1000 + r_fast.finish_run.wall_time) << ","
          << num(r_dyn.wall_seconds / r_fast.wall_seconds) << "," << num(dist.named) << "," << num(dist.all) << ","
          << num(dyn_move.named) << "," << num(fast_move.named) << "," << num(polished.named) << "," << dyn_ok << ","
          << fast_ok << "," << num(polish_s) << "," << num(mirror_named) << "\n"
          << std::flush;
      std::cerr << "d " << num(d, 3) << " hold (" << num(hold.x(), 3) << ", " << num(hold.y(), 3) << "): dynamic "
                << num(r_dyn.wall_seconds, 3) << " s, fast " << num(r_fast.wall_seconds, 3) << " s (" << r_fast.method_used
                << ": dynamic phase " << num(r_fast.dynamic.wall_time, 3) << " s, coarse finish "
                << num(r_fast.coarse_finish.wall_ms / 1000, 3) << " s (" << r_fast.coarse_finish.iterations << " it), finish "
                << num(r_fast.finish.wall_ms / 1000 + r_fast.finish_run.wall_time, 3) << " s (" << r_fast.finish.iterations << " it, "
                << r_fast.finish_run.steps << " steps)), named points " << num(1000 * dist.named, 3) << " mm, all " << num(1000 * dist.all, 3) << " mm, named up to a mirror " << num(1000 * mirror_named, 3) << " mm\n";
      const std::string series = "d = " + num(100 * d, 2) + " cm";
      chart->push_back({r_dyn.wall_seconds, std::max(1e-5, mirror_named), "", series + " dynamic"});
      const bool fell_back = o.fast.method == RestShapeMethod::kQuasiStatic && r_fast.method_used != "quasi_static";
      chart->push_back({r_fast.wall_seconds, std::max(1e-5, mirror_named), "",
                        series + " " + o.fast_label + (fell_back ? ", fell back" : "")});
    }
  }
}

double cornerReference(const Options& o, Real d) {
  db::DrapeBuildConfig c;
  c.settings = referenceSettings(o);
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

// Chart points of stored holds rows: wall time per hold point and method against the named-point
// distance (columns by name, so rows of older column sets still draw).
std::vector<ChartPoint> chartFromCsv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::string line;
  std::getline(in, line);
  std::vector<std::string> header;
  {
    std::stringstream ss(line);
    std::string h;
    while (std::getline(ss, h, ',')) header.push_back(h);
  }
  auto col = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    if (it == header.end()) throw std::runtime_error(path + ": no column " + name);
    return static_cast<std::size_t>(it - header.begin());
  };
  const std::size_t c_d = col("spacing_m"), c_dyn = col("dynamic_s"), c_fast = col("fast_s"),
                    c_named = col("named_point_distance_m"), c_method = col("fast_method");
  // Older rows have no mirror-aware column; where it is empty, the plain distance is used.
  const auto mirror_it = std::find(header.begin(), header.end(), "mirror_aware_named_distance_m");
  const std::size_t c_mirror = mirror_it == header.end() ? c_named : static_cast<std::size_t>(mirror_it - header.begin());
  std::vector<ChartPoint> out;
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::string cur;
    bool quoted = false;
    for (char ch : line) {
      if (ch == '"') quoted = !quoted;
      else if (ch == ',' && !quoted) {
        f.push_back(cur);
        cur.clear();
      } else cur += ch;
    }
    f.push_back(cur);
    if (f.size() < header.size()) continue;
    const std::string series = "d = " + num(100 * std::stod(f[c_d]), 2) + " cm";
    const double named = std::max(1e-5, std::stod(f[c_mirror].empty() ? f[c_named] : f[c_mirror]));
    out.push_back({std::stod(f[c_dyn]), named, "", series + " dynamic"});
    const std::string& method = f[c_method];
    const bool dynamic_arm = method.rfind("dynamic", 0) == 0 && method.find("failed") == std::string::npos;
    const bool fell_back = !dynamic_arm && method != "quasi_static";
    out.push_back({std::stod(f[c_fast]), named, "",
                   series + (dynamic_arm ? " " + method : fell_back ? " quasi-static, fell back" : " quasi-static")});
  }
  return out;
}

void buildMode(const Options& o) {
  const std::string path = o.out + "/build_whole.csv";
  std::ofstream csv(path);
  if (!csv) throw std::runtime_error("cannot write " + path);
  csv << "spacing_m,repeat,method,hold_points,simulated,failed,workers,threads_per_simulation,wall_s,"
         "simulation_s_sum,corner_reference_s\n";
  std::vector<ChartPoint> chart;
  for (Real d : o.spacings) {
    for (int rep = 0; rep < o.repeats; ++rep) {
      for (bool fast : {false, true}) {
        if (!fast && o.fast_build_only) continue;
        const RestShapeMethod m = fast ? o.fast.method : RestShapeMethod::kDynamic;
        db::DrapeBuildConfig c = baseConfig(o, d);
        c.rest_shape = o.fast;
        c.rest_shape.method = m;
        if (fast) applyFastSimulation(o, c.settings);
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
        const double corner = o.corner_reference ? cornerReference(o, d) : 0.0;
        csv << num(d) << "," << rep << ",\"" << (fast ? o.fast_label : std::string("reference")) << "\"," << rep_out.planned << "," << rep_out.simulated_now << ","
            << rep_out.failed_now << "," << pass.workers << "," << pass.threads_per_simulation << ","
            << num(rep_out.wall_seconds) << "," << num(rep_out.simulation_seconds) << "," << num(corner) << "\n"
            << std::flush;
        std::cerr << "d " << num(d, 3) << " " << (fast ? o.fast_label : std::string("reference")) << ": " << rep_out.planned << " rows in "
                  << num(rep_out.wall_seconds, 4) << " s (" << pass.workers << " x " << pass.threads_per_simulation
                  << "), corner reference " << num(corner, 4) << " s\n";
        const std::string series = fast ? o.fast_label : std::string("reference");
        chart.push_back({100 * d, rep_out.wall_seconds, "", "whole build, " + series});
        if (corner > 0) chart.push_back({100 * d, corner, "", "one corner simulation, reference, 1 thread"});
      }
    }
  }
  std::string err;
  if (!chart.empty() &&
      !writeLogLogChart(o.out + "/build_whole.png", chart, "particle spacing d [cm]", "wall time [s]",
                        "Whole thesis database (towel, 6x6 quadrant grid, 36 views)", &err))
    std::cerr << "drape_build_bench: chart: " << err << "\n";
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  try {
    o = parseArgs(argc, argv);
    o.fast_label = fastLabel(o);
  } catch (const std::exception& e) {
    std::cerr << "drape_build_bench: " << e.what() << "\n";
    return 2;
  }
  try {
    std::filesystem::create_directories(o.out);
    std::vector<ChartPoint> chart;
    if (!o.chart_from.empty()) {
      chart = chartFromCsv(o.chart_from);
    } else {
      if (o.mode != "build") holdsMode(o, &chart);
      if (o.mode != "holds") buildMode(o);
    }
    if (!chart.empty()) {
      std::string err;
      if (!writeLogLogChart(o.out + "/build_speed.png", chart, "wall time per hold point [s], one thread",
                            "largest named-point distance to the reference, up to a mirror [m]",
                            "Rest shapes: reference dynamic vs a fast path (towel, 6x6 quadrant grid)", &err))
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
