// ROS node class hosting the drape simulator and the database builder. Thin: reads its parameters
// once (private namespace, config/drape_simulator.yaml), validates requests at the boundary, converts
// messages and calls the ROS-free cores (TextileRegistry, DrapeSimulation). Long work (database
// builds) runs on the registry's worker thread, never in a service callback. docs/ros.md.
#pragma once

#include <ros/ros.h>

#include <memory>
#include <string>

#include "textile_handling/ListTextiles.h"
#include "textile_handling/PublishRestShape.h"
#include "textile_handling/RegisterTextile.h"
#include "textile_handling/Resimulate.h"
#include "textile_handling/SimulateDrape.h"
#include "textile_handling/registry/textile_registry.h"
#include "textile_handling/sim/drape_scene.h"

namespace textile_handling {

class DrapeSimulatorNode {
 public:
  /// Reads all parameters, opens the database; throws std::runtime_error naming the parameter (or the
  /// database problem) if one is invalid.
  DrapeSimulatorNode(ros::NodeHandle& nh, ros::NodeHandle& private_nh);

 private:
  bool simulateDrape(SimulateDrape::Request& req, SimulateDrape::Response& res);
  /// Builds and runs one scene and fills the response; throws on bad input or allocation failure.
  void runSimulation(const DrapeSceneSpec& spec, const std::string& hold_label, SimulateDrape::Response& res);
  bool registerTextile(RegisterTextile::Request& req, RegisterTextile::Response& res);
  bool resimulate(Resimulate::Request& req, Resimulate::Response& res);
  bool listTextiles(ListTextiles::Request& req, ListTextiles::Response& res);
  bool publishRestShape(PublishRestShape::Request& req, PublishRestShape::Response& res);
  void publishProgress(const registry::BuildProgressEvent& e);
  void publishChanged(std::int64_t textile_id);

  ros::ServiceServer simulate_service_, register_service_, resimulate_service_, list_service_, markers_service_;
  ros::Publisher progress_pub_, changed_pub_, markers_pub_;
  Real default_spacing_ = 0.02;
  std::string default_integrator_ = "semi_implicit";
  SimulationSettings settings_;
  ClothModelSpec model_spec_;  ///< simulate_drape's model and options (~model, ~model_options, ~settle_damping_per_s)
  Vec3 hold_position_ = Vec3(0, 0, 1.0);
  bool self_collision_ = true;
  SelfCollisionOptions collision_;
  ObstacleSpec obstacles_;
  std::string hold_frame_ = "gripper";
  std::unique_ptr<registry::TextileRegistry> registry_;
};

}  // namespace textile_handling
