// ROS node class of the textile recognizer. Thin: reads its parameters once (private namespace,
// config/textile_recognizer.yaml), converts images, camera_info, depth and tf at the edge, and calls
// the ROS-free recognition core (recognition::TextileRecognizer) on a worker thread. Frames that
// arrive while the worker is busy are dropped; callbacks never wait for recognition. docs/ros.md.
#pragma once

#include <image_transport/camera_common.h>
#include <image_transport/image_transport.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>

#include <atomic>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <utility>

#include "textile_handling/DatabaseChanged.h"
#include "textile_handling/recognition/textile_recognizer.h"

namespace textile_handling {

class TextileRecognizerNode {
 public:
  /// Reads all parameters and opens the database; throws std::runtime_error naming the bad parameter.
  TextileRecognizerNode(ros::NodeHandle& nh, ros::NodeHandle& private_nh);
  ~TextileRecognizerNode();

 private:
  struct Frame {
    sensor_msgs::ImageConstPtr image;
    sensor_msgs::CameraInfoConstPtr info;
    sensor_msgs::ImageConstPtr depth;
  };

  void imageCallback(const sensor_msgs::ImageConstPtr& image);
  void infoCallback(const sensor_msgs::CameraInfoConstPtr& info);
  sensor_msgs::CameraInfoConstPtr matchingInfo(const ros::Time& stamp) const;  // mutex_ held
  void depthCallback(const sensor_msgs::ImageConstPtr& depth);
  void databaseChanged(const DatabaseChanged::ConstPtr& msg);
  /// Until stop_: waits for database changes (DatabaseChangeWatcher) and requests reloads.
  void watchDatabase(const std::string& db_path);
  void workerLoop();
  void process(const Frame& frame);
  void publishFailure(const std_msgs::Header& header, const std::string& code, const std::string& why);
  void logSkippedViews() const;
  /// Refuses an image before conversion: pixel limit, encoding (reason code, message; empty if fine).
  std::pair<std::string, std::string> checkImageMessage(const sensor_msgs::Image& image) const;

  ros::NodeHandle nh_, pnh_;
  image_transport::ImageTransport it_;
  image_transport::Subscriber image_sub_;
  ros::Subscriber info_sub_, depth_sub_, changed_sub_;
  ros::Publisher result_pub_, poses_pub_, safe_poses_pub_;
  image_transport::Publisher debug_pub_;
  tf2_ros::Buffer tf_buffer_;
  tf2_ros::TransformListener tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;

  std::string gripper_frame_ = "gripper";
  std::string up_frame_ = "world";
  std::string grasp_frame_prefix_ = "grasp/";
  std::string safe_grasp_frame_prefix_ = "safe_grasp/";
  double tf_timeout_s_ = 0.2;
  double depth_max_age_s_ = 0.05;
  double depth_wait_s_ = 0.5;   // wall time the worker waits for a frame's depth image
  bool use_depth_ = false;
  // camera_info is paired with an image by stamp (within camera_info_max_age_s); the worker waits up to
  // camera_info_wait_s for one that arrives after its image, then answers success: false.
  double camera_info_wait_s_ = 0.2;
  double camera_info_max_age_s_ = 0.0;
  std::int64_t max_image_pixels_ = 25'000'000;
  // Multi-image fusion (thesis: two images): earlier observations of the same hold, kept while the
  // gripper turns; a new frame is fused with up to fusion_views - 1 of them whose view azimuth differs by
  // at least fusion_min_separation_deg.
  int fusion_views_ = 2;
  double fusion_window_s_ = 20.0;
  double fusion_min_separation_deg_ = 20.0;
  struct Past {
    ros::Time stamp;
    double gripper_yaw_deg = 0;  // heading of the gripper about the up axis, in the up frame
    recognition::CameraObservation observation;
  };
  std::deque<Past> history_;  // worker thread only
  std::unique_ptr<recognition::TextileRecognizer> recognizer_;

  std::mutex mutex_;
  std::condition_variable cv_;
  bool has_frame_ = false, stop_ = false;
  Frame pending_;
  sensor_msgs::ImageConstPtr last_depth_;
  std::deque<sensor_msgs::CameraInfoConstPtr> infos_;  // newest last, at most kInfoHistory
  std::atomic<bool> busy_{false}, reload_requested_{false};
  std::atomic<long> dropped_{0};
  std::thread worker_;
  std::thread watcher_;  // watchDatabase(): sets reload_requested_ when the database changed
};

}  // namespace textile_handling
