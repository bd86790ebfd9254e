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

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "textile_handling/db/textile_symmetry.h"
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
  // The bag's textile is mirror-symmetric about its bounding-box centre (the towel).
  db::TextileSymmetry symmetry;
  symmetry.mirror_x = symmetry.mirror_y = true;
  symmetry.cx = truth["bounding_box_centre"][0].as<double>();
  symmetry.cy = truth["bounding_box_centre"][1].as<double>();

  recognition::TextileRecognizer rec(argv[3], o);
  // Messages of one stamp (tf, camera_info, colour, depth) are gathered first: rosbag orders messages of
  // equal stamps arbitrarily, and a colour frame must be judged with its own tf and depth.
  struct Frame {
    bool has_gripper = false;
    Eigen::Isometry3d world_gripper = Eigen::Isometry3d::Identity();
    sensor_msgs::CameraInfo info;
    sensor_msgs::Image::ConstPtr colour, depth;
  };
  std::map<ros::Time, Frame> frames;
  Eigen::Isometry3d world_camera = Eigen::Isometry3d::Identity();
  {
    rosbag::Bag bag(argv[1], rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& m : rosbag::View(bag)) {
      if (auto tf = m.instantiate<tf2_msgs::TFMessage>()) {
        for (const auto& t : tf->transforms) {
          if (t.child_frame_id == "camera_optical") world_camera = tf2::transformToEigen(t);
          if (t.child_frame_id == "gripper") {
            Frame& f = frames[t.header.stamp];
            f.world_gripper = tf2::transformToEigen(t);
            f.has_gripper = true;
          }
        }
      } else if (auto ci = m.instantiate<sensor_msgs::CameraInfo>()) {
        frames[ci->header.stamp].info = *ci;
      } else if (auto im = m.instantiate<sensor_msgs::Image>()) {
        (m.getTopic() == "/camera/depth/image_raw" ? frames[im->header.stamp].depth : frames[im->header.stamp].colour) = im;
      }
    }
  }
  struct Past {
    double yaw_deg;
    recognition::CameraObservation obs;
  };
  std::vector<Past> history;
  auto report = [&](const char* what, const recognition::RecognitionResult& r, const Eigen::Isometry3d& camera_gripper) {
    std::printf(" %s hold (%.3f, %.3f) view %.1f rot %.1f score %.3f coverage %.3f colour %.3f conf %.3f depth_decided %d reflected %d "
                "(refl view %.1f) depth residual %.1f mm fit %d moved %.1f mm\n",
                what, r.hold_point.x(), r.hold_point.y(), r.view_angle_deg, r.rotation_deg, r.score, r.coverage, r.colour_fraction, r.confidence,
                (int)r.depth_decided, (int)r.reflected, r.reflection_view_deg, 1e3 * r.depth_residual_m,
                (int)r.shape_fit.applied, 1e3 * r.shape_fit.max_displacement_m);
    for (const auto& c : r.top_k)
      std::printf("    candidate (%.3f, %.3f) member (%.3f, %.3f) view %.1f score %.3f coarse %.3f refined %d\n",
                  c.canonical_hold.x(), c.canonical_hold.y(), c.hold_point.x(), c.hold_point.y(), c.view_angle_deg,
                  c.score, c.coarse_score, (int)c.refined);
    // Relabel by a mirror that maps the true hold onto the result's (as test_replay_recognition): of the
    // mirrors equally close (a hold point on a symmetry axis leaves the names open), the best fitting.
    double hold_distance[4];
    for (int mi = 0; mi < 4; ++mi)
      hold_distance[mi] = (symmetry.apply(static_cast<db::MirrorKind>(mi), hold) - r.hold_point).norm();
    const double best_d = *std::min_element(hold_distance, hold_distance + 4);
    const Eigen::Isometry3d gripper_camera = camera_gripper.inverse();
    double best_worst = 1e9;
    std::string best_lines;
    for (int mi = 0; mi < 4; ++mi) {
      if (hold_distance[mi] > best_d + 1e-6) continue;
      double worst = 0;
      std::string lines;
      for (const auto& gp : r.grasp_poses) {
        const auto it = textile_pts.find(gp.name);
        if (it == textile_pts.end()) continue;
        const Vec2 q = symmetry.apply(static_cast<db::MirrorKind>(mi), it->second);
        std::string truth_name;
        for (const auto& kv : textile_pts)
          if ((kv.second - q).norm() < 1e-6) truth_name = kv.first;
        const Vec3 p = gripper_camera * gp.position_camera;
        const Vec3 t = gripper_pts.at(truth_name);
        worst = std::max(worst, (p - t).norm());
        char buf[256];
        std::snprintf(buf, sizeof(buf), "    %-22s (truth %-22s) result (%+.3f, %+.3f, %+.3f) truth (%+.3f, %+.3f, %+.3f) error %.3f m\n",
                      gp.name.c_str(), truth_name.c_str(), p.x(), p.y(), p.z(), t.x(), t.y(), t.z(), (p - t).norm());
        lines += buf;
      }
      if (worst < best_worst) {
        best_worst = worst;
        best_lines = lines;
      }
    }
    std::printf("%s    largest grasp-point error %.3f m\n", best_lines.c_str(), best_worst);
  };
  for (const auto& [stamp, f] : frames) {
    if (!f.colour) continue;
    if (!f.has_gripper) {
      std::printf("frame t=%.2f: no gripper tf at this stamp, skipped\n", stamp.toSec());
      continue;
    }
    recognition::CameraObservation obs;
    obs.intrinsics = vision::PinholeIntrinsics{f.info.K[0], f.info.K[4], f.info.K[2], f.info.K[5],
                                               static_cast<int>(f.info.width), static_cast<int>(f.info.height)};
    obs.image = cv_bridge::toCvCopy(f.colour)->image;
    obs.encoding = f.colour->encoding;
    const Eigen::Isometry3d camera_gripper = world_camera.inverse() * f.world_gripper;
    obs.hold_camera = camera_gripper.translation();
    obs.up_camera = world_camera.linear().transpose() * Vec3::UnitZ();
    obs.heading_camera = Vec3(camera_gripper.linear() * Vec3::UnitX());
    const Vec3 gx = f.world_gripper.linear() * Vec3::UnitX();
    const double yaw = std::atan2(gx.y(), gx.x()) * 180.0 / M_PI;
    if (use_depth && f.depth) obs.depth = cv_bridge::toCvCopy(f.depth)->image;
    std::printf("frame t=%.2f (gripper yaw %.1f deg%s):\n", stamp.toSec(), yaw, obs.depth.empty() ? "" : ", depth");
    try {
      report("single:", rec.recognize(obs), camera_gripper);
    } catch (const std::exception& e) {
      std::printf(" single: error: %s\n", e.what());
    }
    // Fusion as the node does it with its default parameters (config/textile_recognizer.yaml: two
    // views at least 20 degrees apart).
    std::vector<double> earlier_yaws;  // newest first
    for (auto it = history.rbegin(); it != history.rend(); ++it) earlier_yaws.push_back(it->yaw_deg);
    const std::vector<std::size_t> partners = recognition::chooseFusionPartners(yaw, earlier_yaws, 2, 20.0);
    if (!partners.empty()) {
      const Past& partner = history[history.size() - 1 - partners.front()];
      try {
        report("fused: ", rec.recognize(std::vector<recognition::CameraObservation>{obs, partner.obs}), camera_gripper);
      } catch (const std::exception& e) {
        std::printf(" fused: error: %s\n", e.what());
      }
    }
    history.push_back(Past{yaw, obs});
  }
  return 0;
}
