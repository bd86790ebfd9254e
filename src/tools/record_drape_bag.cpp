// record_drape_bag: writes a rosbag of a simulated cell scene — a textile hanging from a gripper that
// turns in front of a fixed camera — with the topics a real cell records, plus a ground-truth YAML.
//
//   record_drape_bag SCENE.yaml --out BAG [--yaw DEG,DEG,...] [--frames-per-view N] [--period S]
//                    [--camera-distance M] [--camera-height M] [--depth] [--noise SIGMA] [--seed N]
//                    [--truth FILE.yaml] [--width PX] [--compress]
//
// The scene (docs/simulation.md) is simulated to rest first. Frames (z up, metres):
//   world -> camera_optical   static (/tf_static): camera at (0, -distance, hold_z + height) looking
//                             horizontally along +y (optical frame: x right, y down, z forward);
//   world -> gripper          (/tf, every frame): at the hold position, turned by the yaw of the view.
// The textile's rest shape turns with the gripper; in the database's convention a gripper yaw psi is
// the view azimuth -psi (docs/vision.md). Topics: /camera/color/image_raw (bgr8),
// /camera/color/camera_info, and with --depth /camera/depth/image_raw (32FC1, metres, NaN = no return)
// + /camera/depth/camera_info. The truth file lists, per view, the stamp range, the gripper yaw, the
// hold point and every named point of the textile in the gripper frame.
#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/TransformStamped.h>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;

namespace {

int usage() {
  std::cerr << "usage: record_drape_bag SCENE.yaml --out BAG [--yaw DEG,...] [--frames-per-view N] [--period S]\n"
               "       [--camera-distance M] [--camera-height M] [--depth] [--noise SIGMA] [--seed N] [--truth FILE]\n"
               "       [--width PX] [--compress]\n";
  return 2;
}

std::vector<double> parseList(const std::string& s) {
  std::vector<double> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    char* end = nullptr;
    const double v = std::strtod(item.c_str(), &end);
    if (end == item.c_str() || *end != '\0' || !std::isfinite(v)) throw std::invalid_argument("bad number '" + item + "'");
    out.push_back(v);
  }
  if (out.empty()) throw std::invalid_argument("empty list");
  return out;
}

geometry_msgs::TransformStamped transform(const std::string& parent, const std::string& child, const Vec3& t,
                                          const Eigen::Quaternion<Real>& q, const ros::Time& stamp) {
  geometry_msgs::TransformStamped m;
  m.header.frame_id = parent;
  m.header.stamp = stamp;
  m.child_frame_id = child;
  m.transform.translation.x = t.x();
  m.transform.translation.y = t.y();
  m.transform.translation.z = t.z();
  m.transform.rotation.x = q.x();
  m.transform.rotation.y = q.y();
  m.transform.rotation.z = q.z();
  m.transform.rotation.w = q.w();
  return m;
}

sensor_msgs::CameraInfo cameraInfo(const vision::PinholeIntrinsics& k, const std::string& frame, const ros::Time& stamp) {
  sensor_msgs::CameraInfo ci;
  ci.header.frame_id = frame;
  ci.header.stamp = stamp;
  ci.width = static_cast<unsigned>(k.width);
  ci.height = static_cast<unsigned>(k.height);
  ci.distortion_model = "plumb_bob";
  ci.D = {0, 0, 0, 0, 0};
  ci.K = {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
  ci.R = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  ci.P = {k.fx, 0, k.cx, 0, 0, k.fy, k.cy, 0, 0, 0, 1, 0};
  return ci;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  std::string scene_path = argv[1], bag_path, truth_path;
  std::vector<double> yaws = {0.0, 90.0};
  int frames_per_view = 3, seed = 1;
  double period = 0.2, distance = 1.5, height = -0.3, noise = 2.0;
  bool depth = false, compress = false;
  int width = 640;
  try {
    for (int i = 2; i < argc; ++i) {
      const std::string a = argv[i];
      auto next = [&]() -> std::string {
        if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
        return argv[++i];
      };
      if (a == "--out") bag_path = next();
      else if (a == "--truth") truth_path = next();
      else if (a == "--yaw") yaws = parseList(next());
      else if (a == "--frames-per-view") frames_per_view = std::stoi(next());
      else if (a == "--period") period = std::stod(next());
      else if (a == "--camera-distance") distance = std::stod(next());
      else if (a == "--camera-height") height = std::stod(next());
      else if (a == "--noise") noise = std::stod(next());
      else if (a == "--seed") seed = std::stoi(next());
      else if (a == "--depth") depth = true;
      else if (a == "--compress") compress = true;
      else if (a == "--width") width = std::stoi(next());
      else return usage();
    }
    if (bag_path.empty()) return usage();
    if (width < 64 || width > 4096) throw std::invalid_argument("--width must be in [64, 4096]");
    if (frames_per_view < 1 || !(period > 0) || !(distance > 0) || !std::isfinite(height) || !(noise >= 0))
      throw std::invalid_argument("frames-per-view, period, camera distance must be positive, noise >= 0");
  } catch (const std::exception& e) {
    std::cerr << "record_drape_bag: " << e.what() << "\n";
    return 2;
  }
  if (truth_path.empty()) truth_path = bag_path + ".truth.yaml";

  DrapeScene scene;
  try {
    scene = buildDrapeScene(loadDrapeSceneYaml(scene_path));
  } catch (const std::exception& e) {
    std::cerr << "record_drape_bag: " << e.what() << "\n";
    return 2;
  }
  DrapeSimulation sim(*scene.model, scene.pins, scene.spec.settings, scene.x0, scene.v0);
  sim.setPostStepPass(scene.postStepPass());
  const RunResult r = sim.run();
  std::cout << "simulated " << scene.spec.textile.name << " held at " << scene.spec.hold.front().label() << ": "
            << (r.rest_reached ? "rest" : (r.diverged ? "DIVERGED" : "time cap")) << " after " << r.sim_time << " s ("
            << r.wall_time << " s wall)\n";
  if (r.diverged) {
    std::cerr << "record_drape_bag: simulation diverged: " << r.divergence_reason << "\n";
    return 3;
  }
  const VecX& x = sim.positions();
  const Index n = scene.model->numNodes();
  const Vec3 hold = node3(x, scene.hold_particle);
  const auto triangles = vision::trianglesFromTopology(ParticleTopology::fromGrid(scene.grid));

  vision::ShadedRenderOptions ro;
  {
    // A 640 x 480, f = 525 px camera, scaled to the requested width (same field of view).
    const double s = width / 640.0;
    ro.intrinsics.fx = ro.intrinsics.fy = 525.0 * s;
    ro.intrinsics.width = width;
    ro.intrinsics.height = static_cast<int>(std::lround(480 * s));
    ro.intrinsics.cx = (ro.intrinsics.width - 1) / 2.0;
    ro.intrinsics.cy = (ro.intrinsics.height - 1) / 2.0;
  }
  ro.noise_sigma = noise;
  ro.render_depth = depth;
  ro.render_mask = false;
  // Camera: looks along +y at the hold axis; optical axis horizontal.
  const Vec3 cam_pos(hold.x(), hold.y() - distance, hold.z() + height);
  Mat3 cam_rot;  // columns: optical x (right) = +x, y (down) = -z, z (forward) = +y, in world
  cam_rot.col(0) = Vec3::UnitX();
  cam_rot.col(1) = -Vec3::UnitZ();
  cam_rot.col(2) = Vec3::UnitY();
  ro.camera.rotation = cam_rot;
  ro.camera.position = cam_pos;

  rosbag::Bag bag;
  try {
    bag.open(bag_path, rosbag::bagmode::Write);
    if (compress) bag.setCompression(rosbag::compression::BZ2);
  } catch (const std::exception& e) {
    std::cerr << "record_drape_bag: cannot write " << bag_path << ": " << e.what() << "\n";
    return 2;
  }
  const ros::Time t0(1.0);
  tf2_msgs::TFMessage statics;
  statics.transforms.push_back(
      transform("world", "camera_optical", cam_pos, Eigen::Quaternion<Real>(cam_rot), t0));
  bag.write("/tf_static", t0, statics);

  std::ofstream truth(truth_path);
  truth.precision(9);
  truth << "# Ground truth of " << bag_path << " (written by record_drape_bag)\n"
        << "textile: " << scene.spec.textile.name << "\n"
        << "hold_point: \"" << scene.spec.hold.front().label() << "\"\n";
  const Vec2 hold_xy = scene.grid.activePosition(scene.hold_particle);
  truth << "hold_xy: [" << hold_xy.x() << ", " << hold_xy.y() << "]\n"
        << "spacing_m: " << scene.spec.spacing << "\n"
        << "camera_frame: camera_optical\ngripper_frame: gripper\nworld_frame: world\n";
  // The textile's named points (textile frame) and its bounding-box centre (the mirror axes of a
  // symmetric textile), so tests can relabel poses of a mirror-equivalent hold point.
  {
    const std::vector<Vec2> full = fullOutline(scene.spec.textile);
    Vec2 lo = full.front(), hi = full.front();
    for (const Vec2& v : full) {
      lo = lo.cwiseMin(v);
      hi = hi.cwiseMax(v);
    }
    truth << "bounding_box_centre: [" << 0.5 * (lo.x() + hi.x()) << ", " << 0.5 * (lo.y() + hi.y()) << "]\n"
          << "named_points_textile:\n";
    for (const auto& np : scene.spec.textile.named_points)
      truth << "  " << np.name << ": [" << np.position.x() << ", " << np.position.y() << "]\n";
  }
  truth << "views:\n";
  int seq = 0;
  for (size_t v = 0; v < yaws.size(); ++v) {
    const Real psi = yaws[v] * M_PI / 180.0;
    const Eigen::AngleAxis<Real> rz(psi, Vec3::UnitZ());
    VecX xw(3 * n);
    for (Index k = 0; k < n; ++k) xw.segment<3>(3 * k) = hold + rz * (node3(x, k) - hold);
    const ros::Time first = t0 + ros::Duration(period * (seq + 1));
    truth << "  - gripper_yaw_deg: " << yaws[v] << "\n"
          << "    view_azimuth_deg: " << -yaws[v] << "\n"
          << "    stamp_first: " << first.toSec() << "\n";
    for (int f = 0; f < frames_per_view; ++f, ++seq) {
      const ros::Time stamp = t0 + ros::Duration(period * (seq + 1));
      ro.seed = static_cast<std::uint64_t>(seed * 1000 + seq);
      const vision::ShadedImage img = vision::renderShaded(xw, triangles, ro);
      tf2_msgs::TFMessage tf;
      tf.transforms.push_back(transform("world", "gripper", hold, Eigen::Quaternion<Real>(rz), stamp));
      bag.write("/tf", stamp, tf);
      std_msgs::Header h;
      h.stamp = stamp;
      h.frame_id = "camera_optical";
      h.seq = static_cast<unsigned>(seq);
      bag.write("/camera/color/image_raw", stamp, cv_bridge::CvImage(h, "bgr8", img.bgr).toImageMsg());
      bag.write("/camera/color/camera_info", stamp, cameraInfo(ro.intrinsics, "camera_optical", stamp));
      if (depth) {
        bag.write("/camera/depth/image_raw", stamp, cv_bridge::CvImage(h, "32FC1", img.depth).toImageMsg());
        bag.write("/camera/depth/camera_info", stamp, cameraInfo(ro.intrinsics, "camera_optical", stamp));
      }
    }
    truth << "    stamp_last: " << (t0 + ros::Duration(period * seq)).toSec() << "\n"
          << "    named_points_in_gripper:\n";
    for (const auto& np : scene.named_particles) {
      const Vec3 p = node3(x, np.second) - hold;  // gripper frame = sim frame at yaw 0, origin at the hold
      truth << "      " << np.first << ": [" << p.x() << ", " << p.y() << ", " << p.z() << "]\n";
    }
  }
  bag.close();
  std::cout << "wrote " << bag_path << " (" << seq << " frames, " << yaws.size() << " views) and " << truth_path << "\n";
  return 0;
}
