// Builds the hanging-drape database for one textile: plans the candidate hold points (a lattice of
// spacing s over the fundamental domain of the textile's mirror symmetry, edges and axes included, or
// explicit points), simulates the fundamental-domain points in parallel, renders the silhouette views
// of every result and derives the mirrored hold points by mirroring the final positions (and
// re-rendering them). Resumable: a rebuild with the same settings skips done simulations. Reports
// only through DrapeBuildConfig's callbacks (the tools print them). See docs/database.md.
// The builder library (textile_handling_db_builder); the store (textile_handling_db_core) does not use it.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/simulation_outcome_codec.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/rest_shape_search.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

namespace internal {
struct PassPlan;
struct BuildMesh;
}  // namespace internal

class RemoteSimulator;  // below

/// One pass of a build, as reported to DrapeBuildConfig::on_pass_start / on_pass_end.
struct DrapeBuildPass {
  std::string textile;             ///< the textile's name
  int bracket_corner = -1;         ///< 0..3: the bracket pass of that grid-cell corner; -1: nearest particle
  int planned = 0;                 ///< rows (hold points) in the pass's plan
  int to_simulate = 0;             ///< simulated (not mirrored) rows in the plan
  int already_done = 0;            ///< simulated rows done before this build
  int to_run = 0;                  ///< simulations this pass runs
  int workers = 0;                 ///< worker threads of the pass
  int threads_per_simulation = 1;  ///< OpenMP threads inside one simulation (as chosen)
  std::string symmetry;            ///< "none", "x", "y", "xy" (as used)
  bool symmetric_grid = false;     ///< mirrored rows derived rather than simulated
};

/// A simulation that failed, as reported to DrapeBuildConfig::on_failure.
struct DrapeBuildFailure {
  std::int64_t simulation_id = 0;  ///< the row marked failed
  Vec2 hold = Vec2::Zero();        ///< its hold point in the textile frame [m]
  std::string reason;              ///< why (also stored as the row's failure reason)
};

/// Progress of a pass, as reported to DrapeBuildConfig::on_progress after every finished simulation.
struct DrapeBuildProgress {
  int done = 0;          ///< simulated rows of the pass done or failed, those done before the build included
  int total = 0;         ///< DrapeBuildPass::to_simulate
  int done_before = 0;   ///< of `done`, rows that were done before this build (a resumed build)
  double elapsed_s = 0;  ///< wall time since the pass's first simulation started [s]
  /// Estimated wall time until the pass's last simulation finishes [s] (BuildTimeEstimate); 0 when all
  /// have finished, -1 when unknown (no simulation of this build has finished).
  double eta_s = -1;
};

/// Scale factors of a build's material for every simulation (a database member's material variation,
/// scaledMaterial() in material.h); the textile keeps its stored material.
struct MaterialVariation {
  Real bending = 1;  ///< both bending curves times this
  Real shear = 1;    ///< both shear curves times this
  Real density = 1;  ///< areal density times this
  bool identity() const { return bending == 1 && shear == 1 && density == 1; }
};

/// Everything a build needs. The simulation and view settings are stored with every simulation row
/// (as canonical text, DrapeDatabaseBuilder::parametersText), so a rebuild with other settings plans
/// new rows instead of mixing results.
struct DrapeBuildConfig {
  TextileOutline textile = presetTextile("towel");
  Material material = Material::cotton();

  // ---- hold points ----
  /// Lattice spacing s [m] of the default hold points (holdPointLattice of the fundamental domain).
  Real lattice_spacing = 0.08;
  /// Explicit hold points [m]; when non-empty they replace the lattice. Points outside the fundamental
  /// domain are folded into it (with symmetry on).
  std::vector<Vec2> hold_points;
  /// Simulate only the fundamental domain and derive the mirrored hold points (needs a particle grid
  /// that is symmetric too; otherwise every hold point is simulated).
  bool use_symmetry = true;
  /// Hold-point neighbourhoods ("brackets"). false: every hold point pins the particle nearest to it
  /// (the thesis; a point between particles moves by up to d/sqrt(2)). true: every hold point gets up
  /// to four simulations, one per corner of the particle-grid cell that contains it (1 or 2 when it
  /// lies on a grid line), each stored as its own row of that hold point, so the hold point's class in
  /// the index covers the shapes of the particles around it instead of one arbitrarily snapped one.
  /// The corners are built as four passes with their own parameter texts ("hold_bracket: k").
  bool bracket_hold_points = false;

  // ---- simulation ----
  Real spacing = 0.02;              ///< particle grid spacing d [m]
  Real hold_height = 1.0;           ///< world z of the held particle [m]
  /// Cloth model and options (any registered model; its fingerprint lines go into the parameter text).
  ClothModelSpec model = defaultModelSpec("particle_kes");
  SimulationSettings settings = defaultSimulationSettings();
  /// Starting pose of every simulation (DrapeSceneSpec::start_tilt_deg / start_tilt_axis_deg): the flat
  /// sheet tilted about a horizontal line through the hold point; 0 = flat (the thesis). Written into
  /// the parameter text only when non-zero.
  Real start_tilt_deg = 0;
  Real start_tilt_axis_deg = 0;
  /// Self-collision v3 with the contact forces (default SelfCollisionOptions, as the demo scene;
  /// docs/collision.md) in every simulation. Off by default: about 1.7 times the simulation cost; without
  /// it a rest shape can pass through itself (docs/database.md). Written into the parameter text only when on.
  bool self_collision = false;
  /// Picked-from-a-heap start (heap_start.h) of every simulation, before the tilt. The seed is mixed
  /// with the hold point, so every hold point gets its own folds. Written into the parameter text only
  /// when folds > 0.
  HeapStart start_heap;
  /// Material variation of every simulation (written into the parameter text unless the identity).
  MaterialVariation material_variation;
  /// Name of the database member this build makes (drape_build_members.h): written into the parameter
  /// text when non-empty, so every row says how it was made.
  std::string member;
  /// The automatic choice's report (AutomaticChoice::text(), automatic_configuration.h) when model, spacing
  /// and integrator were chosen automatically; written into the parameter text, one "automatic:" line each.
  std::string automatic_choice;
  /// How a rest shape is found (rest_shape_search.h): kDynamic (the default) runs the simulation to
  /// rest; kQuasiStatic settles on a 2 cm grid, finishes the equilibrium there with Newton solves and
  /// settles the prolonged shape on the build's grid (falling back to kDynamic if a stage fails).
  /// Builds with self_collision are always dynamic. Written into the parameter text when quasi-static.
  RestShapeSettings rest_shape;
  /// A run that hits settings.max_time without reaching rest is stored as failed (true) or as done
  /// with rest_reached = false (false).
  bool require_rest = true;
  /// A run that diverges or does not reach rest is retried once with dt_max and error_tolerance
  /// divided by 4 (a period-2 chatter of the linearised implicit step at large dt can keep one
  /// particle from resting; smaller steps remove it). Failed only if the retry fails too.
  bool retry_with_smaller_steps = true;

  // ---- views ----
  vision::ViewSet views;            ///< default 36 views, 10 deg apart
  vision::CanonicalFrame frame;     ///< default 64 x 64 px, 1 m x 1 m
  vision::SilhouetteProjection projection = vision::SilhouetteProjection::orthographic();

  // ---- target ----
  /// 0: build the textile named by `textile` (added if missing) into its active generation.
  /// Otherwise: build into the staged generation of this stored textile (HangingDrapeDatabase::
  /// stageGeneration), whose material must equal `material`; the rows stay invisible to readers until
  /// promoteStagedGeneration. Throws NotFoundError from build() if the textile has no staged generation.
  std::int64_t staged_textile_id = 0;

  // ---- execution ----
  int workers = 0;                  ///< simulations run at once (0 = hardware threads)
  /// OpenMP threads inside one simulation; 0 = automatic: cores / workers (at least 1), so a build with
  /// fewer jobs than cores gives the idle cores to the simulations and never oversubscribes.
  int threads_per_simulation = 0;
  bool retry_failed = false;        ///< reset failed rows to pending before building
  /// Several builders on one database (docs/database.md, "Concurrent builders"): a row is claimed before
  /// it runs, the claims are renewed every claim_lease_s / 3 while the build runs, and a row whose
  /// builder stopped renewing is taken over once its lease has run out.
  double claim_lease_s = 60;
  std::string claim_owner;          ///< this builder's name in the claims; empty = "<host>:<pid>:<n>"
  /// Non-null: the simulations run there (one worker thread per slot), the rest of the build here.
  std::shared_ptr<RemoteSimulator> remote;

  // ---- reporting (the builder prints nothing; every callback is optional) ----
  // A build runs one pass, or one per bracket corner (bracket_hold_points). The callbacks are called
  // one at a time (serialised by the builder), from the calling thread or from a worker thread.
  /// Called when a pass has planned its rows, before its first simulation starts.
  std::function<void(const DrapeBuildPass& pass)> on_pass_start;
  /// Called after every finished simulation, done or failed, with the pass's counts and time estimate.
  std::function<void(const DrapeBuildProgress& progress)> on_progress;
  /// Called for a simulation that failed (the row is marked failed), just before its on_progress call.
  std::function<void(const DrapeBuildFailure& failure)> on_failure;
  /// Called when a pass's workers have stopped (also when a database error ends the pass, before it is
  /// thrown).
  std::function<void(const DrapeBuildPass& pass)> on_pass_end;
  /// Polled before each simulation starts: true = finish the running simulations and return (the
  /// build is resumable). Used by services that must shut down promptly.
  std::function<bool()> should_stop;

  /// The fastest robust settings measured for database builds (docs/database.md): semi-implicit Euler
  /// with the simulator's default linear solver, error-controlled steps (tolerance 0.1 mm, dt_max
  /// 40 ms), 20 s cap.
  static SimulationSettings defaultSimulationSettings();
  /// The build's options for `model`: settlingModelSpec(model, 4 /s), i.e. settle damping 4 /s and the
  /// definite-fix Jacobian where the model has these keys. Throws ClothModelError for unknown models.
  static ClothModelSpec defaultModelSpec(const std::string& model);
};

struct DrapeBuildReport {
  std::int64_t textile_id = 0;
  std::int64_t generation = 0;    ///< the generation the rows were written to
  std::string symmetry;           ///< "none", "x", "y", "xy" (as used: "none" when switched off)
  bool symmetric_grid = false;    ///< particle grid symmetric, mirrored rows derived
  int planned = 0;                ///< hold points (rows) in the plan
  int to_simulate = 0;            ///< simulated rows in the plan
  int already_done = 0;           ///< simulated rows done before this build
  int simulated_now = 0;          ///< simulations finished (done) in this build
  int failed_now = 0;             ///< simulations that failed in this build
  int derived_now = 0;            ///< mirror rows derived in this build
  int done_elsewhere = 0;         ///< jobs another builder of the same database finished (done or failed)
  double wall_seconds = 0;
  double simulation_seconds = 0;  ///< sum of the simulations' wall times
  std::vector<std::string> failures;  ///< "hold (x, y): reason"
};

/// Adds the counts, times and failures of `part` (one pass, or one member's build) to `total`; the
/// textile id and generation become part's.
void accumulateBuildReport(DrapeBuildReport& total, const DrapeBuildReport& part);

/// Runs a pass's simulations in other processes (the MPI build farm, docs/build_farm.md): the builder
/// plans, claims, derives the mirror rows and stores; the other side only simulates, with
/// DrapeDatabaseBuilder::simulateHoldPoint of a builder of the same configuration.
class RemoteSimulator {
 public:
  virtual ~RemoteSimulator() = default;
  /// Simulations that can run at once: the pass runs this many worker threads, slots 0 .. slots() - 1.
  virtual int slots() const = 0;
  /// Simulates hold point `plan_index` of pass `corner` as row `simulation_id` on `slot` (never two calls
  /// for one slot at a time). Throws DrapeDatabaseError if the other side is gone or answers garbage.
  virtual SimulationOutcome simulate(int slot, int corner, std::size_t plan_index, std::int64_t simulation_id) = 0;
};

class DrapeDatabaseBuilder {
 public:
  /// Validates the configuration (outline, material, finite settings: by building the scene of the
  /// first hold point) and throws InvalidInputError before anything is written.
  DrapeDatabaseBuilder(HangingDrapeDatabase& db, DrapeBuildConfig config);
  /// A builder without a database, for a build farm's worker process: it validates and plans as the
  /// builder of the same configuration does and only runs simulateHoldPoint(); build() throws.
  explicit DrapeDatabaseBuilder(DrapeBuildConfig config);

  /// The simulation of hold point `plan_index` of pass `corner` (-1: the unbracketed pass; 0..3 with
  /// bracket_hold_points) as row `simulation_id`, with its views: what a build stores for that row. The
  /// remote half of RemoteSimulator; needs no database. Throws InvalidInputError for a bad corner/index.
  SimulationOutcome simulateHoldPoint(int corner, std::size_t plan_index, std::int64_t simulation_id) const;

  /// Plans (or re-plans) the rows and runs every pending one. Throws DrapeDatabaseError on database
  /// failures (the simulations committed so far stay).
  DrapeBuildReport build();

  /// Canonical hold points (fundamental domain) and the full plan the build uses.
  const std::vector<PlannedHoldPoint>& plan() const { return plan_; }
  const TextileSymmetry& symmetry() const { return symmetry_; }
  bool symmetricGrid() const { return symmetric_grid_; }

  /// Canonical text of all simulation and view settings (the `parameters` column). `bracket_corner`
  /// >= 0 names the bracket pass (bracket_hold_points); -1: nearest-particle holds.
  static std::string parametersText(const DrapeBuildConfig& config, int bracket_corner = -1);
  /// Every parameter text a build of `config` writes: one, or one per bracket corner (0..3).
  static std::vector<std::string> parameterTexts(const DrapeBuildConfig& config);
  /// The textile-frame point whose nearest particle a bracket pass pins for hold point `hold`: the
  /// corner (bit 0: upper column, bit 1: upper row) of the grid cell containing `hold`; `hold` itself
  /// for corner -1. Empty if that corner duplicates a lower corner (hold on a grid line) or is not a
  /// particle of the textile.
  static std::optional<Vec2> bracketHold(const ParticleGrid& grid, const Vec2& hold, int corner);
  /// The plan of one bracket pass (corner 0..3): the hold points whose corner particle exists and is
  /// not a duplicate, with their mirror images (the full plan for corner -1).
  std::vector<PlannedHoldPoint> passPlan(int corner) const;
  /// The scene of one hold point under `config`.
  static DrapeSceneSpec sceneSpec(const DrapeBuildConfig& config, const Vec2& hold);

 private:
  /// One pass: plans its rows (drape_build_plan.cpp) and runs its jobs (drape_build_worker.cpp) on
  /// the worker threads.
  DrapeBuildReport buildPass(int corner, const std::vector<PlannedHoldPoint>& plan);
  DrapeBuildPass passInfo(int corner, const internal::PassPlan& plan, int workers) const;
  /// The textile and generation the rows go to (DrapeBuildConfig::staged_textile_id).
  std::pair<std::int64_t, std::int64_t> targetTextile();

  HangingDrapeDatabase& database() const;  ///< throws InvalidInputError for a simulate-only builder
  /// Claims row `id` for this builder, also when a dead builder of this machine holds it. When the claim
  /// fails, *status is the row's status as read (pending: held by a live builder).
  bool claimRow(std::int64_t id, SimulationStatus* status);

  HangingDrapeDatabase* db_ = nullptr;
  DrapeBuildConfig config_;
  TextileSymmetry symmetry_;
  bool symmetric_grid_ = false;
  std::vector<Vec2> canonical_;   ///< the simulated (fundamental-domain) hold points
  ParticleGrid grid_;             ///< the particle grid of every simulation
  std::vector<PlannedHoldPoint> plan_;
  std::string claim_owner_;       ///< this builder's name in the row claims
  mutable std::once_flag mesh_once_;                    ///< simulateHoldPoint's mesh, made once
  mutable std::shared_ptr<internal::BuildMesh> mesh_;
};

/// Silhouettes of a mirrored shape from the source shape's silhouettes. With the world mirror of
/// textile_symmetry.h, the view at azimuth a of the mirrored shape is the source's view at -a (mirror x)
/// or 180 - a (mirror y) flipped left-right about the hold axis, or the source's view at a + 180 (both
/// mirrors, a half turn) as it is. Exact for the orthographic and the pinhole projection (the hold point
/// lies on the canonical frame's vertical centre line), so mirror-equivalent hold points get identical
/// silhouette sets. Returns false (and leaves *out empty) if a needed source angle is not in `source`.
bool mirroredViews(const std::vector<ViewInput>& source, MirrorKind m, const std::vector<double>& angles,
                   std::vector<ViewInput>* out);

/// The mask flipped left-right (column x -> width - 1 - x).
vision::BitMask flipLeftRight(const vision::BitMask& mask);

}  // namespace db
}  // namespace textile_handling
