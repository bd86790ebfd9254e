#include "textile_handling/db/drape_database_builder.h"

#include <omp.h>

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <cmath>
#include <cstdio>
#include <exception>
#include <mutex>
#include <sstream>
#include <thread>
#include <tuple>
#include <utility>

#include "database_sql.h"
#include "drape_build_steps.h"
#include "textile_handling/db/build_time_estimate.h"
#include "textile_handling/sim/memory_budget.h"
#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace db {

namespace {

using Clock = std::chrono::steady_clock;

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

}  // namespace

SimulationSettings DrapeBuildConfig::defaultSimulationSettings() {
  SimulationSettings s;
  s.integrator = IntegratorType::kSemiImplicitEuler;
  s.policy = StepPolicy::kErrorControlled;
  s.dt = 1e-3;
  s.dt_max = 0.04;
  s.error_tolerance = 1e-4;
  s.max_time = 20.0;
  // The simulator's default solve (CG to 1e-6 from a zero start). CG to 1e-3 with warm starts builds
  // about 2x faster and keeps 35 of the thesis's 36 rest shapes at d = 2/3 cm within 5 mm, but at
  // d = 2 cm it moved enough shapes into neighbouring equilibria to lower the recognition benchmark's
  // exact rate from 83.7 % to 79.9 % (docs/database.md, "Build speed"): opt-in, not the default.
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
  // Newton's settings change the computed shapes only with that integrator (the other texts stay).
  if (c.settings.integrator == IntegratorType::kBackwardEulerNewton)
    t += "simulation.newton_max_iterations: " + std::to_string(c.settings.solver.newton_max_iterations) +
         "\nsimulation.newton_tolerance: " + internal::fmt17(c.settings.solver.newton_tolerance) + "\n";
  if (c.start_tilt_deg != 0)
    t += "start_tilt_deg: " + internal::fmt17(c.start_tilt_deg) + "\nstart_tilt_axis_deg: " +
         internal::fmt17(c.start_tilt_axis_deg) + "\n";
  if (c.start_heap.folds > 0)
    t += "start_heap: folds " + std::to_string(c.start_heap.folds) + " seed " + std::to_string(c.start_heap.seed) +
         " lift_deg " + internal::fmt17(c.start_heap.lift_deg) + "\n";
  if (!c.material_variation.identity())
    t += "material_variation: bending " + internal::fmt17(c.material_variation.bending) + " shear " +
         internal::fmt17(c.material_variation.shear) + " density " + internal::fmt17(c.material_variation.density) + "\n";
  if (!c.member.empty()) t += "member: " + c.member + "\n";
  {
    std::istringstream lines(c.automatic_choice);
    for (std::string line; std::getline(lines, line);)
      if (!line.empty()) t += "automatic: " + line + "\n";
  }
  // Only for the quasi-static method (dynamic builds keep their former texts); it never applies with
  // self-collision (rest_shape_search.h), so those builds are dynamic and keep theirs too.
  if (c.rest_shape.method == RestShapeMethod::kQuasiStatic && !c.self_collision) t += c.rest_shape.text() + "\n";
  if (bracket_corner >= 0) t += "hold_bracket: " + std::to_string(bracket_corner) + "\n";
  return t;
}

void accumulateBuildReport(DrapeBuildReport& total, const DrapeBuildReport& part) {
  total.textile_id = part.textile_id;
  total.generation = part.generation;
  total.planned += part.planned;
  total.to_simulate += part.to_simulate;
  total.already_done += part.already_done;
  total.simulated_now += part.simulated_now;
  total.failed_now += part.failed_now;
  total.derived_now += part.derived_now;
  total.done_elsewhere += part.done_elsewhere;
  total.wall_seconds += part.wall_seconds;
  total.simulation_seconds += part.simulation_seconds;
  total.failures.insert(total.failures.end(), part.failures.begin(), part.failures.end());
}

namespace {

// The heap seed of one hold point: the build's seed mixed with the hold point in whole micrometres
// (splitmix64 finaliser), so hold points get different folds and a rebuild gets the same ones.
std::uint64_t heapSeed(std::uint64_t seed, const Vec2& hold) {
  auto mix = [](std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  };
  const auto um = [](Real v) { return static_cast<std::uint64_t>(static_cast<std::int64_t>(std::llround(v * 1e6))); };
  return mix(seed ^ mix(um(hold.x()) ^ mix(um(hold.y()) + 0x9e3779b97f4a7c15ULL)));
}

}  // namespace

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
  s.start_tilt_deg = c.start_tilt_deg;
  s.start_tilt_axis_deg = c.start_tilt_axis_deg;
  s.start_heap = c.start_heap;
  s.start_heap.seed = heapSeed(c.start_heap.seed, hold);
  if (!c.material_variation.identity())
    s.material = scaledMaterial(c.material, c.material_variation.bending, c.material_variation.shear,
                                c.material_variation.density, c.material.name + "_varied");
  return s;
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

// "<host>:<pid>:<n>": unique among the builders of one database, and it tells an operator where a
// claimed row runs.
std::string defaultClaimOwner() {
  static std::atomic<int> counter{0};
  char host[256] = "host";
  if (::gethostname(host, sizeof host) != 0) std::snprintf(host, sizeof host, "host");
  host[sizeof host - 1] = '\0';
  return std::string(host) + ":" + std::to_string(::getpid()) + ":" + std::to_string(counter++);
}

// True if `owner` ("<host>:<pid>:<n>", defaultClaimOwner) names a process of this machine that no longer
// exists: its claims need not be waited for. (A reused pid only makes us wait for the lease.)
bool ownerIsDeadHere(const std::string& owner) {
  const std::size_t a = owner.rfind(':');
  if (a == std::string::npos || a == 0) return false;
  const std::size_t b = owner.rfind(':', a - 1);
  if (b == std::string::npos) return false;
  char host[256] = "";
  if (::gethostname(host, sizeof host) != 0) return false;
  host[sizeof host - 1] = '\0';
  if (owner.substr(0, b) != host) return false;
  char* end = nullptr;
  const long pid = std::strtol(owner.c_str() + b + 1, &end, 10);
  if (end != owner.c_str() + a || pid <= 0) return false;
  return ::kill(static_cast<pid_t>(pid), 0) == -1 && errno == ESRCH;
}

// Renews `owner`'s claims every lease / 3 while a pass runs, and releases what is left (rows of a
// stopped build) when the pass ends. A failed renewal is retried at the next tick: the worst case is
// that another builder takes a row over, and storing skips rows finished elsewhere.
class ClaimRenewal {
 public:
  ClaimRenewal(HangingDrapeDatabase& db, const std::string& owner, double lease_s)
      : db_(db), owner_(owner), period_(lease_s / 3) {
    thread_ = std::thread([this] { run(); });
  }
  ~ClaimRenewal() {
    {
      std::lock_guard<std::mutex> lock(mu_);
      done_ = true;
    }
    cv_.notify_all();
    thread_.join();
    try {
      db_.releaseClaims(owner_);
    } catch (const std::exception&) {
      // The claims run out by themselves.
    }
  }
  ClaimRenewal(const ClaimRenewal&) = delete;
  ClaimRenewal& operator=(const ClaimRenewal&) = delete;

 private:
  void run() {
    std::unique_lock<std::mutex> lock(mu_);
    while (!cv_.wait_for(lock, period_, [this] { return done_; })) {
      lock.unlock();
      try {
        db_.renewClaims(owner_, period_.count() * 3);
      } catch (const std::exception&) {
      }
      lock.lock();
    }
  }
  HangingDrapeDatabase& db_;
  std::string owner_;
  std::chrono::duration<double> period_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread thread_;
};

}  // namespace

DrapeDatabaseBuilder::DrapeDatabaseBuilder(HangingDrapeDatabase& db, DrapeBuildConfig config)
    : DrapeDatabaseBuilder(std::move(config)) {
  db_ = &db;
}

HangingDrapeDatabase& DrapeDatabaseBuilder::database() const {
  if (!db_) throw InvalidInputError("build: this builder has no database (it only simulates hold points)");
  return *db_;
}

DrapeDatabaseBuilder::DrapeDatabaseBuilder(DrapeBuildConfig config) : config_(std::move(config)) {
  const DrapeBuildConfig& c = config_;
  claim_owner_ = c.claim_owner.empty() ? defaultClaimOwner() : c.claim_owner;
  if (claim_owner_.size() > 200) throw InvalidInputError("build: claim owner longer than 200 characters");
  if (!(c.claim_lease_s >= 3 && c.claim_lease_s <= 1e6))
    throw InvalidInputError("build: claim lease must be in [3, 1e6] s (shorter leases run out while a loaded machine renews them)");
  std::string err;
  if (c.textile.name.empty()) throw InvalidInputError("build: textile has no name");
  if (!validateTextileOutline(c.textile, &err)) throw InvalidInputError("build: textile '" + c.textile.name + "': " + err);
  if (!c.material.validate(&err)) throw InvalidInputError("build: material: " + err);
  for (const auto& [name, k] : {std::pair<const char*, Real>{"bending", c.material_variation.bending},
                                {"shear", c.material_variation.shear}, {"density", c.material_variation.density}})
    if (!(std::isfinite(k) && k > 0))
      throw InvalidInputError(std::string("build: material_variation.") + name + " must be finite and > 0, got " +
                              internal::fmt17(k));
  for (char ch : c.member)
    if (ch == '\n' || ch == '\r') throw InvalidInputError("build: member name must be one line");
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
  if (c.threads_per_simulation < 0) throw InvalidInputError("build: threads per simulation must be >= 0 (0 = automatic)");
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

bool DrapeDatabaseBuilder::claimRow(std::int64_t id, SimulationStatus* status) {
  HangingDrapeDatabase& db = database();
  if (db.claimSimulation(id, claim_owner_, config_.claim_lease_s)) return true;
  // Held by a builder of this machine that died (a crash, SIGKILL): take the row over at once.
  const HangingDrapeDatabase::ClaimState s = db.claimState(id);
  *status = s.status;
  return s.status == SimulationStatus::kPending && ownerIsDeadHere(s.claimed_by) &&
         db.claimSimulation(id, claim_owner_, config_.claim_lease_s, s.claimed_by);
}

SimulationOutcome DrapeDatabaseBuilder::simulateHoldPoint(int corner, std::size_t plan_index,
                                                         std::int64_t simulation_id) const {
  if (corner < -1 || corner > 3 || (corner >= 0) != config_.bracket_hold_points)
    throw InvalidInputError("simulateHoldPoint: pass " + std::to_string(corner) + " is not a pass of this build");
  const std::vector<PlannedHoldPoint> plan = corner < 0 ? plan_ : passPlan(corner);
  if (plan_index >= plan.size())
    throw InvalidInputError("simulateHoldPoint: hold point " + std::to_string(plan_index) + " of a plan of " +
                            std::to_string(plan.size()));
  std::call_once(mesh_once_, [this] { mesh_ = std::make_shared<internal::BuildMesh>(internal::buildMesh(config_, symmetry_, symmetric_grid_)); });
  const std::vector<std::int64_t> no_ids;  // only mirror derivation reads the pass's ids
  const internal::PassContext ctx{config_, corner, grid_, plan, no_ids, *mesh_, config_.views.angles(),
                                  config_.projection.type == vision::ProjectionType::kOrthographic ? "orthographic"
                                                                                                  : "pinhole"};
  internal::BuildJob job;
  job.plan_index = plan_index;
  job.id = simulation_id;
  SimulationOutcome out;
  out.result = internal::simulateRow(ctx, job, &out.failure);
  out.result.simulation_id = simulation_id;
  return out;
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
    accumulateBuildReport(total, buildPass(corner, plan));
  }
  total.wall_seconds = secondsSince(t0);
  return total;
}

std::pair<std::int64_t, std::int64_t> DrapeDatabaseBuilder::targetTextile() {
  if (config_.staged_textile_id == 0) {
    const std::int64_t id = database().ensureTextile(config_.textile, config_.material);
    return {id, database().textile(id).generation};
  }
  const auto staged = database().stagedGeneration(config_.staged_textile_id);
  if (!staged) throw NotFoundError("textile " + std::to_string(config_.staged_textile_id) + " has no staged generation");
  if (!(staged->material == config_.material))
    throw InvalidInputError("build: the material differs from the one of textile " +
                            std::to_string(config_.staged_textile_id) + "'s staged generation");
  return {staged->textile_id, staged->generation};
}

DrapeBuildPass DrapeDatabaseBuilder::passInfo(int corner, const internal::PassPlan& pp, int workers) const {
  DrapeBuildPass p;
  p.textile = config_.textile.name;
  p.bracket_corner = corner;
  p.planned = pp.planned;
  p.to_simulate = pp.to_simulate;
  p.already_done = pp.already_done;
  p.to_run = pp.simulations;
  p.workers = workers;
  p.threads_per_simulation = config_.threads_per_simulation;
  p.symmetry = symmetry_.name();
  p.symmetric_grid = symmetric_grid_;
  return p;
}

DrapeBuildReport DrapeDatabaseBuilder::buildPass(int corner, const std::vector<PlannedHoldPoint>& plan) {
  const auto t0 = Clock::now();
  const DrapeBuildConfig& c = config_;
  DrapeBuildReport rep;
  rep.symmetry = symmetry_.name();
  rep.symmetric_grid = symmetric_grid_;
  std::tie(rep.textile_id, rep.generation) = targetTextile();
  if (c.retry_failed) database().resetFailed(rep.textile_id);

  const internal::PassPlan pp =
      internal::planPass(database(), c, plan, rep.textile_id, rep.generation, parametersText(c, corner));
  rep.planned = pp.planned;
  rep.to_simulate = pp.to_simulate;
  rep.already_done = pp.already_done;
  const internal::BuildMesh mesh = internal::buildMesh(c, symmetry_, symmetric_grid_);
  const internal::PassContext ctx{c,    corner, grid_, plan, pp.ids, mesh, c.views.angles(),
                                  c.projection.type == vision::ProjectionType::kOrthographic ? "orthographic"
                                                                                             : "pinhole"};
  const std::vector<internal::BuildJob>& jobs = pp.jobs;
  // Automatic parallelism: one worker per core (no more than there are jobs), and the cores a short
  // job list leaves idle go to the simulations' OpenMP threads: never more threads than cores.
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  int workers = c.remote ? c.remote->slots() : c.workers > 0 ? c.workers : cores;
  workers = std::max(1, std::min(workers, static_cast<int>(jobs.size())));
  const int threads = c.threads_per_simulation > 0 ? c.threads_per_simulation : std::max(1, cores / workers);
  DrapeBuildPass pass = passInfo(corner, pp, workers);
  pass.threads_per_simulation = threads;
  if (c.on_pass_start) c.on_pass_start(pass);

  std::mutex mu;  // the job queue, the report, the time estimate and the callbacks
  std::size_t next_job = 0;
  std::deque<const internal::BuildJob*> waiting;  // claimed by another builder that is still alive
  const auto pass_start = std::chrono::steady_clock::now();
  const auto now_s = [&pass_start] { return secondsSince(pass_start); };
  BuildTimeEstimate estimate(workers, pass.to_run);
  int completed = 0;  // simulations of this pass finished, done or failed, here or by another builder
  std::exception_ptr fatal;
  bool stop = false;
  // Under `mu`: one more simulation of the pass has finished.
  const auto finishedOne = [&](std::int64_t id, bool estimated) {
    ++completed;
    const double t = now_s();
    if (estimated) estimate.finished(id, t);
    if (!c.on_progress) return;
    DrapeBuildProgress progress;
    progress.done = rep.already_done + completed;
    progress.total = rep.to_simulate;
    progress.done_before = rep.already_done;
    progress.elapsed_s = t;
    progress.eta_s = estimate.remainingSeconds(t);
    c.on_progress(progress);
  };
  // The row a job claims: its simulation, or for a derive-only job its first mirror row.
  const auto claimKey = [&pp](const internal::BuildJob& j) -> std::int64_t {
    if (j.simulate) return j.id;
    return j.derived.empty() ? 0 : pp.ids[j.derived.front()];
  };
  auto worker = [&](int slot) {
    omp_set_num_threads(threads);
    const internal::RowSimulator simulate_row = [&, slot](const internal::BuildJob& j, std::string* failure) {
      if (!c.remote) return internal::simulateRow(ctx, j, failure);
      SimulationOutcome o = c.remote->simulate(slot, corner, j.plan_index, j.id);
      *failure = o.failure;
      return std::move(o.result);
    };
    for (;;) {
      const internal::BuildJob* job = nullptr;
      bool retry = false;
      {
        std::lock_guard<std::mutex> lock(mu);
        if (stop || (c.should_stop && c.should_stop())) return;
        if (next_job < jobs.size()) {
          job = &jobs[next_job++];
        } else if (!waiting.empty()) {
          job = waiting.front();
          waiting.pop_front();
          retry = true;
        } else {
          return;
        }
      }
      try {
        // A job another builder holds is set aside and looked at again once the queue is empty: it ends
        // there (done or failed), or its lease runs out and it is taken over here.
        const std::int64_t key = claimKey(*job);
        SimulationStatus status = SimulationStatus::kPending;
        if (key != 0 && !claimRow(key, &status)) {
          const bool pending = status == SimulationStatus::kPending;
          {
            std::lock_guard<std::mutex> lock(mu);
            if (pending) {
              waiting.push_back(job);
            } else {
              ++rep.done_elsewhere;
              if (job->simulate) finishedOne(job->id, false);
            }
          }
          // Still running elsewhere and nothing else to do: wait a little before looking again.
          if (retry && pending)
            std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.2, c.claim_lease_s / 4)));
          continue;
        }
        {
          std::lock_guard<std::mutex> lock(mu);
          if (job->simulate) estimate.started(job->id, now_s());
        }
        const internal::JobOutcome out = internal::runJob(database(), ctx, *job, simulate_row);
        std::lock_guard<std::mutex> lock(mu);
        if (out.superseded) {
          ++rep.done_elsewhere;
        } else if (!out.failure.empty()) {
          ++rep.failed_now;
          const Vec2 p = plan[job->plan_index].position;
          char hold[96];
          std::snprintf(hold, sizeof hold, "hold (%.6g, %.6g) m, simulation %lld: ", p.x(), p.y(),
                        static_cast<long long>(job->id));
          rep.failures.push_back(hold + out.failure);
          if (c.on_failure) c.on_failure({job->id, p, out.failure});
        } else {
          rep.derived_now += static_cast<int>(job->derived.size());
          if (job->simulate) {
            ++rep.simulated_now;
            rep.simulation_seconds += out.wall_time_s;
          }
        }
        if (job->simulate) finishedOne(job->id, true);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mu);
        if (!fatal) fatal = std::current_exception();
        stop = true;
        return;
      }
    }
  };

  if (!jobs.empty()) {
    ClaimRenewal renewal(database(), claim_owner_, c.claim_lease_s);
    std::vector<std::thread> pool;
    for (int w = 0; w < workers; ++w) pool.emplace_back(worker, w);
    for (auto& t : pool) t.join();
  }
  if (c.on_pass_end) c.on_pass_end(pass);
  rep.wall_seconds = secondsSince(t0);
  if (fatal) std::rethrow_exception(fatal);
  return rep;
}

}  // namespace db
}  // namespace textile_handling
