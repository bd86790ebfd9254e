// ROS node class hosting the drape simulator. Thin: reads its parameters once (private namespace,
// config/drape_simulator.yaml), validates requests at the boundary, and calls the ROS-free core.
#pragma once

#include <ros/ros.h>

#include <string>

#include "textile_handling/SimulateDrape.h"
#include "textile_handling/sim/drape_scene.h"

namespace textile_handling {

class DrapeSimulatorNode {
 public:
  /// Reads all parameters; throws std::runtime_error naming the parameter if one is invalid.
  DrapeSimulatorNode(ros::NodeHandle& nh, ros::NodeHandle& private_nh);

 private:
  bool simulateDrape(SimulateDrape::Request& req, SimulateDrape::Response& res);

  ros::ServiceServer simulate_service_;
  Real default_spacing_ = 0.02;
  std::string default_integrator_ = "semi_implicit";
  SimulationSettings settings_;
  ParticleModelOptions model_options_;
  Vec3 hold_position_ = Vec3(0, 0, 1.0);
};

}  // namespace textile_handling
