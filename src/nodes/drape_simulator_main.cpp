#include <ros/ros.h>

#include "drape_simulator_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "drape_simulator");
  ros::NodeHandle nh, pnh("~");
  try {
    textile_handling::DrapeSimulatorNode node(nh, pnh);
    ros::AsyncSpinner spinner(2);  // a long simulation does not block other service calls
    spinner.start();
    ros::waitForShutdown();
  } catch (const std::exception& e) {
    ROS_FATAL("drape_simulator: %s", e.what());
    return 1;
  }
  return 0;
}
