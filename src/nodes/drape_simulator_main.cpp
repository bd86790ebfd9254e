#include <ros/ros.h>

#include "drape_simulator_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "drape_simulator");
  ros::NodeHandle nh, pnh("~");
  try {
    textile_handling::DrapeSimulatorNode node(nh, pnh);
    // simulate_drape runs its simulation in the callback (bounded by max_sim_time_s and the memory
    // budget); four threads keep list_textiles and the other services answering while two such calls
    // and a registration's validation run.
    ros::AsyncSpinner spinner(4);
    spinner.start();
    ros::waitForShutdown();
  } catch (const std::exception& e) {
    ROS_FATAL("drape_simulator: %s", e.what());
    return 1;
  }
  return 0;
}
