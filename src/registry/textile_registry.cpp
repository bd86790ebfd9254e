#include "textile_handling/registry/textile_registry.h"
#include "textile_handling/db/postgres_connection.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "textile_handling/db/build_progress_records.h"
#include "textile_handling/db/database_errors.h"
#include "textile_handling/db/drape_build_job.h"
#include "textile_handling/registry/external_build_command.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace registry {

namespace {

using db::InvalidInputError;

// Textile, named-point and material names share one rule (validateTextileName).
void checkName(const std::string& name, const char* what) {
  std::string why;
  if (!validateTextileName(name, &why)) throw InvalidInputError(std::string(what) + ": " + why);
}

void checkSpacing(Real v, const char* what) {
  if (!std::isfinite(v) || v < 0) throw InvalidInputError(std::string(what) + " must be finite and >= 0 (0 = default)");
}

// The database members every build makes (the base alone by default).
std::vector<db::DrapeMemberSpec> buildMembers(const RegistryOptions& o) {
  return o.members.empty() ? db::drapeMembersByName("base") : o.members;
}

}  // namespace

TextileRegistry::TextileRegistry(std::string database_path, RegistryOptions options, ProgressCallback on_progress,
                                 ChangedCallback on_changed)
    : path_(std::move(database_path)),
      options_(std::move(options)),
      on_progress_(std::move(on_progress)),
      on_changed_(std::move(on_changed)) {
  if (path_.empty()) throw std::invalid_argument("TextileRegistry: empty database path");
  if (!(options_.build.lattice_spacing > 0) || !(options_.build.spacing > 0) || options_.max_hold_points < 1)
    throw std::invalid_argument("TextileRegistry: lattice spacing, particle spacing and max_hold_points must be positive");
  if (!db::isPostgresUrl(path_)) {  // a server URL names no local directory
    const std::filesystem::path parent = std::filesystem::path(path_).parent_path();
    // 0755 whatever the process umask (a node started under umask 000 must not make world-writable
    // directories).
    if (!parent.empty()) createDirectories(parent.string(), 0755);
  }
  if (!options_.build_command.empty()) {
    if (options_.build_command.front().empty()) throw std::invalid_argument("TextileRegistry: empty build command");
    if (!(options_.build_stop_grace_s >= 0 && options_.build_stop_grace_s <= 3600))
      throw std::invalid_argument("TextileRegistry: build_stop_grace_s must be in [0, 3600]");
    job_dir_ = options_.build_job_dir.empty()
                   ? (std::filesystem::temp_directory_path() / ("textile_handling_build_jobs_" + std::to_string(::getuid()))).string()
                   : options_.build_job_dir;
    createDirectories(job_dir_, 0700);
    checkWritableDirectory(job_dir_);
  }
  db_ = std::make_unique<db::HangingDrapeDatabase>(path_);
  worker_ = std::thread([this] { workerLoop(); });
}

TextileRegistry::~TextileRegistry() {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_ = true;
  }
  stop_requested_ = true;
  queue_cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

Material TextileRegistry::resolveMaterial(const std::string& name, const std::string& yaml) const {
  if (!yaml.empty()) {
    try {
      return parseMaterialYaml(yaml);
    } catch (const std::exception& e) {
      throw InvalidInputError(std::string("material_yaml: ") + e.what());
    }
  }
  if (name.empty()) return options_.build.material;
  checkName(name, "material");
  if (!options_.material_dir.empty()) {
    const std::string file = options_.material_dir + "/" + name + ".yaml";
    if (std::filesystem::exists(file)) {
      try {
        return loadMaterialYaml(file);
      } catch (const std::exception& e) {
        throw InvalidInputError(std::string("material '") + name + "': " + e.what());
      }
    }
  }
  if (name == "cotton") return Material::cotton();
  throw InvalidInputError("unknown material '" + name + "' (no " +
                          (options_.material_dir.empty() ? std::string("material directory")
                                                         : options_.material_dir + "/" + name + ".yaml") +
                          ", and not the built-in cotton)");
}

int TextileRegistry::planHoldPoints(const db::DrapeBuildConfig& config) {
  // The builder validates the configuration (scene of the first hold point) and plans the rows; it
  // neither reads nor writes the database until build().
  db::DrapeDatabaseBuilder planner(*db_, config);
  const int n = static_cast<int>(planner.plan().size());
  if (n > options_.max_hold_points)
    throw InvalidInputError("the hold-point lattice has " + std::to_string(n) + " points (limit " +
                            std::to_string(options_.max_hold_points) + "): choose a larger hold_point_spacing");
  return n;
}

ClothModelSpec TextileRegistry::checkedModel(const std::string& model_text) const {
  try {
    // "name" or "name key=value ..." (a request's model and model_options, or a staged generation's).
    const ClothModelSpec request = parseClothModelSpecText(model_text);
    if (!options_.models.empty() &&
        std::find(options_.models.begin(), options_.models.end(), request.name) == options_.models.end()) {
      std::string known;
      for (const auto& m : options_.models) known += (known.empty() ? "" : ", ") + m;
      throw InvalidInputError("unknown model '" + request.name + "' (available: " + known + ")");
    }
    // The template's options when it builds this model already, the build defaults otherwise; then the
    // request's own option values.
    ClothModelSpec spec = request.name == options_.build.model.name ? options_.build.model
                                                                     : db::DrapeBuildConfig::defaultModelSpec(request.name);
    for (const auto& [key, value] : request.options) spec.set(key, value);
    ClothModelRegistry::instance().validate(spec);
    return spec;
  } catch (const ClothModelError& e) {
    throw InvalidInputError(e.what());
  }
}

namespace {
// The request's model as one text ("name key=value ..."); empty when the request names no model.
std::string requestModelText(const std::string& model, const std::string& model_options) {
  if (model.empty() && !model_options.empty())
    throw InvalidInputError("model_options given without a model name");
  return model_options.empty() ? model : model + " " + model_options;
}
}  // namespace

QueuedBuild TextileRegistry::registerTextile(const TextileRegistration& r) {
  checkName(r.name, "name");
  checkSpacing(r.hold_point_spacing, "hold_point_spacing_m");
  TextileOutline outline;
  outline.name = r.name;
  outline.outline = r.outline;
  outline.named_points = r.named_points;
  std::string error;
  if (!validateTextileOutline(outline, &error)) throw InvalidInputError("outline: " + error);
  const Material material = resolveMaterial(r.material_name, r.material_yaml);
  if (!material.validate(&error)) throw InvalidInputError("material: " + error);
  if (db_->findTextile(r.name)) throw InvalidInputError("a textile named '" + r.name + "' already exists");
  Job job;
  job.textile_name = r.name;
  job.config = options_.build;
  job.config.textile = outline;
  job.config.material = material;
  if (r.hold_point_spacing > 0) job.config.lattice_spacing = r.hold_point_spacing;
  const std::string model_text = requestModelText(r.model, r.model_options);
  if (!model_text.empty()) job.config.model = checkedModel(model_text);
  const int planned = planHoldPoints(job.config);  // throws before anything is stored
  job.textile_id = db_->addTextile(outline, material);  // refuses a name taken meanwhile
  if (on_changed_) on_changed_(job.textile_id);
  QueuedBuild q = enqueue(std::move(job));
  q.hold_points = planned;
  return q;
}

QueuedBuild TextileRegistry::resimulate(const ResimulationRequest& r) {
  checkSpacing(r.spacing, "spacing_m");
  const db::TextileRecord rec = db_->textile(r.textile_id);  // NotFoundError for an unknown id
  Job job = storedTextileJob(
      rec, r.material_name.empty() && r.material_yaml.empty() ? rec.material : resolveMaterial(r.material_name, r.material_yaml));
  std::string error;
  if (!job.config.material.validate(&error)) throw InvalidInputError("material: " + error);
  if (r.spacing > 0) job.config.spacing = r.spacing;
  const std::string model_text = requestModelText(r.model, r.model_options);
  if (!model_text.empty()) job.config.model = checkedModel(model_text);
  job.staged = true;
  job.stage_new = true;
  job.request_spacing = r.spacing;
  job.request_model = model_text;
  const int planned = planHoldPoints(job.config);
  QueuedBuild q = enqueue(std::move(job));
  q.hold_points = planned;
  return q;
}

int TextileRegistry::resumeStagedBuilds() {
  int queued = 0;
  for (const db::StagedGeneration& g : db_->stagedGenerations()) {
    Job job = storedTextileJob(db_->textile(g.textile_id), g.material);
    if (g.spacing > 0) job.config.spacing = g.spacing;
    if (!g.model.empty()) job.config.model = checkedModel(g.model);
    job.staged = true;
    planHoldPoints(job.config);
    enqueue(std::move(job));
    ++queued;
  }
  return queued;
}

TextileRegistry::Job TextileRegistry::storedTextileJob(const db::TextileRecord& rec, const Material& material) const {
  Job job;
  job.textile_id = rec.id;
  job.textile_name = rec.outline.name;
  job.config = options_.build;
  job.config.textile = rec.outline;
  job.config.material = material;
  return job;
}

QueuedBuild TextileRegistry::ensureBuilt(std::int64_t textile_id) {
  const db::TextileRecord rec = db_->textile(textile_id);
  Job job = storedTextileJob(rec, rec.material);
  const int planned = planHoldPoints(job.config);
  QueuedBuild q = enqueue(std::move(job));
  q.hold_points = planned;
  return q;
}

std::vector<TextileSummary> TextileRegistry::list() const {
  std::vector<TextileSummary> out;
  for (auto& rec : db_->textiles()) {
    TextileSummary s;
    s.counts = db_->counts(rec.id);
    s.record = std::move(rec);
    out.push_back(std::move(s));
  }
  return out;
}

std::int64_t TextileRegistry::ensurePreset(const std::string& name) {
  TextileOutline outline;
  try {
    outline = presetTextile(name);
  } catch (const std::exception& e) {
    throw InvalidInputError(e.what());
  }
  // A stored preset keeps its material (a resimulation may have changed it).
  if (const auto rec = db_->findTextile(name)) return rec->id;
  return db_->addTextile(outline, options_.build.material);
}

void TextileRegistry::setDefaultMaterial(const Material& m) {
  std::string error;
  if (!m.validate(&error)) throw InvalidInputError("default material: " + error);
  std::lock_guard<std::mutex> lock(queue_mutex_);
  options_.build.material = m;
}

StoredRestShape TextileRegistry::restShape(std::int64_t textile_id, const Vec2& hold) const {
  const db::TextileRecord rec = db_->textile(textile_id);
  auto done = db_->simulations(textile_id, db::SimulationStatus::kDone);
  done.erase(std::remove_if(done.begin(), done.end(), [](const db::SimulationRecord& s) { return !s.active; }), done.end());
  if (done.empty()) throw db::NotFoundError("textile " + std::to_string(textile_id) + " has no finished simulation yet");
  const db::SimulationRecord* best = &done.front();
  for (const auto& s : done)
    if ((s.hold - hold).squaredNorm() < (best->hold - hold).squaredNorm()) best = &s;
  StoredRestShape out;
  out.simulation_id = best->id;
  out.hold = best->hold;
  out.positions = db_->positions(best->id);
  out.held_particle = best->held_particle;
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(rec.outline, best->spacing, &error);
  if (grid.empty()) throw db::InvalidInputError("stored textile no longer rasterises: " + error);
  if (3 * grid.numActive() != out.positions.size() || out.held_particle < 0 || out.held_particle >= grid.numActive())
    throw db::BlobFormatError("simulation " + std::to_string(best->id) + ": positions do not match its particle grid");
  for (const auto& t : vision::trianglesFromTopology(ParticleTopology::fromGrid(grid))) out.triangles.push_back(t);
  return out;
}

int TextileRegistry::pendingJobs() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return static_cast<int>(jobs_.size()) + (running_job_ ? 1 : 0);
}

bool TextileRegistry::waitIdle(double timeout_s) const {
  std::unique_lock<std::mutex> lock(queue_mutex_);
  return queue_cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
                            [this] { return jobs_.empty() && !running_job_; });
}

QueuedBuild TextileRegistry::enqueue(Job job) {
  QueuedBuild q;
  q.textile_id = job.textile_id;
  BuildProgressEvent e;
  e.textile_id = job.textile_id;
  e.textile_name = job.textile_name;
  e.state = "queued";
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    e.jobs_queued = static_cast<int>(jobs_.size()) + (running_job_ ? 1 : 0);
  }
  // "queued" goes out before the worker can see the job, so it always precedes "running".
  emit(e);
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    jobs_.push_back(std::move(job));
  }
  queue_cv_.notify_all();
  return q;
}

void TextileRegistry::emit(const BuildProgressEvent& e) const {
  if (on_progress_) on_progress_(e);
}

void TextileRegistry::workerLoop() {
  for (;;) {
    Job job;
    int behind = 0;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_cv_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
      if (stop_) return;
      job = std::move(jobs_.front());
      jobs_.pop_front();
      behind = static_cast<int>(jobs_.size());
      running_job_ = true;
    }
    runJob(job, behind);
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      running_job_ = false;
    }
    queue_cv_.notify_all();
  }
}

void TextileRegistry::runJob(Job& job, int queued_behind) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  BuildProgressEvent e;
  e.textile_id = job.textile_id;
  e.textile_name = job.textile_name;
  e.jobs_queued = queued_behind;
  e.state = "running";
  emit(e);
  try {
    // The worker's own connection: SQLite connections are not shared between threads here.
    db::HangingDrapeDatabase wdb(path_);
    if (job.stage_new)
      wdb.stageGeneration(job.textile_id, job.config.material, job.request_spacing, job.request_model);
    if (job.staged) job.config.staged_textile_id = job.textile_id;
    const BuildProgressFn on_progress = [&](const db::DrapeBuildProgress& progress) {
      BuildProgressEvent p = e;
      p.done = progress.done;
      p.total = progress.total;
      p.elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
      p.eta_s = std::max(0.0, progress.eta_s);  // the message's 0 = unknown or done
      emit(p);
    };
    const db::DrapeBuildReport rep =
        options_.build_command.empty() ? buildHere(wdb, job, on_progress) : buildWithCommand(job, on_progress);
    e.done = rep.already_done + rep.simulated_now;
    e.total = rep.to_simulate;
    e.failed = rep.failed_now;
    e.elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
    e.state = stop_requested_ ? "stopped" : (rep.failed_now > 0 ? "failed" : "done");
    e.message = std::to_string(rep.simulated_now) + " simulated, " + std::to_string(rep.derived_now) +
                " mirrored, " + std::to_string(rep.failed_now) + " failed";
    if (!rep.failures.empty()) e.message += "; first failure: " + rep.failures.front();
    if (job.staged && !stop_requested_) {
      std::string outcome;
      const bool promoted = promoteIfComplete(wdb, job, rep, &outcome);
      e.state = promoted ? "done" : "failed";
      e.message += "; " + outcome;
    }
  } catch (const std::exception& ex) {
    e.state = "failed";
    e.message = ex.what();
    e.elapsed_s = std::chrono::duration<double>(Clock::now() - start).count();
  }
  emit(e);
  // A staged build changes nothing readers see until its promotion (which announces itself).
  if (!job.staged && on_changed_) on_changed_(job.textile_id);
}

db::DrapeBuildReport TextileRegistry::buildHere(db::HangingDrapeDatabase& wdb, Job& job, const BuildProgressFn& on_progress) {
  job.config.should_stop = [this] { return stop_requested_.load(); };
  job.config.on_progress = on_progress;
  // One build per database member (the base alone by default); the report sums them.
  db::DrapeBuildReport rep;
  for (const db::DrapeBuildReport& r : db::buildDrapeMembers(wdb, job.config, buildMembers(options_)))
    db::accumulateBuildReport(rep, r);
  return rep;
}

db::DrapeBuildReport TextileRegistry::buildWithCommand(const Job& job, const BuildProgressFn& on_progress) {
  db::DrapeBuildJob file;
  file.config = job.config;
  file.members.clear();
  for (const db::DrapeMemberSpec& m : buildMembers(options_)) file.members += (file.members.empty() ? "" : ",") + m.name;
  // The process id keeps two registries that share the directory (two nodes of one machine) apart.
  const std::string job_path = job_dir_ + "/textile_" + std::to_string(job.textile_id) + "_" +
                               std::to_string(::getpid()) + "_" + std::to_string(++job_files_written_) + ".yaml";
  db::saveDrapeBuildJob(file, job_path);
  std::vector<std::string> argv = options_.build_command;
  argv.insert(argv.end(), {"--db", path_, "--job", job_path, "--progress-records"});

  db::DrapeBuildReport rep;
  int reports = 0;
  const auto on_line = [&](const std::string& line) {
    db::DrapeBuildProgress progress;
    if (db::parseProgressRecord(line, &progress)) {
      on_progress(progress);
      return;
    }
    db::DrapeBuildReport member;
    if (db::parseReportRecord(line, &member)) {  // one per member build: the job's report sums them
      db::accumulateBuildReport(rep, member);
      ++reports;
      return;
    }
    // drape_db's line for a failed simulation (build_progress_printer.cpp): kept for the job's message.
    static const std::string kFailed = "drape_db: simulation ";
    if (line.rfind(kFailed, 0) == 0 && line.find(" failed: ") != std::string::npos)
      rep.failures.push_back(line.substr(std::string("drape_db: ").size()));
  };
  const ExternalCommandOutcome outcome =
      runExternalCommand(argv, on_line, [this] { return stop_requested_.load(); }, options_.build_stop_grace_s);
  std::remove(job_path.c_str());
  if (!outcome.started) throw std::runtime_error("database build command: " + outcome.error);
  if (outcome.stopped) return rep;  // resumable: the next build of these settings continues it
  std::string tail;
  for (std::size_t k = outcome.tail.size() > 3 ? outcome.tail.size() - 3 : 0; k < outcome.tail.size(); ++k)
    tail += (tail.empty() ? "" : " | ") + outcome.tail[k];
  if (!outcome.exited || (outcome.exit_code != 0 && outcome.exit_code != 4))
    throw std::runtime_error("database build command ended with " + describeOutcome(outcome) +
                             (tail.empty() ? std::string() : ": " + tail));
  if (reports == 0)
    throw std::runtime_error("database build command printed no build report (is it `drape_db build`?): " + tail);
  return rep;
}

bool TextileRegistry::promoteIfComplete(db::HangingDrapeDatabase& wdb, const Job& job, const db::DrapeBuildReport& rep,
                                        std::string* outcome) {
  try {
    std::vector<std::string> texts;  // every member's rows must be complete enough
    for (const db::DrapeMemberSpec& m : buildMembers(options_))
      for (const std::string& t : db::DrapeDatabaseBuilder::parameterTexts(db::memberBuildConfig(job.config, m)))
        texts.push_back(t);
    const db::PromotionReport p =
        wdb.promoteStagedGeneration(job.textile_id, rep.generation, texts, options_.max_failed_fraction);
    *outcome = "generation " + std::to_string(p.generation) + " active (" + std::to_string(p.done) + " done, " +
               std::to_string(p.failed) + " failed; " + std::to_string(p.removed_simulations) +
               " old simulations removed)";
  } catch (const db::InvalidInputError& ex) {
    *outcome = std::string("old entries kept: ") + ex.what();
    return false;
  }
  if (on_changed_) on_changed_(job.textile_id);
  return true;
}

}  // namespace registry
}  // namespace textile_handling
