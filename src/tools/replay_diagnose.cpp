// replay_diagnose: runs the recognition core on every colour frame of a recorded cell bag (as the
// textile_recognizer node would, one image at a time) and prints, per frame, the decision (hold point,
// member, view angle, reflection, depth residual, top candidates) and each grasp point's error against
// the bag's ground truth. A debugging tool for the bag-replay tests (docs/recognition.md).
//
//   replay_diagnose BAG TRUTH.yaml DATABASE [--no-depth] [--no-fit] [--no-reflections]
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_msgs/TFMessage.h>
#include <cv_bridge/cv_bridge.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "textile_handling/recognition/textile_recognizer.h"

using namespace textile_handling;

int main(int argc, char** argv) {
  if (argc < 4) {
    std::fprintf(stderr, "usage: replay_diagnose BAG TRUTH.yaml DATABASE [--no-depth] [--no-fit] [--no-reflections]\n");
    return 2;
  }
  bool use_depth = true;
  recognition::RecognizerOptions o;
  for (int i = 4; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-depth") use_depth = false;
    else if (a == "--no-fit") o.shape_fit.enabled = false;
    else if (a == "--no-reflections") o.refinement.consider_reflections = false;
  }
  const YAML::Node truth = YAML::LoadFile(argv[2]);
  std::map<std::string, Vec2> textile_pts;
  for (const auto& kv : truth["named_points_textile"])
    textile_pts[kv.first.as<std::string>()] = Vec2(kv.second[0].as<double>(), kv.second[1].as<double>());
  std::map<std::string, Vec3> gripper_pts;
  for (const auto& kv : truth["views"][0]["named_points_in_gripper"])
    gripper_pts[kv.first.as<std::string>()] =
        Vec3(kv.second[0].as<double>(), kv.second[1].as<double>(), kv.second[2].as<double>());
  const Vec2 hold(truth["hold_xy"][0].as<double>(), truth["hold_xy"][1].as<double>());
  const Vec2 centre(truth["bounding_box_centre"][0].as<double>(), truth["bounding_box_centre"][1].as<double>());

  recognition::TextileRecognizer rec(argv[3], o);
  rosbag::Bag bag(argv[1], rosbag::bagmode::Read);
  Eigen::Isometry3d world_camera = Eigen::Isometry3d::Identity(), world_gripper = Eigen::Isometry3d::Identity();
  sensor_msgs::CameraInfo info;
  sensor_msgs::Image::ConstPtr depth;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
    if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
      for (const auto& t : tf->transforms) {
        if (t.child_frame_id == "camera_optical") world_camera = tf2::transformToEigen(t);
        if (t.child_frame_id == "gripper") world_gripper = tf2::transformToEigen(t);
      }
    } else if (auto ci = m.instantiate<sensor_msgs::CameraInfo>()) {
      info = *ci;
    } else if (auto im = m.instantiate<sensor_msgs::Image>()) {
      if (m.getTopic() == "/camera/depth/image_raw") {
        depth = im;
        continue;
      }
      recognition::CameraObservation obs;
      obs.intrinsics = vision::PinholeIntrinsics{info.K[0], info.K[4], info.K[2], info.K[5], static_cast<int>(info.width),
                                                 static_cast<int>(info.height)};
      obs.image = cv_bridge::toCvCopy(im)->image;
      obs.encoding = im->encoding;
      const Eigen::Isometry3d camera_gripper = world_camera.inverse() * world_gripper;
      obs.hold_camera = camera_gripper.translation();
      obs.up_camera = world_camera.linear().transpose() * Vec3::UnitZ();
      obs.heading_camera = Vec3(camera_gripper.linear() * Vec3::UnitX());
      std::printf("frame t=%.2f:", im->header.stamp.toSec());
      if (use_depth && depth && depth->header.stamp == im->header.stamp) {
        obs.depth = cv_bridge::toCvCopy(depth)->image;
        std::printf(" (depth)");
      }
      try {
        const recognition::RecognitionResult r = rec.recognize(obs);
        std::printf(" hold (%.3f, %.3f) view %.1f rot %.1f score %.3f conf %.3f depth_decided %d reflected %d (refl view %.1f) "
                    "depth residual %.1f mm fit %d moved %.1f mm\n",
                    r.hold_point.x(), r.hold_point.y(), r.view_angle_deg, r.rotation_deg, r.score, r.confidence,
                    (int)r.depth_decided, (int)r.reflected, r.reflection_view_deg, 1e3 * r.depth_residual_m,
                    (int)r.shape_fit.applied, 1e3 * r.shape_fit.max_displacement_m);
        for (const auto& c : r.top_k)
          std::printf("    candidate (%.3f, %.3f) member (%.3f, %.3f) view %.1f score %.3f coarse %.3f refined %d\n",
                      c.canonical_hold.x(), c.canonical_hold.y(), c.hold_point.x(), c.hold_point.y(), c.view_angle_deg,
                      c.score, c.coarse_score, (int)c.refined);
        // Relabel by the mirror that maps the true hold onto the result's (as test_replay_recognition).
        int best_m = 0;
        double best_d = 1e9;
        for (int mi = 0; mi < 4; ++mi) {
          const Vec2 h((mi & 1) ? 2 * centre.x() - hold.x() : hold.x(), (mi & 2) ? 2 * centre.y() - hold.y() : hold.y());
          if ((h - r.hold_point).norm() < best_d) {
            best_d = (h - r.hold_point).norm();
            best_m = mi;
          }
        }
        const Eigen::Isometry3d gripper_camera = camera_gripper.inverse();
        for (const auto& gp : r.grasp_poses) {
          const auto it = textile_pts.find(gp.name);
          if (it == textile_pts.end()) continue;
          const Vec2 q((best_m & 1) ? 2 * centre.x() - it->second.x() : it->second.x(),
                       (best_m & 2) ? 2 * centre.y() - it->second.y() : it->second.y());
          std::string truth_name;
          for (const auto& kv : textile_pts)
            if ((kv.second - q).norm() < 1e-6) truth_name = kv.first;
          const Vec3 p = gripper_camera * gp.position_camera;
          const Vec3 t = gripper_pts.at(truth_name);
          std::printf("    %-22s (truth %-22s) result (%+.3f, %+.3f, %+.3f) truth (%+.3f, %+.3f, %+.3f) error %.3f m\n",
                      gp.name.c_str(), truth_name.c_str(), p.x(), p.y(), p.z(), t.x(), t.y(), t.z(), (p - t).norm());
        }
      } catch (const std::exception& e) {
        std::printf(" error: %s\n", e.what());
      }
    }
  }
  return 0;
}
