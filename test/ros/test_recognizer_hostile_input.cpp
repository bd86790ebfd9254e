// rostest: the textile_recognizer node answers every hostile frame with a published success: false result
// carrying a reason code, and keeps running (docs/ros.md, node textile_recognizer).
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <mutex>
#include <string>
#include <vector>

#include "textile_handling/RecognitionResult.h"

namespace {

class HostileInput : public ::testing::Test {
 protected:
  void SetUp() override {
    image_pub_ = nh_.advertise<sensor_msgs::Image>("/camera/color/image_raw", 1);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>("/camera/color/camera_info", 1);
    sub_ = nh_.subscribe("/textile_recognizer/result", 10, &HostileInput::onResult, this);
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(30);
    while ((image_pub_.getNumSubscribers() == 0 || info_pub_.getNumSubscribers() == 0 || sub_.getNumPublishers() == 0) &&
           ros::WallTime::now() < until)
      ros::WallDuration(0.1).sleep();
    ASSERT_GT(image_pub_.getNumSubscribers(), 0u) << "the recognizer did not subscribe to the image";
  }
  void onResult(const textile_handling::RecognitionResult::ConstPtr& r) {
    std::lock_guard<std::mutex> lock(mutex_);
    results_.push_back(*r);
  }
  static sensor_msgs::Image image(int w, int h, const std::string& encoding, const ros::Time& stamp) {
    sensor_msgs::Image m;
    m.header.stamp = stamp;
    m.header.frame_id = "camera";
    m.width = static_cast<unsigned>(w);
    m.height = static_cast<unsigned>(h);
    m.encoding = encoding;
    m.step = static_cast<unsigned>(w * (encoding == "mono8" ? 1 : encoding == "bgra8" ? 4 : 3));
    m.data.assign(static_cast<std::size_t>(m.step) * h, 0);
    return m;
  }
  static sensor_msgs::CameraInfo info(int w, int h, const ros::Time& stamp) {
    sensor_msgs::CameraInfo c;
    c.header.stamp = stamp;
    c.header.frame_id = "camera";
    c.width = static_cast<unsigned>(w);
    c.height = static_cast<unsigned>(h);
    c.K = {525, 0, w / 2.0 - 0.5, 0, 525, h / 2.0 - 0.5, 0, 0, 1};
    return c;
  }
  // The result for `stamp` (waits up to 10 s; the AsyncSpinner of main() delivers them); success stays
  // true if none arrived.
  textile_handling::RecognitionResult resultFor(const ros::Time& stamp) {
    const ros::WallTime until = ros::WallTime::now() + ros::WallDuration(10);
    while (ros::WallTime::now() < until) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        for (const auto& r : results_)
          if (r.header.stamp == stamp) return r;
      }
      ros::WallDuration(0.05).sleep();
    }
    textile_handling::RecognitionResult none;
    none.success = true;
    none.reason_code = "no result published";
    return none;
  }

  ros::NodeHandle nh_;
  ros::Publisher image_pub_, info_pub_;
  ros::Subscriber sub_;
  std::mutex mutex_;
  std::vector<textile_handling::RecognitionResult> results_;
};

TEST_F(HostileInput, EveryHostileFrameIsAnsweredAndTheNodeKeepsRunning) {
  ros::Time stamp(100, 0);
  auto expect = [&](const std::string& code) {
    const textile_handling::RecognitionResult r = resultFor(stamp);
    EXPECT_FALSE(r.success) << code;
    EXPECT_EQ(r.reason_code, code) << r.message;
    EXPECT_FALSE(r.message.empty());
    stamp += ros::Duration(1.0);
  };
  image_pub_.publish(image(64, 48, "bgr8", stamp));  // no camera_info at all
  expect("missing_camera_info");
  info_pub_.publish(info(64, 48, stamp));
  ros::WallDuration(0.2).sleep();
  image_pub_.publish(image(64, 48, "bgra8", stamp));
  expect("unsupported_encoding");
  info_pub_.publish(info(400, 300, stamp));
  ros::WallDuration(0.2).sleep();
  image_pub_.publish(image(400, 300, "bgr8", stamp));  // above the test's max_image_pixels (100000)
  expect("image_too_large");
  image_pub_.publish(image(64, 48, "mono8", stamp));  // still running: answered again
  expect("missing_camera_info");
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_recognizer_hostile_input");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  return RUN_ALL_TESTS();
}
