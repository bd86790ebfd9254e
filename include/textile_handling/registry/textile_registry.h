// TextileRegistry: the ROS-free core behind the drape_simulator node's register_textile, resimulate and
// list_textiles services. It validates requests at the boundary (nothing is written for a bad request),
// stores textiles in the hanging-drape database and runs their database builds on one worker thread,
// FIFO (or hands them to an external command such as an MPI build farm), reporting progress and
// database changes through callbacks. See docs/ros.md and docs/build_farm.md.
#pragma once

#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "textile_handling/db/drape_build_members.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace registry {

/// A new textile as a client describes it.
struct TextileRegistration {
  std::string name;
  std::vector<Vec2> outline;              ///< full outline polygon, textile frame [m]
  std::vector<NamedPoint> named_points;   ///< corners and predefined grasp points
  std::string material_name;              ///< a name known to the registry (empty = default material)
  std::string material_yaml;              ///< or a whole material as YAML text (wins over the name)
  Real hold_point_spacing = 0;            ///< lattice spacing of the hold points [m]; 0 = default
  std::string model;                      ///< cloth model (RegistryOptions::models); empty = default
  /// Options of `model` as "key=value key=value" (the scene file's model: keys); empty = the build
  /// defaults for that model (DrapeBuildConfig::defaultModelSpec).
  std::string model_options;
};

/// A rebuild of a stored textile's entries; empty / zero fields keep the registry's defaults.
struct ResimulationRequest {
  std::int64_t textile_id = 0;
  std::string material_name;              ///< empty = keep the stored material
  std::string material_yaml;
  Real spacing = 0;                       ///< particle grid spacing d [m]; 0 = default
  std::string model;                      ///< cloth model; empty = default
  std::string model_options;              ///< as TextileRegistration::model_options
};

struct RegistryOptions {
  /// Template of every build: simulation settings, views, workers, default spacing and lattice.
  db::DrapeBuildConfig build;
  /// Database members every build makes, in order (db/drape_build_members.h); empty = the base only.
  /// A resimulation is promoted when every member's rows are complete enough (max_failed_fraction).
  std::vector<db::DrapeMemberSpec> members;
  /// Directory of material YAML files (NAME.yaml); "cotton" is also built in.
  std::string material_dir;
  /// Upper bound on the hold points of one build (a guard against absurd lattice spacings).
  int max_hold_points = 2000;
  /// Models a request may name; empty = every model in ClothModelRegistry.
  std::vector<std::string> models;
  /// A resimulation replaces the active entries only if at most this fraction of its simulations
  /// failed (the rest done); otherwise the old entries stay and the new ones are kept staged.
  double max_failed_fraction = 0.05;
  /// Non-empty: every build runs as this external command instead of on the registry's worker thread
  /// (docs/build_farm.md, "The drape simulator node on a farm"): the words of a `drape_db build` command
  /// line without database and job, e.g. {"mpirun", "-np", "4", "--hostfile", "H", "/path/drape_db",
  /// "build", "--mpi"}. For each job the registry writes a build-job file (db/drape_build_job.h) and
  /// appends "--db DATABASE --job FILE --progress-records"; it reads the command's progress and report
  /// lines, and a command that ends otherwise than with exit status 0 or 4 fails the job.
  std::vector<std::string> build_command;
  /// Directory of the build-job files (created with mode 0700; each file is removed when its command
  /// ends); empty = <temporary directory>/textile_handling_build_jobs_<uid>. With a hostfile it must
  /// be readable on the machine of rank 0.
  std::string build_job_dir;
  /// Seconds an external build gets after SIGTERM (the registry stopping) before SIGKILL.
  double build_stop_grace_s = 10;
};

struct BuildProgressEvent {
  std::int64_t textile_id = 0;
  std::string textile_name;
  std::string state;        ///< queued | running | done | failed
  int done = 0, total = 0, failed = 0;
  double elapsed_s = 0, eta_s = 0;
  int jobs_queued = 0;      ///< jobs waiting behind this one
  std::string message;
};

struct TextileSummary {
  db::TextileRecord record;
  db::DatabaseCounts counts;
};

/// A stored rest shape with the triangles of its particle grid (for markers and exports).
struct StoredRestShape {
  std::int64_t simulation_id = 0;
  Vec2 hold = Vec2::Zero();              ///< stored hold point, textile frame [m]
  VecX positions;                        ///< final positions, sim world [m]
  Index held_particle = -1;
  std::vector<std::array<Index, 3>> triangles;
};

/// What a request queued.
struct QueuedBuild {
  std::int64_t textile_id = 0;
  int hold_points = 0;      ///< hold points planned (mirror-derived ones included)
};

class TextileRegistry {
 public:
  using ProgressCallback = std::function<void(const BuildProgressEvent&)>;
  using ChangedCallback = std::function<void(std::int64_t textile_id)>;

  /// Opens (creates) the database at `database_path`, an SQLite file (missing directories get mode 0755
  /// whatever the umask) or a `postgresql://` URL, and starts the worker. Throws db::DrapeDatabaseError if the file cannot be opened,
  /// OutputError if its directory cannot be created, std::invalid_argument for bad options.
  TextileRegistry(std::string database_path, RegistryOptions options, ProgressCallback on_progress = {},
                  ChangedCallback on_changed = {});
  /// Stops the worker: the build in progress stops after its running simulations (resumable).
  ~TextileRegistry();
  TextileRegistry(const TextileRegistry&) = delete;
  TextileRegistry& operator=(const TextileRegistry&) = delete;

  /// Validates and stores a textile, queues its build and returns at once. Throws
  /// db::InvalidInputError (nothing stored) with a message naming the offending field.
  QueuedBuild registerTextile(const TextileRegistration& request);
  /// Queues a rebuild of a stored textile. The job builds a staged generation beside the old entries,
  /// which readers keep using until the new set is complete; then one transaction swaps them
  /// (docs/database.md, "Generations"). Throws db::NotFoundError for an unknown id,
  /// db::InvalidInputError for bad fields.
  QueuedBuild resimulate(const ResimulationRequest& request);
  /// Queues the completion of every staged generation in the database (rebuilds interrupted by a
  /// crash or shutdown), with the staged material, spacing and model and the current defaults
  /// otherwise. Returns the number of jobs queued.
  int resumeStagedBuilds();
  /// Queues the build of a stored textile with the current defaults (resumes an interrupted build;
  /// nothing to do if complete).
  QueuedBuild ensureBuilt(std::int64_t textile_id);
  std::vector<TextileSummary> list() const;
  /// Stores a preset textile (presetTextile(name)) with the default material unless one of that name
  /// exists; returns its id. Throws db::InvalidInputError for an unknown preset.
  std::int64_t ensurePreset(const std::string& name);
  /// The done simulation of a textile whose hold point is nearest to `hold`. Throws db::NotFoundError
  /// (unknown textile, nothing simulated yet).
  StoredRestShape restShape(std::int64_t textile_id, const Vec2& hold) const;
  /// Material of registrations that name none (and of presets).
  void setDefaultMaterial(const Material& m);

  /// Resolves a material by name (material_dir/NAME.yaml or built-in cotton) or from YAML text.
  Material resolveMaterial(const std::string& name, const std::string& yaml) const;

  /// Jobs waiting or running.
  int pendingJobs() const;
  /// Blocks until no job is waiting or running, or `timeout_s` passed; returns true when idle.
  bool waitIdle(double timeout_s) const;
  /// The database setting as messages may show it (a URL's password replaced by ***).
  const std::string& databasePath() const { return db_->path(); }

 private:
  struct Job {
    std::int64_t textile_id = 0;
    std::string textile_name;
    db::DrapeBuildConfig config;
    /// A rebuild into a staged generation: a new one is started when the job runs (stage_new), or the
    /// existing one is completed; promoted when complete.
    bool staged = false;
    bool stage_new = false;
    Real request_spacing = 0;       ///< recorded with a new staged generation (0 = default)
    std::string request_model;
  };

  QueuedBuild enqueue(Job job);
  /// A build of a stored textile with the registry's defaults and `material`.
  Job storedTextileJob(const db::TextileRecord& rec, const Material& material) const;
  /// The build's model for a request's model text ("name key=value ..."); throws InvalidInputError.
  ClothModelSpec checkedModel(const std::string& model_text) const;
  int planHoldPoints(const db::DrapeBuildConfig& config);
  void workerLoop();
  void runJob(Job& job, int queued_behind);
  using BuildProgressFn = std::function<void(const db::DrapeBuildProgress&)>;
  /// The job's member builds on this thread, into `wdb`.
  db::DrapeBuildReport buildHere(db::HangingDrapeDatabase& wdb, Job& job, const BuildProgressFn& on_progress);
  /// The job's member builds as options_.build_command; throws std::runtime_error if the command cannot
  /// run or fails.
  db::DrapeBuildReport buildWithCommand(const Job& job, const BuildProgressFn& on_progress);
  /// Swaps a finished staged build in; false (and why in *outcome) if it is incomplete.
  bool promoteIfComplete(db::HangingDrapeDatabase& wdb, const Job& job, const db::DrapeBuildReport& rep,
                         std::string* outcome);
  void emit(const BuildProgressEvent& e) const;

  std::string path_;
  RegistryOptions options_;
  ProgressCallback on_progress_;
  ChangedCallback on_changed_;
  // The service threads' connection; HangingDrapeDatabase serialises its own calls, and no service
  // holds it across heavy work (validation and planning run without it).
  std::unique_ptr<db::HangingDrapeDatabase> db_;
  mutable std::mutex queue_mutex_;
  mutable std::condition_variable queue_cv_;
  std::deque<Job> jobs_;
  std::string job_dir_;            ///< build-job files of options_.build_command
  int job_files_written_ = 0;
  bool running_job_ = false;
  bool stop_ = false;
  std::atomic<bool> stop_requested_{false};
  std::thread worker_;
};

}  // namespace registry
}  // namespace textile_handling
