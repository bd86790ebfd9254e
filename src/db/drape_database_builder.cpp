#include "textile_handling/db/drape_database_builder.h"

#include <omp.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <exception>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>
#include <tuple>
#include <utility>

#include "database_sql.h"
#include "textile_handling/sim/memory_budget.h"
#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace db {

namespace {

using Clock = std::chrono::steady_clock;

std::string clockText(double s) {
  if (!std::isfinite(s) || s < 0) return "--:--";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%02ld:%02ld", t / 60, t % 60);
  return buf;
}

// (name, value) of every numeric setting, in a fixed order: the parameter text and the finiteness check.
std::vector<std::pair<std::string, double>> numericSettings(const DrapeBuildConfig& c) {
  const SimulationSettings& s = c.settings;
  std::vector<std::pair<std::string, double>> out = {
      {"spacing_m", c.spacing},
      {"hold_height_m", c.hold_height},
  };
  // The model's numbers sit where the particle model's settle damping always stood, so that the
  // parameter texts of existing particle_kes databases do not change.
  for (const auto& n : ClothModelRegistry::instance().fingerprint(c.model).numbers) out.push_back(n);
  std::vector<std::pair<std::string, double>> rest = {
      {"simulation.cg_max_iterations", s.solver.max_iterations},
      {"simulation.cg_tolerance", s.solver.relative_tolerance},
      {"simulation.cg_accept_tolerance", s.solver.accept_tolerance},
      {"simulation.cg_smoothing_steps", s.solver.smoothing_steps},
      {"simulation.cg_smoothing_weight", s.solver.smoothing_weight},
      {"simulation.dt_s", s.dt},
      {"simulation.dt_min_s", s.dt_min},
      {"simulation.dt_max_s", s.dt_max},
      {"simulation.error_tolerance_m", s.error_tolerance},
      {"simulation.max_time_s", s.max_time},
      {"simulation.rest_speed_m_s", s.rest_speed},
      {"simulation.rest_mean_speed_m_s", s.rest_mean_speed},
      {"simulation.rest_duration_s", s.rest_duration},
      {"simulation.rest_min_time_s", s.rest_min_time},
      {"simulation.max_edge_stretch", s.max_edge_stretch},
      {"simulation.max_speed_m_s", s.max_speed},
      {"views.count", c.views.count},
      {"views.start_deg", c.views.start_deg},
      {"views.step_deg", c.views.step_deg},
      {"frame.width_px", c.frame.width_px},
      {"frame.height_px", c.frame.height_px},
      {"frame.metres_per_pixel", c.frame.metres_per_pixel},
      {"frame.top_margin_px", c.frame.top_margin_px},
      {"frame.supersample", c.frame.supersample},
      {"frame.coverage_threshold", c.frame.coverage_threshold},
      {"projection.camera_distance_m", c.projection.camera_distance},
      {"projection.camera_height_m", c.projection.camera_height},
      {"projection.fx", c.projection.intrinsics.fx},
      {"projection.fy", c.projection.intrinsics.fy},
  };
  out.insert(out.end(), rest.begin(), rest.end());
  return out;
}

struct Mesh {
  std::vector<vision::Triangle> triangles;
  std::map<MirrorKind, std::vector<Index>> perms;
};

}  // namespace

SimulationSettings DrapeBuildConfig::defaultSimulationSettings() {
  SimulationSettings s;
  s.integrator = IntegratorType::kSemiImplicitEuler;
  s.policy = StepPolicy::kErrorControlled;
  s.dt = 1e-3;
  s.dt_max = 0.04;
  s.error_tolerance = 1e-4;
  s.max_time = 20.0;
  return s;
}

ClothModelSpec DrapeBuildConfig::defaultModelSpec(const std::string& model) { return settlingModelSpec(model, 4.0); }

std::vector<std::string> DrapeDatabaseBuilder::parameterTexts(const DrapeBuildConfig& c) {
  if (!c.bracket_hold_points) return {parametersText(c)};
  std::vector<std::string> out;
  for (int k = 0; k < 4; ++k) out.push_back(parametersText(c, k));
  return out;
}

std::optional<Vec2> DrapeDatabaseBuilder::bracketHold(const ParticleGrid& grid, const Vec2& hold, int corner) {
  if (corner < 0) return hold;
  if (corner > 3 || grid.empty()) return std::nullopt;
  const Real d = grid.spacing();
  const Real fx = (hold.x() - grid.origin().x()) / d, fy = (hold.y() - grid.origin().y()) / d;
  const Index j0 = static_cast<Index>(std::floor(fx + 1e-9)), i0 = static_cast<Index>(std::floor(fy + 1e-9));
  const bool on_col = std::abs(fx - std::round(fx)) < 1e-9, on_row = std::abs(fy - std::round(fy)) < 1e-9;
  const bool up_x = corner & 1, up_y = corner & 2;
  if ((up_x && on_col) || (up_y && on_row)) return std::nullopt;  // the same particle as a lower corner
  const Index j = up_x ? j0 + 1 : static_cast<Index>(on_col ? std::llround(fx) : j0);
  const Index i = up_y ? i0 + 1 : static_cast<Index>(on_row ? std::llround(fy) : i0);
  if (i < 0 || j < 0 || i >= grid.rows() || j >= grid.cols() || !grid.active(i, j)) return std::nullopt;
  return grid.node(i, j);
}

std::vector<PlannedHoldPoint> DrapeDatabaseBuilder::passPlan(int corner) const {
  if (corner < 0) return plan_;
  std::vector<Vec2> pts;
  for (const Vec2& p : canonical_)
    if (bracketHold(grid_, p, corner)) pts.push_back(p);
  if (pts.empty()) return {};
  std::vector<PlannedHoldPoint> plan = planHoldPoints(pts, symmetry_);
  if (!symmetric_grid_)
    for (auto& h : plan) {
      h.mirror = MirrorKind::kIdentity;
      h.source = static_cast<int>(&h - plan.data());
    }
  if (symmetric_grid_) return plan;
  // Without mirroring every point is simulated at its own corner particle: drop the points (mirror
  // images) for which that corner does not exist.
  std::vector<PlannedHoldPoint> kept;
  for (const auto& h : plan)
    if (bracketHold(grid_, h.position, corner)) kept.push_back(h);
  for (auto& h : kept) h.source = static_cast<int>(&h - kept.data());
  return kept;
}

std::string DrapeDatabaseBuilder::parametersText(const DrapeBuildConfig& c, int bracket_corner) {
  const ClothModelFingerprint model = ClothModelRegistry::instance().fingerprint(c.model);
  std::string t = "format: 1\nmodel: " + c.model.name + "\n";
  t += "integrator: " + toString(c.settings.integrator) + "\n";
  t += "policy: " + toString(c.settings.policy) + "\n";
  t += "linear_solver: " + toString(c.settings.solver.kind) + "\n";
  // Solver details that change the computed shapes (a warm-started or loosely converged CG gives a
  // slightly different rest shape): without them a rebuild with other solver settings would resume
  // rows computed with the old ones and mix the two.
  t += "preconditioner: " + toString(c.settings.solver.preconditioner) + "\n";
  t += std::string("cg_warm_start: ") + (c.settings.solver.warm_start ? "true" : "false") + "\n";
  for (const std::string& line : model.lines) t += line + "\n";
  t += std::string("require_rest: ") + (c.require_rest ? "true" : "false") + "\n";
  t += std::string("retry_with_smaller_steps: ") + (c.retry_with_smaller_steps ? "true" : "false") + "\n";
  t += std::string("projection: ") +
       (c.projection.type == vision::ProjectionType::kOrthographic ? "orthographic" : "pinhole") + "\n";
  for (const auto& [name, value] : numericSettings(c)) {
    // Projection details only matter for the pinhole projection.
    if (c.projection.type == vision::ProjectionType::kOrthographic && name.rfind("projection.", 0) == 0) continue;
    t += name + ": " + internal::fmt17(value) + "\n";
  }
  // Only when on, so that the parameter texts of builds without collision stay as they were.
  if (c.self_collision) t += "self_collision: v3\n";
  if (bracket_corner >= 0) t += "hold_bracket: " + std::to_string(bracket_corner) + "\n";
  return t;
}

DrapeSceneSpec DrapeDatabaseBuilder::sceneSpec(const DrapeBuildConfig& c, const Vec2& hold) {
  DrapeSceneSpec s;
  s.textile = c.textile;
  s.material = c.material;
  s.spacing = c.spacing;
  HoldPoint h;
  h.position = hold;
  s.hold = {h};
  s.hold_position = Vec3(0, 0, c.hold_height);
  s.model = c.model;
  s.settings = c.settings;
  s.settings.trajectory_every = 0;
  s.self_collision = c.self_collision;
  return s;
}

vision::BitMask flipLeftRight(const vision::BitMask& mask) {
  vision::BitMask out(mask.width(), mask.height());
  for (int y = 0; y < mask.height(); ++y)
    for (int x = 0; x < mask.width(); ++x)
      if (mask.get(x, y)) out.set(mask.width() - 1 - x, y);
  return out;
}

bool mirroredViews(const std::vector<ViewInput>& source, MirrorKind m, const std::vector<double>& angles,
                   std::vector<ViewInput>* out) {
  out->clear();
  auto wrap = [](double a) {
    a = std::fmod(a, 360.0);
    return a < 0 ? a + 360.0 : a;
  };
  std::vector<ViewInput> result;
  for (double a : angles) {
    double src_angle = a;
    bool flip = true;
    switch (m) {
      case MirrorKind::kMirrorX: src_angle = -a; break;
      case MirrorKind::kMirrorY: src_angle = 180.0 - a; break;
      case MirrorKind::kMirrorXY: src_angle = a + 180.0; flip = false; break;
      case MirrorKind::kIdentity: flip = false; break;
    }
    src_angle = wrap(src_angle);
    const ViewInput* found = nullptr;
    for (const ViewInput& v : source) {
      const double d = std::abs(wrap(v.view_angle_deg) - src_angle);
      if (std::min(d, 360.0 - d) < 1e-6) {
        found = &v;
        break;
      }
    }
    if (!found) return false;
    result.push_back({a, flip ? flipLeftRight(found->mask) : found->mask});
  }
  *out = std::move(result);
  return true;
}

std::string formatProgressBar(int done, int total, double elapsed_s, int failed, int width) {
  const double frac = total > 0 ? std::min(1.0, static_cast<double>(done) / total) : 1.0;
  const int filled = static_cast<int>(std::floor(frac * width));
  std::string bar = "[";
  for (int k = 0; k < width; ++k) bar += k < filled ? '=' : (k == filled ? '>' : ' ');
  if (filled >= width) bar.back() = '=';
  bar += "]";
  char buf[160];
  const double eta = done > 0 && done < total ? elapsed_s / done * (total - done) : (done >= total ? 0.0 : -1.0);
  std::snprintf(buf, sizeof buf, " %d/%d simulations%s  elapsed %s  ETA %s", done, total,
                failed > 0 ? (" (" + std::to_string(failed) + " failed)").c_str() : "", clockText(elapsed_s).c_str(),
                clockText(eta).c_str());
  return bar + buf;
}

namespace {

// A build runs up to `workers` simulations at once: together they must fit in the memory budget
// (buildDrapeScene has checked one). Throws MemoryBudgetError (an std::invalid_argument).
void checkBuildMemory(const DrapeBuildConfig& c, Index nodes, int simulations) {
  const int hw = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const int at_once = std::max(1, std::min(c.workers > 0 ? c.workers : hw, simulations));
  checkMemoryBudget(estimateSimulationBytes(memoryInput(nodes, c.settings, c.self_collision)), c.settings.memory_budget_bytes,
                    "the database build of '" + c.textile.name + "' (" + std::to_string(nodes) + " particles per simulation)",
                    static_cast<std::size_t>(at_once));
}

}  // namespace

DrapeDatabaseBuilder::DrapeDatabaseBuilder(HangingDrapeDatabase& db, DrapeBuildConfig config)
    : db_(db), config_(std::move(config)) {
  const DrapeBuildConfig& c = config_;
  std::string err;
  if (c.textile.name.empty()) throw InvalidInputError("build: textile has no name");
  if (!validateTextileOutline(c.textile, &err)) throw InvalidInputError("build: textile '" + c.textile.name + "': " + err);
  if (!c.material.validate(&err)) throw InvalidInputError("build: material: " + err);
  try {
    ClothModelRegistry::instance().validate(c.model);
  } catch (const ClothModelError& e) {
    throw InvalidInputError(std::string("build: ") + e.what());
  }
  for (const auto& [name, value] : numericSettings(c))
    if (!std::isfinite(value)) throw InvalidInputError("build: setting " + name + " is not finite");
  if (!(c.spacing > 0)) throw InvalidInputError("build: particle spacing must be > 0");
  if (c.hold_points.empty() && !(c.lattice_spacing > 0 && std::isfinite(c.lattice_spacing)))
    throw InvalidInputError("build: lattice spacing must be finite and > 0");
  if (c.workers < 0) throw InvalidInputError("build: workers must be >= 0");
  if (c.threads_per_simulation < 1) throw InvalidInputError("build: threads per simulation must be >= 1");
  try {
    c.frame.validate();
    (void)c.views.angles();
  } catch (const std::exception& e) {
    throw InvalidInputError(std::string("build: views: ") + e.what());
  }
  const std::vector<Vec2> full = fullOutline(c.textile);
  for (const Vec2& p : c.hold_points)
    if (!p.allFinite() || !pointInPolygon(full, p, 1e-9))
      throw InvalidInputError("build: hold point (" + internal::fmt17(p.x()) + ", " + internal::fmt17(p.y()) + ") is not on the textile");

  symmetry_ = c.use_symmetry ? detectSymmetry(c.textile) : TextileSymmetry{};
  std::vector<Vec2> canonical;
  try {
    if (c.hold_points.empty()) {
      canonical = fundamentalDomainLattice(c.textile, symmetry_, c.lattice_spacing);
    } else {
      for (const Vec2& p : c.hold_points) canonical.push_back(symmetry_.canonical(p));
    }
  } catch (const std::invalid_argument& e) {
    throw InvalidInputError(std::string("build: hold points: ") + e.what());
  }
  if (canonical.empty()) throw InvalidInputError("build: no hold points");
  canonical_ = canonical;
  plan_ = planHoldPoints(canonical, symmetry_);

  // The scene of the first hold point checks the remaining settings (model, solver, time steps).
  try {
    DrapeScene scene = buildDrapeScene(sceneSpec(c, plan_.front().position));
    checkBuildMemory(c, scene.model->numNodes(), static_cast<int>(canonical.size()));
    DrapeSimulation probe(*scene.model, scene.pins, scene.spec.settings, scene.x0, scene.v0);
    symmetric_grid_ = symmetry_.any();
    for (MirrorKind m : symmetry_.mirrors())
      if (mirrorPermutation(scene.grid, symmetry_, m).empty()) symmetric_grid_ = false;
    grid_ = scene.grid;
  } catch (const std::invalid_argument& e) {
    throw InvalidInputError(std::string("build: ") + e.what());
  }
  if (!symmetric_grid_)
    for (auto& h : plan_) {
      h.mirror = MirrorKind::kIdentity;
      h.source = static_cast<int>(&h - plan_.data());
    }
}

DrapeBuildReport DrapeDatabaseBuilder::build() {
  if (!config_.bracket_hold_points) return buildPass(-1, plan_);
  const auto t0 = Clock::now();
  DrapeBuildReport total;
  total.symmetry = symmetry_.name();
  total.symmetric_grid = symmetric_grid_;
  for (int corner = 0; corner < 4; ++corner) {
    if (config_.should_stop && config_.should_stop()) break;
    const std::vector<PlannedHoldPoint> plan = passPlan(corner);
    if (plan.empty()) continue;
    const DrapeBuildReport r = buildPass(corner, plan);
    total.textile_id = r.textile_id;
    total.generation = r.generation;
    total.planned += r.planned;
    total.to_simulate += r.to_simulate;
    total.already_done += r.already_done;
    total.simulated_now += r.simulated_now;
    total.failed_now += r.failed_now;
    total.derived_now += r.derived_now;
    total.simulation_seconds += r.simulation_seconds;
    total.failures.insert(total.failures.end(), r.failures.begin(), r.failures.end());
  }
  total.wall_seconds = secondsSince(t0);
  return total;
}

std::pair<std::int64_t, std::int64_t> DrapeDatabaseBuilder::targetTextile() {
  if (config_.staged_textile_id == 0) {
    const std::int64_t id = db_.ensureTextile(config_.textile, config_.material);
    return {id, db_.textile(id).generation};
  }
  const auto staged = db_.stagedGeneration(config_.staged_textile_id);
  if (!staged) throw NotFoundError("textile " + std::to_string(config_.staged_textile_id) + " has no staged generation");
  if (!(staged->material == config_.material))
    throw InvalidInputError("build: the material differs from the one of textile " +
                            std::to_string(config_.staged_textile_id) + "'s staged generation");
  return {staged->textile_id, staged->generation};
}

DrapeBuildReport DrapeDatabaseBuilder::buildPass(int corner, const std::vector<PlannedHoldPoint>& plan) {
  const auto t0 = Clock::now();
  const DrapeBuildConfig& c = config_;
  DrapeBuildReport rep;
  rep.symmetry = symmetry_.name();
  rep.symmetric_grid = symmetric_grid_;
  std::tie(rep.textile_id, rep.generation) = targetTextile();
  if (c.retry_failed) db_.resetFailed(rep.textile_id);
  const std::string params = parametersText(c, corner);

  std::vector<NewSimulation> rows;
  for (const PlannedHoldPoint& h : plan) {
    NewSimulation r;
    r.textile_id = rep.textile_id;
    r.generation = rep.generation;
    r.hold = h.position;
    r.lattice_i = h.lattice_i;
    r.lattice_j = h.lattice_j;
    r.source = h.mirror;
    r.source_index = h.mirror == MirrorKind::kIdentity ? -1 : h.source;
    r.model = c.model.name;
    r.integrator = toString(c.settings.integrator);
    r.spacing = c.spacing;
    r.parameters = params;
    rows.push_back(r);
  }
  const std::vector<std::int64_t> ids = db_.addSimulations(rows);
  rep.planned = static_cast<int>(rows.size());

  std::map<std::int64_t, SimulationRecord> state;
  for (auto& r : db_.simulations(rep.textile_id)) state[r.id] = r;

  // Mesh data shared by every job (same grid for every hold point).
  Mesh mesh;
  {
    std::string err;
    const ParticleGrid grid = ParticleGrid::rasterize(c.textile, c.spacing, &err);
    if (grid.empty()) throw InvalidInputError("build: rasterisation failed: " + err);
    mesh.triangles = vision::trianglesFromTopology(ParticleTopology::fromGrid(grid));
    if (symmetric_grid_)
      for (MirrorKind m : symmetry_.mirrors()) mesh.perms[m] = mirrorPermutation(grid, symmetry_, m);
  }

  struct Job {
    std::size_t plan_index;
    std::int64_t id;
    std::vector<std::size_t> derived;  // plan indices of pending mirror rows
    bool simulate;                     // false: the source is done, only derive
  };
  std::vector<Job> jobs;
  std::map<std::size_t, std::size_t> job_of_source;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (plan[k].mirror != MirrorKind::kIdentity) continue;
    ++rep.to_simulate;
    const SimulationStatus st = state[ids[k]].status;
    if (st == SimulationStatus::kDone) ++rep.already_done;
    if (st == SimulationStatus::kPending) {
      job_of_source[k] = jobs.size();
      jobs.push_back({k, ids[k], {}, true});
    }
  }
  std::vector<std::pair<std::int64_t, std::string>> orphan_failures;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (plan[k].mirror == MirrorKind::kIdentity || state[ids[k]].status != SimulationStatus::kPending) continue;
    const std::size_t src = static_cast<std::size_t>(plan[k].source);
    const SimulationRecord& s = state[ids[src]];
    if (s.status == SimulationStatus::kPending) {
      jobs[job_of_source[src]].derived.push_back(k);
    } else if (s.status == SimulationStatus::kDone) {
      auto it = job_of_source.find(src);
      if (it == job_of_source.end()) {
        job_of_source[src] = jobs.size();
        jobs.push_back({src, ids[src], {}, false});
        it = job_of_source.find(src);
      }
      jobs[it->second].derived.push_back(k);
    } else {
      orphan_failures.emplace_back(ids[k], "source simulation " + std::to_string(ids[src]) + " failed: " + s.failure_reason);
    }
  }
  for (const auto& [id, reason] : orphan_failures) db_.markFailed(id, reason);
  // Derive-only jobs first (cheap), then simulations in plan order.
  std::stable_sort(jobs.begin(), jobs.end(), [](const Job& a, const Job& b) { return !a.simulate && b.simulate; });

  const int n_sim_jobs = static_cast<int>(std::count_if(jobs.begin(), jobs.end(), [](const Job& j) { return j.simulate; }));
  int workers = c.workers > 0 ? c.workers : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  workers = std::max(1, std::min(workers, static_cast<int>(jobs.size())));

  std::mutex mu;  // queue, counters, progress output
  std::size_t next_job = 0;
  int finished = 0, failed = 0;
  std::exception_ptr fatal;
  std::atomic<bool> stop{false};
  const bool tty = isatty(fileno(stderr)) != 0;
  const int total_display = rep.to_simulate;
  const int done_before = rep.already_done;
  int last_printed = -1;  // completed count of the last line printed (non-terminal output)
  auto report_progress = [&](bool final_line) {
    if (!c.progress) return;
    const int completed = finished + failed;
    const std::string bar = formatProgressBar(done_before + completed, total_display, secondsSince(t0), failed);
    if (tty) {
      std::cerr << "\r" << bar << (final_line ? "\n" : "") << std::flush;
    } else if ((final_line && completed != last_printed) ||
               (!final_line && (n_sim_jobs <= 20 || completed % std::max(1, n_sim_jobs / 20) == 0))) {
      std::cerr << bar << "\n" << std::flush;
      last_printed = completed;
    }
  };
  if (c.progress && n_sim_jobs > 0) {
    std::lock_guard<std::mutex> lock(mu);
    std::cerr << "drape_db: " << c.textile.name
              << (corner >= 0 ? " (bracket corner " + std::to_string(corner) + " of the hold points' grid cells)" : "")
              << ": " << rep.planned << " hold points (" << rep.to_simulate
              << " simulated, symmetry " << rep.symmetry << (symmetric_grid_ ? "" : ", no mirroring") << "), "
              << rep.already_done << " already done, " << n_sim_jobs << " to run on " << workers << " worker(s) x "
              << c.threads_per_simulation << " thread(s)\n";
    report_progress(false);
  }

  auto render = [&](const VecX& x, Index held, double* seconds) {
    const auto r0 = Clock::now();
    const Vec3 hold = x.segment<3>(3 * held);
    std::vector<vision::SilhouetteView> v = vision::renderViews(x, mesh.triangles, hold, c.views, c.projection, c.frame);
    std::vector<ViewInput> out;
    out.reserve(v.size());
    for (auto& s : v) out.push_back({s.view_angle_deg, std::move(s.mask)});
    *seconds = secondsSince(r0);
    return out;
  };
  auto depth_of = [](const VecX& x, Index held) {
    Real lowest = x[3 * held + 2];
    for (Eigen::Index k = 0; k < x.size() / 3; ++k) lowest = std::min(lowest, x[3 * k + 2]);
    return x[3 * held + 2] - lowest;
  };
  const std::vector<double> view_angles = c.views.angles();
  const std::string projection =
      c.projection.type == vision::ProjectionType::kOrthographic ? "orthographic" : "pinhole";

  auto worker = [&]() {
    omp_set_num_threads(c.threads_per_simulation);
    for (;;) {
      Job job;
      {
        std::lock_guard<std::mutex> lock(mu);
        if (stop || next_job >= jobs.size() || (c.should_stop && c.should_stop())) return;
        job = jobs[next_job++];
      }
      try {
        std::vector<SimulationResult> results;
        SimulationResult src;
        std::string failure;
        if (job.simulate) {
          src.simulation_id = job.id;
          try {
            const std::optional<Vec2> at = bracketHold(grid_, plan[job.plan_index].position, corner);
            if (!at) throw std::invalid_argument("hold point has no particle at bracket corner " + std::to_string(corner));
            DrapeSceneSpec spec = sceneSpec(c, *at);
            double wall = 0;
            for (int attempt = 0; attempt < (c.retry_with_smaller_steps ? 2 : 1); ++attempt) {
              if (attempt == 1) {
                spec.settings.dt_max *= 0.25;
                spec.settings.error_tolerance *= 0.25;
                spec.settings.dt = std::min(spec.settings.dt, spec.settings.dt_max);
              }
              DrapeScene scene = buildDrapeScene(spec);
              DrapeSimulation sim(*scene.model, scene.pins, scene.spec.settings, scene.x0, scene.v0);
              sim.setPostStepPass(scene.postStepPass());
              const RunResult r = sim.run();
              wall += r.wall_time;
              std::string why;
              if (r.diverged)
                why = "diverged at t = " + internal::fmt17(r.divergence_time) + " s: " + r.divergence_reason;
              else if (!r.rest_reached && c.require_rest)
                why = "no rest within max_time " + internal::fmt17(spec.settings.max_time) + " s";
              if (!why.empty()) {
                failure += (failure.empty() ? "" : "; retry with dt_max " + internal::fmt17(spec.settings.dt_max) + " s: ") + why;
                continue;
              }
              failure.clear();
              src.positions = sim.positions();
              src.rest_reached = r.rest_reached;
              src.sim_time_s = r.sim_time;
              src.wall_time_s = wall;
              src.steps = r.steps;
              src.rejected_steps = r.rejected_steps;
              src.held_particle = scene.hold_particle;
              src.hanging_depth_m = depth_of(src.positions, scene.hold_particle);
              src.projection = projection;
              src.frame = c.frame;
              src.views = render(src.positions, scene.hold_particle, &src.render_time_s);
              break;
            }
          } catch (const DrapeDatabaseError&) {
            throw;
          } catch (const std::exception& e) {
            failure = std::string("simulation error: ") + e.what();
          }
          if (!failure.empty()) {
            db_.markFailed(job.id, failure);
            for (std::size_t k : job.derived)
              db_.markFailed(ids[k], "source simulation " + std::to_string(job.id) + " failed: " + failure);
            std::lock_guard<std::mutex> lock(mu);
            ++failed;
            ++rep.failed_now;
            const Vec2 p = plan[job.plan_index].position;
            char hold[96];
            std::snprintf(hold, sizeof hold, "hold (%.6g, %.6g) m, simulation %lld: ", p.x(), p.y(),
                          static_cast<long long>(job.id));
            rep.failures.push_back(hold + failure);
            if (c.progress && tty) std::cerr << "\n";
            if (c.progress) std::cerr << "drape_db: simulation " << job.id << " failed: " << failure << "\n";
            report_progress(false);
            if (c.on_progress) c.on_progress(done_before + finished + failed, total_display);
            continue;
          }
        } else {
          // Source already done: load it (positions and stored metadata) to derive its mirrors.
          const SimulationRecord rec = db_.simulation(job.id);
          src.positions = db_.positions(job.id);
          src.held_particle = rec.held_particle;
          src.rest_reached = rec.rest_reached;
          src.sim_time_s = rec.sim_time_s;
          src.steps = rec.steps;
          src.rejected_steps = rec.rejected_steps;
          src.hanging_depth_m = rec.hanging_depth_m;
          if (src.held_particle < 0 || 3 * src.held_particle >= src.positions.size())
            throw BlobFormatError("simulation " + std::to_string(job.id) + " has no valid held particle");
          for (StoredView& v : db_.views(job.id)) src.views.push_back({v.view_angle_deg, std::move(v.mask)});
        }
        // Mirror rows: mirrored positions, re-rendered (exact for any projection).
        const Vec3 hold_world = src.positions.segment<3>(3 * src.held_particle);
        std::vector<SimulationResult> derived;
        for (std::size_t k : job.derived) {
          const MirrorKind m = plan[k].mirror;
          const std::vector<Index>& perm = mesh.perms.at(m);
          if (static_cast<Eigen::Index>(perm.size()) * 3 != src.positions.size())
            throw BlobFormatError("simulation " + std::to_string(job.id) + " has " +
                                  std::to_string(src.positions.size() / 3) + " particles, the grid has " +
                                  std::to_string(perm.size()));
          SimulationResult d;
          d.simulation_id = ids[k];
          d.positions = mirrorPositions(src.positions, perm, m, hold_world);
          d.held_particle = perm[static_cast<std::size_t>(src.held_particle)];
          d.rest_reached = src.rest_reached;
          d.sim_time_s = src.sim_time_s;
          d.wall_time_s = 0;
          d.steps = src.steps;
          d.rejected_steps = src.rejected_steps;
          d.hanging_depth_m = src.hanging_depth_m;
          d.projection = projection;
          d.frame = c.frame;
          // Views: the source's silhouettes mirrored (exact, and mirror-equivalent hold points get
          // identical silhouette sets); re-rendered only if the view set is not closed under the mirror.
          const auto r0 = Clock::now();
          if (!mirroredViews(src.views, m, view_angles, &d.views))
            d.views = render(d.positions, d.held_particle, &d.render_time_s);
          else
            d.render_time_s = secondsSince(r0);
          derived.push_back(std::move(d));
        }
        if (job.simulate) results.push_back(std::move(src));
        for (auto& d : derived) results.push_back(std::move(d));
        // One transaction: the simulation, its views, its mirrors and their views.
        if (!results.empty()) db_.storeResults(results);
        std::lock_guard<std::mutex> lock(mu);
        rep.derived_now += static_cast<int>(job.derived.size());
        if (job.simulate) {
          ++finished;
          ++rep.simulated_now;
          rep.simulation_seconds += results.front().wall_time_s;
          report_progress(false);
          if (c.on_progress) c.on_progress(done_before + finished + failed, total_display);
        }
      } catch (...) {
        std::lock_guard<std::mutex> lock(mu);
        if (!fatal) fatal = std::current_exception();
        stop = true;
        return;
      }
    }
  };

  if (!jobs.empty()) {
    std::vector<std::thread> pool;
    for (int w = 0; w < workers; ++w) pool.emplace_back(worker);
    for (auto& t : pool) t.join();
  }
  if (c.progress && n_sim_jobs > 0) report_progress(true);
  rep.wall_seconds = secondsSince(t0);
  if (fatal) std::rethrow_exception(fatal);
  return rep;
}

}  // namespace db
}  // namespace textile_handling
