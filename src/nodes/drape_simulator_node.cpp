#include "drape_simulator_node.h"

#include <cmath>
#include <stdexcept>

namespace textile_handling {

namespace {

Real positiveParam(ros::NodeHandle& nh, const std::string& name, Real fallback) {
  Real v = fallback;
  nh.param(name, v, fallback);
  if (!std::isfinite(v) || !(v > 0))
    throw std::runtime_error("parameter ~" + name + " must be a finite positive number");
  return v;
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
  double damping = model_options_.settle_damping;
  pnh.param("settle_damping_per_s", damping, damping);
  if (!std::isfinite(damping) || damping < 0)
    throw std::runtime_error("parameter ~settle_damping_per_s must be finite and >= 0");
  model_options_.settle_damping = damping;
  std::vector<double> hold;
  if (pnh.getParam("hold_position_m", hold)) {
    if (hold.size() != 3 || !std::isfinite(hold[0]) || !std::isfinite(hold[1]) || !std::isfinite(hold[2]))
      throw std::runtime_error("parameter ~hold_position_m must be a list of three finite numbers");
    hold_position_ = Vec3(hold[0], hold[1], hold[2]);
  }
  simulate_service_ = pnh.advertiseService("simulate_drape", &DrapeSimulatorNode::simulateDrape, this);
  (void)nh;
  ROS_INFO_NAMED("drape_simulator", "ready: default spacing %.3f m, integrator %s", default_spacing_,
                 default_integrator_.c_str());
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
  spec.model_options = model_options_;
  if (!req.integrator.empty()) {
    try {
      spec.settings.integrator = integratorFromString(req.integrator);
    } catch (const std::invalid_argument& e) {
      return reject(e.what());
    }
  }
  DrapeScene scene;
  try {
    scene = buildDrapeScene(spec);
  } catch (const std::exception& e) {
    return reject(e.what());
  }
  DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
  const RunResult r = sim.run();
  auto& s = res.summary;
  s.textile = spec.textile.name;
  s.hold_point = hold.label();
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
  res.success = !r.diverged;
  res.message = r.diverged ? "simulation diverged: " + r.divergence_reason
                           : (r.rest_reached ? "rest reached" : "time cap reached before rest");
  ROS_INFO_NAMED("drape_simulator", "%s held at %s: %s after %.2f s simulated (%ld steps, %.2f s wall)",
                 s.textile.c_str(), s.hold_point.c_str(), res.message.c_str(), r.sim_time, r.steps, r.wall_time);
  return true;
}

}  // namespace textile_handling
