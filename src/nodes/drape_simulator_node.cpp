#include "drape_simulator_node.h"

#include <ros/package.h>
#include <visualization_msgs/MarkerArray.h>

#include <cmath>
#include <cstdlib>
#include <new>
#include <stdexcept>

#include "node_paths.h"
#include "textile_handling/BuildProgress.h"
#include "textile_handling/DatabaseChanged.h"
#include "textile_handling/db/database_errors.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {

namespace {

Real positiveParam(ros::NodeHandle& nh, const std::string& name, Real fallback) {
  Real v = fallback;
  nh.param(name, v, fallback);
  if (!std::isfinite(v) || !(v > 0))
    throw std::runtime_error("parameter ~" + name + " must be a finite positive number");
  return v;
}

int positiveIntParam(ros::NodeHandle& nh, const std::string& name, int fallback) {
  int v = fallback;
  nh.param(name, v, fallback);
  if (v < 1) throw std::runtime_error("parameter ~" + name + " must be a positive integer");
  return v;
}

// ~database_build_command: a string of words separated by spaces (no shell quoting) or a list of words;
// the word `drape_db` is this package's drape_db, found beside the node's executable.
std::vector<std::string> buildCommandParam(ros::NodeHandle& pnh) {
  std::vector<std::string> words;
  XmlRpc::XmlRpcValue value;
  if (!pnh.getParam("database_build_command", value)) return words;
  if (value.getType() == XmlRpc::XmlRpcValue::TypeString) {
    words = splitCommandWords(static_cast<std::string>(value));
  } else if (value.getType() == XmlRpc::XmlRpcValue::TypeArray) {
    for (int k = 0; k < value.size(); ++k) {
      if (value[k].getType() != XmlRpc::XmlRpcValue::TypeString)
        throw std::runtime_error("parameter ~database_build_command: every list entry must be a string");
      words.push_back(static_cast<std::string>(value[k]));
    }
  } else {
    throw std::runtime_error("parameter ~database_build_command must be a string or a list of strings");
  }
  // A command that is not a `drape_db build` (or a wrapper of one) fails each job with "printed no build
  // report" (TextileRegistry), so the node need not guess at wrappers here.
  return withToolPath(words, "drape_db", words.empty() ? "" : packageToolPath("drape_db"),
                      "parameter ~database_build_command");
}

}  // namespace

DrapeSimulatorNode::DrapeSimulatorNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) {
  default_spacing_ = positiveParam(pnh, "default_spacing_m", default_spacing_);
  pnh.param<std::string>("default_integrator", default_integrator_, default_integrator_);
  try {
    settings_.integrator = integratorFromString(default_integrator_);
    std::string policy = "error";
    pnh.param<std::string>("time_step_policy", policy, policy);
    settings_.policy = stepPolicyFromString(policy);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("parameter ~default_integrator / ~time_step_policy: ") + e.what());
  }
  settings_.dt = positiveParam(pnh, "initial_dt_s", settings_.dt);
  settings_.dt_max = positiveParam(pnh, "max_dt_s", settings_.dt_max);
  settings_.error_tolerance = positiveParam(pnh, "error_tolerance_m", settings_.error_tolerance);
  settings_.max_time = positiveParam(pnh, "max_sim_time_s", settings_.max_time);
  settings_.solver.relative_tolerance = positiveParam(pnh, "cg_tolerance", settings_.solver.relative_tolerance);
  if (!(settings_.solver.relative_tolerance < 1)) throw std::runtime_error("parameter ~cg_tolerance must be < 1");
  pnh.param("cg_warm_start", settings_.solver.warm_start, settings_.solver.warm_start);
  settings_.solver.newton_tolerance = positiveParam(pnh, "newton_tolerance", settings_.solver.newton_tolerance);
  settings_.solver.newton_max_iterations =
      positiveIntParam(pnh, "newton_max_iterations", settings_.solver.newton_max_iterations);
  std::string preconditioner = toString(settings_.solver.preconditioner);
  pnh.param<std::string>("cg_preconditioner", preconditioner, preconditioner);
  std::string self_collision = "v3";
  pnh.param<std::string>("self_collision", self_collision, self_collision);
  try {
    settings_.solver.preconditioner = preconditionerFromString(preconditioner);
    self_collision_ = self_collision != "off";
    if (self_collision_) collision_.version = selfCollisionVersionFromString(self_collision);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("parameter ~cg_preconditioner / ~self_collision: ") + e.what());
  }
  // Optional floor (a plane z = floor_height_m); absent = no floor.
  double floor_z = 0;
  if (pnh.getParam("floor_height_m", floor_z)) {
    if (!std::isfinite(floor_z)) throw std::runtime_error("parameter ~floor_height_m must be finite");
    PlaneObstacle floor;
    floor.point = Vec3(0, 0, floor_z);
    obstacles_.planes.push_back(floor);
  }
  // simulate_drape's cloth model: any registered model, its options as "key=value ..." text.
  std::string model = "particle_kes", model_options;
  pnh.param<std::string>("model", model, model);
  pnh.param<std::string>("model_options", model_options, model_options);
  double damping = 0;
  pnh.param("settle_damping_per_s", damping, damping);
  if (!std::isfinite(damping) || damping < 0)
    throw std::runtime_error("parameter ~settle_damping_per_s must be finite and >= 0");
  try {
    model_spec_ = parseClothModelSpecText(model + " " + model_options);
    if (ClothModelRegistry::instance().find(model_spec_.name).hasOptionKey("settle_damping_per_s") &&
        !model_spec_.options.count("settle_damping_per_s"))
      model_spec_.set("settle_damping_per_s", damping);
    ClothModelRegistry::instance().validate(model_spec_);
  } catch (const ClothModelError& e) {
    throw std::runtime_error(std::string("parameter ~model / ~model_options: ") + e.what());
  }
  std::vector<double> hold;
  if (pnh.getParam("hold_position_m", hold)) {
    if (hold.size() != 3 || !std::isfinite(hold[0]) || !std::isfinite(hold[1]) || !std::isfinite(hold[2]))
      throw std::runtime_error("parameter ~hold_position_m must be a list of three finite numbers");
    hold_position_ = Vec3(hold[0], hold[1], hold[2]);
  }
  // Memory budget of one simulate_drape scene and of a database build's simultaneous simulations
  // (0 = half of physical memory; docs/simulation.md, "Memory budget").
  double budget_mb = 0;
  pnh.param("memory_budget_mb", budget_mb, budget_mb);
  if (!std::isfinite(budget_mb) || budget_mb < 0 || budget_mb > 1e12)
    throw std::runtime_error("parameter ~memory_budget_mb must be a finite number of MiB >= 0 (0 = half of physical memory)");
  settings_.memory_budget_bytes = static_cast<std::size_t>(budget_mb * 1024 * 1024);
  pnh.param<std::string>("hold_frame", hold_frame_, hold_frame_);
  if (hold_frame_.empty()) throw std::runtime_error("parameter ~hold_frame must not be empty");

  // ---- database and builds ----
  registry::RegistryOptions ro;
  std::string db_path = "~/.ros/textile_handling/drapes.sqlite";
  pnh.param<std::string>("database_path", db_path, db_path);
  db_path = expandHome(db_path);
  if (db_path.empty()) throw std::runtime_error("parameter ~database_path must not be empty");
  ro.material_dir = ros::package::getPath("textile_handling") + "/data/materials";
  pnh.param<std::string>("material_dir", ro.material_dir, ro.material_dir);
  ro.build.spacing = positiveParam(pnh, "database_spacing_m", 0.02);
  ro.build.lattice_spacing = positiveParam(pnh, "hold_point_spacing_m", 0.08);
  ro.build.views.count = positiveIntParam(pnh, "views", 36);
  ro.build.views.step_deg = 360.0 / ro.build.views.count;
  ro.build.workers = positiveIntParam(pnh, "worker_threads", 2);
  ro.build.threads_per_simulation = 1;
  ro.build.hold_height = hold_position_.z();
  ro.build.settings.memory_budget_bytes = settings_.memory_budget_bytes;
  pnh.param("database_self_collision", ro.build.self_collision, false);
  std::string members = "base";
  pnh.param<std::string>("database_members", members, members);
  try {
    ro.members = db::drapeMembersByName(members);
  } catch (const db::InvalidInputError& e) {
    throw std::runtime_error(std::string("parameter ~database_members: ") + e.what());
  }
  ro.max_hold_points = positiveIntParam(pnh, "max_hold_points", ro.max_hold_points);
  pnh.param("max_failed_fraction", ro.max_failed_fraction, ro.max_failed_fraction);
  if (!(ro.max_failed_fraction >= 0 && ro.max_failed_fraction <= 1))
    throw std::runtime_error("parameter ~max_failed_fraction must be in [0, 1]");
  // Builds on an external command (an MPI build farm) instead of the node's worker (docs/build_farm.md).
  ro.build_command = buildCommandParam(pnh);
  pnh.param<std::string>("database_build_job_dir", ro.build_job_dir, ro.build_job_dir);
  ro.build_job_dir = expandHome(ro.build_job_dir);
  std::vector<std::string> presets;
  pnh.param("preset_textiles", presets, presets);
  bool build_presets = false;
  pnh.param("build_presets_on_start", build_presets, build_presets);
  progress_pub_ = pnh.advertise<BuildProgress>("build_progress", 10);
  changed_pub_ = pnh.advertise<DatabaseChanged>("database_changed", 1, /*latch=*/true);
  markers_pub_ = pnh.advertise<visualization_msgs::MarkerArray>("rest_shape_markers", 1, /*latch=*/true);
  std::string default_material = "cotton";
  pnh.param<std::string>("default_material", default_material, default_material);
  try {
    registry_ = std::make_unique<registry::TextileRegistry>(
        db_path, ro, [this](const registry::BuildProgressEvent& e) { publishProgress(e); },
        [this](std::int64_t id) { publishChanged(id); });
    registry_->setDefaultMaterial(registry_->resolveMaterial(default_material, ""));
  } catch (const std::exception& e) {
    throw std::runtime_error("database '" + db_path + "' / ~default_material: " + e.what());
  }
  for (const auto& name : presets) {
    std::int64_t id = 0;
    try {
      id = registry_->ensurePreset(name);
      if (build_presets) registry_->ensureBuilt(id);
    } catch (const std::exception& e) {
      throw std::runtime_error("parameter ~preset_textiles: '" + name + "': " + e.what());
    }
  }
  try {
    const int resumed = registry_->resumeStagedBuilds();
    if (resumed > 0)
      ROS_INFO_NAMED("drape_simulator", "resuming %d interrupted resimulation(s); the old entries stay active meanwhile",
                     resumed);
  } catch (const std::exception& e) {
    ROS_ERROR_NAMED("drape_simulator", "cannot resume interrupted resimulations: %s", e.what());
  }
  publishChanged(0);

  simulate_service_ = pnh.advertiseService("simulate_drape", &DrapeSimulatorNode::simulateDrape, this);
  register_service_ = pnh.advertiseService("register_textile", &DrapeSimulatorNode::registerTextile, this);
  resimulate_service_ = pnh.advertiseService("resimulate", &DrapeSimulatorNode::resimulate, this);
  list_service_ = pnh.advertiseService("list_textiles", &DrapeSimulatorNode::listTextiles, this);
  markers_service_ = pnh.advertiseService("publish_rest_shape", &DrapeSimulatorNode::publishRestShape, this);
  (void)nh;
  ROS_INFO_NAMED("drape_simulator", "ready: database %s, default spacing %.3f m, integrator %s", db_path.c_str(),
                 default_spacing_, default_integrator_.c_str());
  if (!ro.build_command.empty()) {
    std::string command;
    for (const std::string& w : ro.build_command) command += (command.empty() ? "" : " ") + w;
    ROS_INFO_NAMED("drape_simulator", "database builds run as: %s --db DATABASE --job FILE --progress-records",
                   command.c_str());
  }
}

void DrapeSimulatorNode::publishProgress(const registry::BuildProgressEvent& e) {
  BuildProgress m;
  m.header.stamp = ros::Time::now();
  m.textile_id = e.textile_id;
  m.textile_name = e.textile_name;
  m.state = e.state;
  m.done = e.done;
  m.total = e.total;
  m.failed = e.failed;
  m.elapsed_s = e.elapsed_s;
  m.eta_s = e.eta_s;
  m.jobs_queued = e.jobs_queued;
  m.message = e.message;
  progress_pub_.publish(m);
  if (e.state == "failed")
    ROS_WARN_NAMED("drape_simulator", "build of '%s' failed: %s", e.textile_name.c_str(), e.message.c_str());
  else if (e.state != "running" || e.done == e.total)
    ROS_INFO_NAMED("drape_simulator", "build of '%s': %s %d/%d %s", e.textile_name.c_str(), e.state.c_str(), e.done,
                   e.total, e.message.c_str());
}

void DrapeSimulatorNode::publishChanged(std::int64_t textile_id) {
  DatabaseChanged m;
  m.header.stamp = ros::Time::now();
  m.database_path = registry_ ? registry_->databasePath() : "";
  m.textile_id = textile_id;
  if (registry_) {
    try {
      for (const auto& t : registry_->list()) {
        ++m.textiles;
        m.simulations_done += t.counts.done;
        m.views += t.counts.views;
      }
    } catch (const std::exception& e) {
      ROS_WARN_THROTTLE_NAMED(5.0, "drape_simulator", "database_changed: cannot count entries: %s", e.what());
    }
  }
  changed_pub_.publish(m);
}

namespace {

// Converts a request outline (two arrays) and named points; a clear reason on malformed input.
bool outlineFromArrays(const std::vector<double>& xs, const std::vector<double>& ys, std::vector<Vec2>* out,
                       std::string* why) {
  if (xs.size() != ys.size()) {
    *why = "outline_x and outline_y differ in length";
    return false;
  }
  out->clear();
  for (size_t i = 0; i < xs.size(); ++i) out->emplace_back(xs[i], ys[i]);
  return true;
}

}  // namespace

bool DrapeSimulatorNode::registerTextile(RegisterTextile::Request& req, RegisterTextile::Response& res) {
  registry::TextileRegistration r;
  r.name = req.name;
  std::string why;
  if (!outlineFromArrays(req.outline_x, req.outline_y, &r.outline, &why)) {
    res.success = false;
    res.message = why;
    ROS_WARN_THROTTLE_NAMED(1.0, "drape_simulator", "register_textile rejected: %s", why.c_str());
    return true;
  }
  for (const auto& p : req.named_points) r.named_points.push_back(NamedPoint{p.name, p.kind, Vec2(p.x, p.y)});
  r.material_name = req.material;
  r.material_yaml = req.material_yaml;
  r.hold_point_spacing = req.hold_point_spacing_m;
  r.model = req.model;
  r.model_options = req.model_options;
  try {
    const registry::QueuedBuild q = registry_->registerTextile(r);
    res.success = true;
    res.textile_id = q.textile_id;
    res.queued_simulations = q.hold_points;
    res.message = "stored; " + std::to_string(q.hold_points) + " hold points queued";
    ROS_INFO_NAMED("drape_simulator", "registered textile '%s' as id %ld, %d hold points queued", r.name.c_str(),
                   static_cast<long>(q.textile_id), q.hold_points);
  } catch (const std::exception& e) {
    res.success = false;
    res.message = e.what();
    ROS_WARN_THROTTLE_NAMED(1.0, "drape_simulator", "register_textile rejected: %s", e.what());
  }
  return true;
}

bool DrapeSimulatorNode::resimulate(Resimulate::Request& req, Resimulate::Response& res) {
  registry::ResimulationRequest r;
  r.textile_id = req.textile_id;
  r.material_name = req.material;
  r.material_yaml = req.material_yaml;
  r.spacing = req.spacing_m;
  r.model = req.model;
  r.model_options = req.model_options;
  try {
    const registry::QueuedBuild q = registry_->resimulate(r);
    res.success = true;
    res.queued_simulations = q.hold_points;
    res.message = "queued " + std::to_string(q.hold_points) + " hold points";
  } catch (const std::exception& e) {
    res.success = false;
    res.message = e.what();
    ROS_WARN_THROTTLE_NAMED(1.0, "drape_simulator", "resimulate rejected: %s", e.what());
  }
  return true;
}

bool DrapeSimulatorNode::listTextiles(ListTextiles::Request&, ListTextiles::Response& res) {
  try {
    for (const auto& t : registry_->list()) {
      TextileInfo info;
      info.id = t.record.id;
      info.name = t.record.outline.name;
      info.material = t.record.material.name;
      for (const Vec2& v : fullOutline(t.record.outline)) {
        info.outline_x.push_back(v.x());
        info.outline_y.push_back(v.y());
      }
      for (const auto& p : t.record.outline.named_points) {
        NamedPoint2D q;
        q.name = p.name;
        q.kind = p.kind;
        q.x = p.position.x();
        q.y = p.position.y();
        info.named_points.push_back(q);
      }
      info.symmetry = t.record.symmetry.name();
      info.simulations_done = t.counts.done;
      info.simulations_pending = t.counts.pending;
      info.simulations_failed = t.counts.failed;
      info.views = t.counts.views;
      info.generation = t.record.generation;
      info.staged_simulations = t.counts.staged_simulations;
      info.staged_done = t.counts.staged_done;
      info.staged_failed = t.counts.staged_failed;
      res.textiles.push_back(info);
    }
  } catch (const std::exception& e) {
    ROS_ERROR_THROTTLE_NAMED(1.0, "drape_simulator", "list_textiles: %s", e.what());
    return false;
  }
  return true;
}

bool DrapeSimulatorNode::publishRestShape(PublishRestShape::Request& req, PublishRestShape::Response& res) {
  res.success = false;
  if (!std::isfinite(req.hold_x) || !std::isfinite(req.hold_y)) {
    res.message = "hold_x and hold_y must be finite";
    return true;
  }
  try {
    const registry::StoredRestShape shape = registry_->restShape(req.textile_id, Vec2(req.hold_x, req.hold_y));
    visualization_msgs::MarkerArray arr;
    visualization_msgs::Marker del;
    del.action = visualization_msgs::Marker::DELETEALL;
    arr.markers.push_back(del);
    visualization_msgs::Marker m;
    m.header.frame_id = req.frame_id.empty() ? hold_frame_ : req.frame_id;
    m.header.stamp = ros::Time::now();
    m.ns = "rest_shape";
    m.id = 0;
    m.type = visualization_msgs::Marker::TRIANGLE_LIST;
    m.action = visualization_msgs::Marker::ADD;
    m.pose.orientation.w = 1.0;
    m.scale.x = m.scale.y = m.scale.z = 1.0;
    m.color.r = 0.2f;
    m.color.g = 0.5f;
    m.color.b = 0.9f;
    m.color.a = 0.9f;
    // Positions relative to the held particle (the marker frame is the hold frame).
    const Vec3 hold = node3(shape.positions, shape.held_particle);
    for (const auto& tri : shape.triangles)
      for (Index k : tri) {
        geometry_msgs::Point p;
        const Vec3 q = node3(shape.positions, k) - hold;
        p.x = q.x();
        p.y = q.y();
        p.z = q.z();
        m.points.push_back(p);
      }
    arr.markers.push_back(m);
    markers_pub_.publish(arr);
    res.success = true;
    res.simulation_id = shape.simulation_id;
    res.message = "published " + std::to_string(shape.triangles.size()) + " triangles";
  } catch (const std::exception& e) {
    res.message = e.what();
    ROS_WARN_THROTTLE_NAMED(1.0, "drape_simulator", "publish_rest_shape rejected: %s", e.what());
  }
  return true;
}

bool DrapeSimulatorNode::simulateDrape(SimulateDrape::Request& req, SimulateDrape::Response& res) {
  auto reject = [&](const std::string& why) {
    res.success = false;
    res.message = why;
    ROS_WARN_THROTTLE_NAMED(1.0, "drape_simulator", "simulate_drape rejected: %s", why.c_str());
    return true;  // the call itself succeeded; the answer carries the error
  };
  DrapeSceneSpec spec;
  try {
    spec.textile = presetTextile(req.textile);
  } catch (const std::invalid_argument& e) {
    return reject(e.what());
  }
  if (!std::isfinite(req.spacing_m) || req.spacing_m < 0) return reject("spacing_m must be finite and >= 0");
  spec.spacing = req.spacing_m > 0 ? req.spacing_m : default_spacing_;
  HoldPoint hold;
  if (!req.hold_point.empty()) {
    hold.name = req.hold_point;
  } else {
    if (req.hold_xy.size() != 2 || !std::isfinite(req.hold_xy[0]) || !std::isfinite(req.hold_xy[1]))
      return reject("give hold_point (a named point) or hold_xy as two finite numbers");
    hold.position = Vec2(req.hold_xy[0], req.hold_xy[1]);
  }
  spec.hold = {hold};
  spec.hold_position = hold_position_;
  spec.settings = settings_;
  spec.model = model_spec_;
  if (!req.model.empty() || !req.model_options.empty()) {
    try {
      // A request's model starts from its own defaults; its options are added to those of the node's
      // model when it names no model.
      ClothModelSpec requested = req.model.empty() ? model_spec_ : ClothModelSpec(req.model);
      if (!req.model_options.empty())
        for (const auto& [key, value] : parseClothModelSpecText(requested.name + " " + req.model_options).options)
          requested.set(key, value);
      ClothModelRegistry::instance().validate(requested);
      spec.model = requested;
    } catch (const ClothModelError& e) {
      return reject(e.what());
    }
  }
  spec.self_collision = self_collision_;
  spec.collision = collision_;
  spec.obstacles = obstacles_;
  if (!req.integrator.empty()) {
    try {
      spec.settings.integrator = integratorFromString(req.integrator);
    } catch (const std::invalid_argument& e) {
      return reject(e.what());
    }
  }
  try {
    runSimulation(spec, hold.label(), res);
  } catch (const std::bad_alloc&) {
    return reject("out of memory while simulating (lower the resolution: spacing_m)");
  } catch (const std::exception& e) {
    return reject(e.what());
  }
  return true;
}

void DrapeSimulatorNode::runSimulation(const DrapeSceneSpec& spec, const std::string& hold_label,
                                       SimulateDrape::Response& res) {
  // The scene's memory estimate is checked against the budget before anything large is allocated.
  const DrapeScene scene = buildDrapeScene(spec);
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  const RunResult r = sim.run();
  auto& s = res.summary;
  s.textile = spec.textile.name;
  s.hold_point = hold_label;
  s.model = scene.model->name();
  s.integrator = toString(spec.settings.integrator);
  s.spacing_m = spec.spacing;
  s.particles = scene.model->numNodes();
  s.rest_reached = r.rest_reached;
  s.diverged = r.diverged;
  s.divergence_reason = r.divergence_reason;
  s.sim_time_s = r.sim_time;
  s.steps = r.steps;
  s.rejected_steps = r.rejected_steps;
  s.wall_time_s = r.wall_time;
  s.hanging_depth_m = hangingDepth(scene, sim.positions());
  s.self_collision = spec.self_collision ? toString(spec.collision.version) : "off";
  s.collision_events = r.post_step_events;
  s.intersecting_pairs = countIntersectingTrianglePairs(scene.triangles(), sim.positions());
  res.success = !r.diverged;
  res.message = r.diverged ? "simulation diverged: " + r.divergence_reason
                           : (r.rest_reached ? "rest reached" : "time cap reached before rest");
  ROS_INFO_NAMED("drape_simulator", "%s held at %s: %s after %.2f s simulated (%ld steps, %.2f s wall)",
                 s.textile.c_str(), s.hold_point.c_str(), res.message.c_str(), r.sim_time, r.steps, r.wall_time);
}

}  // namespace textile_handling
