#include <ros/ros.h>

#include "textile_recognizer_node.h"

int main(int argc, char** argv) {
  ros::init(argc, argv, "textile_recognizer");
  ros::NodeHandle nh, pnh("~");
  try {
    textile_handling::TextileRecognizerNode node(nh, pnh);
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("textile_recognizer: %s", e.what());
    return 1;
  }
  return 0;
}
