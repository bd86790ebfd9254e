#include "textile_recognizer_node.h"

#include <cv_bridge/cv_bridge.h>
#include <geometry_msgs/PoseArray.h>
#include <tf2_eigen/tf2_eigen.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include "node_paths.h"
#include "textile_handling/RecognitionResult.h"
#include "textile_handling/db/database_change_watcher.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {

namespace {

double finiteParam(ros::NodeHandle& nh, const std::string& name, double fallback, double lo) {
  double v = fallback;
  nh.param(name, v, fallback);
  if (!std::isfinite(v) || v < lo)
    throw std::runtime_error("parameter ~" + name + " must be a finite number >= " + std::to_string(lo));
  return v;
}

// A segmentation enum parameter parsed by the core's parser (segmentation.h); a bad value names the parameter.
template <typename Parse>
auto enumParam(const std::string& name, const std::string& value, Parse parse) {
  try {
    return parse(value);
  } catch (const recognition::RecognitionError& e) {
    throw std::runtime_error("parameter ~" + name + ": " + e.what());
  }
}

// The result message (grasp poses in the gripper frame, `header`'s frame) and the grasp frames for tf,
// from a core result; images_fused and processing_ms are left to the caller.
RecognitionResult resultMessage(const recognition::RecognitionResult& res, const std_msgs::Header& header,
                                const Eigen::Isometry3d& gripper_camera, const std::string& grasp_frame_prefix,
                                const std::string& safe_grasp_frame_prefix,
                                std::vector<geometry_msgs::TransformStamped>* frames) {
  RecognitionResult out;
  out.header = header;
  out.success = true;
  out.textile_id = res.textile_id;
  out.textile_name = res.textile_name;
  out.hold_x = res.hold_point.x();
  out.hold_y = res.hold_point.y();
  out.lattice_i = res.lattice_i;
  out.lattice_j = res.lattice_j;
  for (const Vec2& e : res.equivalent_hold_points) {
    out.equivalent_hold_x.push_back(e.x());
    out.equivalent_hold_y.push_back(e.y());
  }
  out.view_angle_deg = res.view_angle_deg;
  out.score = res.score;
  out.coverage = res.coverage;
  out.image_coverage = res.image_coverage;
  out.contradicting_images = res.contradicting_images;
  out.answer_images = res.answer_images;
  out.skipped_views = static_cast<int>(res.skipped_views);
  out.warnings = res.warnings;
  out.confidence = res.confidence;
  out.front_back_ambiguous = res.front_back_ambiguous;
  out.depth_used = res.depth_used;
  for (const auto& c : res.top_k) {
    RecognitionCandidate rc;
    rc.textile_id = c.textile_id;
    rc.textile_name = c.textile_name;
    rc.hold_x = c.hold_point.x();
    rc.hold_y = c.hold_point.y();
    rc.lattice_i = c.lattice_i;
    rc.lattice_j = c.lattice_j;
    rc.view_angle_deg = c.view_angle_deg;
    rc.score = c.score;
    out.top_k.push_back(rc);
  }
  out.grasp_poses.header = out.header;
  out.safe_grasp_poses.header = out.header;
  for (const auto& g : res.grasp_poses) {
    Eigen::Isometry3d pose_camera = Eigen::Isometry3d::Identity();
    pose_camera.linear() = g.rotation_camera;
    pose_camera.translation() = g.position_camera;
    const Eigen::Isometry3d pose_gripper = gripper_camera * pose_camera;
    out.grasp_names.push_back(g.name);
    out.grasp_kinds.push_back(g.kind);
    out.grasp_observed.push_back(g.observation.observed());
    out.grasp_observed_images.push_back(g.observation.images_observed);
    out.grasp_depth_gap_m.push_back(g.observation.depth_gap_m);
    out.grasp_evidence.push_back(recognition::toString(g.evidence));
    out.grasp_uncertainty_m.push_back(g.uncertainty_m);
    out.grasp_safe.push_back(g.safe);
    const geometry_msgs::Pose pose = tf2::toMsg(Eigen::Affine3d(pose_gripper.matrix()));
    out.grasp_poses.poses.push_back(pose);
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(pose_gripper);
    t.header = out.header;
    t.child_frame_id = grasp_frame_prefix + g.name;
    frames->push_back(t);
    if (g.safe) {  // the safe points again, under their own prefix: a robot can listen to these only
      out.safe_grasp_poses.poses.push_back(pose);
      out.safe_grasp_names.push_back(g.name);
      t.child_frame_id = safe_grasp_frame_prefix + g.name;
      frames->push_back(t);
    }
  }
  return out;
}

constexpr std::size_t kInfoHistory = 16;  // camera_info messages kept for pairing with images by stamp

// Image encodings the recognizer takes (colour or mono; CameraObservation).
bool supportedEncoding(const std::string& e) { return e == "bgr8" || e == "rgb8" || e == "mono8"; }

}  // namespace

TextileRecognizerNode::TextileRecognizerNode(ros::NodeHandle& nh, ros::NodeHandle& pnh)
    : nh_(nh), pnh_(pnh), it_(nh), tf_listener_(tf_buffer_) {
  std::string db_path = "~/.ros/textile_handling/drapes.sqlite";
  pnh.param<std::string>("database_path", db_path, db_path);
  db_path = expandHome(db_path);
  pnh.param<std::string>("gripper_frame", gripper_frame_, gripper_frame_);
  pnh.param<std::string>("up_frame", up_frame_, up_frame_);
  pnh.param<std::string>("grasp_frame_prefix", grasp_frame_prefix_, grasp_frame_prefix_);
  pnh.param<std::string>("safe_grasp_frame_prefix", safe_grasp_frame_prefix_, safe_grasp_frame_prefix_);
  if (db_path.empty() || gripper_frame_.empty() || up_frame_.empty())
    throw std::runtime_error("parameters ~database_path, ~gripper_frame and ~up_frame must not be empty");
  if (safe_grasp_frame_prefix_ == grasp_frame_prefix_)
    throw std::runtime_error("parameter ~safe_grasp_frame_prefix must differ from ~grasp_frame_prefix");
  tf_timeout_s_ = finiteParam(pnh, "tf_timeout_s", tf_timeout_s_, 0.0);
  pnh.param("use_depth", use_depth_, use_depth_);
  depth_max_age_s_ = finiteParam(pnh, "depth_max_age_s", depth_max_age_s_, 0.0);
  depth_wait_s_ = finiteParam(pnh, "depth_wait_s", depth_wait_s_, 0.0);

  recognition::RecognizerOptions o;
  int top_k = 5;
  pnh.param("top_k", top_k, top_k);
  if (top_k < 1) throw std::runtime_error("parameter ~top_k must be >= 1");
  o.match.top_k = top_k;
  pnh.param<std::string>("textile", o.textile_name, o.textile_name);
  std::string bg = "uniform_colour", cs = "bgr", dm = use_depth_ ? "gate" : "colour_only";
  pnh.param<std::string>("segmentation/background", bg, bg);
  pnh.param<std::string>("segmentation/colour_space", cs, cs);
  pnh.param<std::string>("segmentation/depth_mode", dm, dm);
  o.segmentation.background = enumParam("segmentation/background", bg, recognition::backgroundModelFromString);
  // The node has no picture of the empty scene to give the background-image model.
  if (o.segmentation.background == recognition::BackgroundModel::kBackgroundImage)
    throw std::runtime_error("parameter ~segmentation/background must be uniform_colour or border_median");
  o.segmentation.colour_space = enumParam("segmentation/colour_space", cs, recognition::colourSpaceFromString);
  o.segmentation.depth_mode = enumParam("segmentation/depth_mode", dm, recognition::depthModeFromString);
  std::vector<int> bgr;
  if (pnh.getParam("segmentation/background_bgr", bgr)) {
    if (bgr.size() != 3) throw std::runtime_error("parameter ~segmentation/background_bgr must have 3 entries");
    for (int k = 0; k < 3; ++k) {
      if (bgr[k] < 0 || bgr[k] > 255) throw std::runtime_error("parameter ~segmentation/background_bgr: 0..255");
      o.segmentation.background_bgr[k] = static_cast<std::uint8_t>(bgr[k]);
    }
  }
  o.segmentation.threshold = finiteParam(pnh, "segmentation/threshold", o.segmentation.threshold, 0.0);
  o.segmentation.min_area_px =
      static_cast<int>(finiteParam(pnh, "segmentation/min_area_px", o.segmentation.min_area_px, 1.0));
  o.geometry.max_elevation_deg = finiteParam(pnh, "max_elevation_deg", o.geometry.max_elevation_deg, 0.0);
  pnh.param("refine", o.refinement.enabled, o.refinement.enabled);
  o.max_shift_x_m = finiteParam(pnh, "max_shift_x_m", o.max_shift_x_m, 0.0);
  o.max_shift_y_m = finiteParam(pnh, "max_shift_y_m", o.max_shift_y_m, 0.0);
  pnh.param("shape_fit/enabled", o.shape_fit.enabled, o.shape_fit.enabled);
  o.shape_fit.edge_weight = finiteParam(pnh, "shape_fit/edge_weight", o.shape_fit.edge_weight, 1e-6);
  pnh.param("shape_fit/iterations", o.shape_fit.iterations, o.shape_fit.iterations);
  pnh.param("shape_fit/fuse_views", o.shape_fit.fuse_views, o.shape_fit.fuse_views);
  o.shape_fit.reach_m = finiteParam(pnh, "shape_fit/reach_m", o.shape_fit.reach_m, 0.0);
  pnh.param("shape_fit/rotations", o.shape_fit.rotations, o.shape_fit.rotations);
  pnh.param("fusion_views", fusion_views_, fusion_views_);
  if (fusion_views_ < 1) throw std::runtime_error("parameter ~fusion_views must be >= 1");
  fusion_window_s_ = finiteParam(pnh, "fusion_window_s", fusion_window_s_, 0.0);
  fusion_min_separation_deg_ = finiteParam(pnh, "fusion_min_separation_deg", fusion_min_separation_deg_, 0.0);
  camera_info_wait_s_ = finiteParam(pnh, "camera_info_wait_s", camera_info_wait_s_, 0.0);
  camera_info_max_age_s_ = finiteParam(pnh, "camera_info_max_age_s", camera_info_max_age_s_, 0.0);
  max_image_pixels_ = static_cast<std::int64_t>(finiteParam(pnh, "max_image_pixels", 25e6, 1.0));
  o.max_image_pixels = max_image_pixels_;
  o.evidence.min_score = finiteParam(pnh, "evidence/min_score", o.evidence.min_score, 0.0);
  o.evidence.min_coverage = finiteParam(pnh, "evidence/min_coverage", o.evidence.min_coverage, 0.0);
  o.evidence.max_colour_fraction = finiteParam(pnh, "evidence/max_colour_fraction", o.evidence.max_colour_fraction, 0.0);
  o.evidence.max_lost_view_fraction =
      finiteParam(pnh, "evidence/max_lost_view_fraction", o.evidence.max_lost_view_fraction, 0.0);
  o.evidence.contradiction_gap = finiteParam(pnh, "evidence/contradiction_gap", o.evidence.contradiction_gap, 0.0);
  o.evidence.contradiction_regret = finiteParam(pnh, "evidence/contradiction_regret", o.evidence.contradiction_regret, 0.0);
  pnh.param("evidence/ignore_unbuilt_textiles", o.evidence.ignore_unbuilt_textiles, o.evidence.ignore_unbuilt_textiles);
  pnh.param("localisation/enabled", o.localisation.enabled, o.localisation.enabled);
  o.trust.safe_bound_m = finiteParam(pnh, "trust/safe_bound_m", o.trust.safe_bound_m, 0.0);
  o.trust.roughness_gain = finiteParam(pnh, "trust/roughness_gain", o.trust.roughness_gain, 0.0);
  try {
    o.validate();
    recognizer_ = std::make_unique<recognition::TextileRecognizer>(db_path, o);
  } catch (const std::exception& e) {
    throw std::runtime_error("recognizer (database '" + db_path + "'): " + e.what());
  }
  if (!recognizer_->ready())
    ROS_WARN_NAMED("textile_recognizer", "database %s has no finished simulations yet; waiting for database_changed",
                   db_path.c_str());
  logSkippedViews();

  result_pub_ = pnh.advertise<RecognitionResult>("result", 10);
  poses_pub_ = pnh.advertise<geometry_msgs::PoseArray>("grasp_poses", 10);
  safe_poses_pub_ = pnh.advertise<geometry_msgs::PoseArray>("safe_grasp_poses", 10);
  image_transport::ImageTransport pit(pnh);
  debug_pub_ = pit.advertise("debug_image", 1);
  std::string changed_topic = "drape_simulator/database_changed";
  pnh.param<std::string>("database_changed_topic", changed_topic, changed_topic);
  changed_sub_ = nh.subscribe(changed_topic, 1, &TextileRecognizerNode::databaseChanged, this);
  image_sub_ = it_.subscribe("image", 2, &TextileRecognizerNode::imageCallback, this);
  info_sub_ = nh.subscribe(image_transport::getCameraInfoTopic(image_sub_.getTopic()), 4,
                           &TextileRecognizerNode::infoCallback, this);
  if (use_depth_) depth_sub_ = nh.subscribe("depth", 2, &TextileRecognizerNode::depthCallback, this);
  // Builders that publish no database_changed topic (other machines, a build farm, drape_db) are seen
  // through the database itself: LISTEN/NOTIFY on PostgreSQL, the file's commit counter on SQLite.
  bool watch_database = true;
  pnh.param("watch_database", watch_database, watch_database);
  if (watch_database) watcher_ = std::thread([this, db_path] { watchDatabase(db_path); });
  worker_ = std::thread([this] { workerLoop(); });
  ROS_INFO_NAMED("textile_recognizer", "ready: %zu silhouettes of %zu hold points, image topic %s%s",
                 recognizer_->silhouetteCount(), recognizer_->holdPointCount(), image_sub_.getTopic().c_str(),
                 use_depth_ ? ", with depth" : "");
}

TextileRecognizerNode::~TextileRecognizerNode() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
  if (watcher_.joinable()) watcher_.join();
}

void TextileRecognizerNode::watchDatabase(const std::string& db_path) {
  std::unique_ptr<db::DatabaseChangeWatcher> watcher;
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return;
    }
    try {
      // A lost server connection is replaced by a new watcher; the reload after it catches up on
      // whatever changed meanwhile.
      if (!watcher) {
        watcher = std::make_unique<db::DatabaseChangeWatcher>(db_path);
        reload_requested_ = true;
      }
      if (watcher->waitForChange(500)) reload_requested_ = true;
    } catch (const std::exception& e) {
      watcher.reset();
      ROS_WARN_THROTTLE_NAMED(30.0, "textile_recognizer", "cannot watch the database for changes (retrying): %s",
                              e.what());
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait_for(lock, std::chrono::seconds(2), [this] { return stop_; });
    }
  }
}

void TextileRecognizerNode::depthCallback(const sensor_msgs::ImageConstPtr& depth) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    last_depth_ = depth;
  }
  cv_.notify_all();  // the worker may be waiting for the depth image of its frame
}

void TextileRecognizerNode::databaseChanged(const DatabaseChanged::ConstPtr&) { reload_requested_ = true; }

// Once per load: which stored views were damaged (the recognizer uses the textile's other views).
void TextileRecognizerNode::logSkippedViews() const {
  for (const std::string& w : recognizer_->resultWarnings()) ROS_WARN_NAMED("textile_recognizer", "%s", w.c_str());
  for (const std::string& w : recognizer_->loadWarnings()) ROS_WARN_NAMED("textile_recognizer", "%s", w.c_str());
}

void TextileRecognizerNode::infoCallback(const sensor_msgs::CameraInfoConstPtr& info) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    infos_.push_back(info);
    if (infos_.size() > kInfoHistory) infos_.pop_front();
  }
  cv_.notify_all();  // the worker may be waiting for the camera_info of its frame
}

sensor_msgs::CameraInfoConstPtr TextileRecognizerNode::matchingInfo(const ros::Time& stamp) const {
  sensor_msgs::CameraInfoConstPtr best;
  double best_dt = camera_info_max_age_s_;
  for (const auto& i : infos_) {
    const double dt = std::fabs((i->header.stamp - stamp).toSec());
    if (dt <= best_dt) {
      best_dt = dt;
      best = i;
    }
  }
  return best;
}

void TextileRecognizerNode::imageCallback(const sensor_msgs::ImageConstPtr& image) {
  // Never block: hand the frame to the worker, or drop it if the worker is busy.
  if (busy_) {
    ++dropped_;
    ROS_DEBUG_THROTTLE_NAMED(5.0, "textile_recognizer", "busy: dropped %ld frames so far", dropped_.load());
    return;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  pending_.image = image;
  pending_.info = matchingInfo(image->header.stamp);
  pending_.depth.reset();
  if (use_depth_ && last_depth_ &&
      std::fabs((last_depth_->header.stamp - image->header.stamp).toSec()) <= depth_max_age_s_)
    pending_.depth = last_depth_;
  has_frame_ = true;
  busy_ = true;
  cv_.notify_one();
}

void TextileRecognizerNode::workerLoop() {
  for (;;) {
    Frame f;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait(lock, [this] { return stop_ || has_frame_; });
      if (stop_) return;
      f = pending_;
      has_frame_ = false;
      // Its camera_info may arrive just after the image: wait a little for it; without one the frame
      // is answered with success: false (process()).
      if (!f.info) {
        cv_.wait_for(lock, std::chrono::duration<double>(camera_info_wait_s_),
                     [&] { return stop_ || matchingInfo(f.image->header.stamp) != nullptr; });
        if (stop_) return;
        f.info = matchingInfo(f.image->header.stamp);
      }
      // The depth image of this frame may arrive just after the colour image: wait a little for it
      // (on the worker thread; callbacks never wait).
      if (use_depth_ && !f.depth) {
        const auto matches = [&] {
          return last_depth_ &&
                 std::fabs((last_depth_->header.stamp - f.image->header.stamp).toSec()) <= depth_max_age_s_;
        };
        cv_.wait_for(lock, std::chrono::duration<double>(depth_wait_s_), [&] { return stop_ || matches(); });
        if (stop_) return;
        if (matches()) f.depth = last_depth_;
        else ROS_WARN_THROTTLE_NAMED(5.0, "textile_recognizer", "no depth image for the frame at %.3f s; colour only",
                                     f.image->header.stamp.toSec());
      }
    }
    if (reload_requested_.exchange(false)) {
      try {
        if (recognizer_->reloadIfChanged()) {
          ROS_INFO_NAMED("textile_recognizer", "database reloaded: %zu silhouettes", recognizer_->silhouetteCount());
          logSkippedViews();
        }
      } catch (const std::exception& e) {
        ROS_WARN_THROTTLE_NAMED(5.0, "textile_recognizer", "database reload failed (keeping the old index): %s",
                                e.what());
      }
    }
    try {
      process(f);
    } catch (const std::exception& e) {
      // Defensive: process() reports its own errors; anything else must not kill the worker.
      ROS_ERROR_THROTTLE_NAMED(1.0, "textile_recognizer", "unexpected error: %s", e.what());
    }
    busy_ = false;
  }
}

void TextileRecognizerNode::publishFailure(const std_msgs::Header& header, const std::string& code,
                                           const std::string& why) {
  RecognitionResult r;
  r.header.stamp = header.stamp;
  r.header.frame_id = gripper_frame_;
  r.success = false;
  r.reason_code = code;
  r.message = why;
  r.skipped_views = static_cast<int>(recognizer_->skippedViews().size());
  r.warnings = recognizer_->resultWarnings();
  result_pub_.publish(r);
  ROS_WARN_THROTTLE_NAMED(2.0, "textile_recognizer", "%s", why.c_str());
}

std::pair<std::string, std::string> TextileRecognizerNode::checkImageMessage(const sensor_msgs::Image& image) const {
  const std::int64_t pixels = static_cast<std::int64_t>(image.width) * static_cast<std::int64_t>(image.height);
  if (pixels > max_image_pixels_)
    return {"image_too_large", "image is " + std::to_string(image.width) + " x " + std::to_string(image.height) +
                                   " px, more than ~max_image_pixels = " + std::to_string(max_image_pixels_)};
  if (!supportedEncoding(image.encoding))
    return {"unsupported_encoding", "image encoding '" + image.encoding + "' is not bgr8, rgb8 or mono8"};
  return {};
}

void TextileRecognizerNode::process(const Frame& f) {
  const auto t0 = std::chrono::steady_clock::now();
  const std_msgs::Header& h = f.image->header;
  if (h.frame_id.empty()) return publishFailure(h, "invalid_image", "image has an empty frame_id");
  // Before any conversion: the size and encoding come from the message header.
  const auto refused = checkImageMessage(*f.image);
  if (!refused.first.empty()) return publishFailure(h, refused.first, refused.second);
  if (f.depth && static_cast<std::int64_t>(f.depth->width) * f.depth->height > max_image_pixels_)
    return publishFailure(h, "image_too_large", "depth image is larger than ~max_image_pixels");
  if (!f.info)
    return publishFailure(h, "missing_camera_info",
                          "no camera_info with the image's stamp " + std::to_string(h.stamp.toSec()) + " s on " +
                              info_sub_.getTopic() + " (waited " + std::to_string(camera_info_wait_s_) + " s)");
  recognition::CameraObservation obs;
  // Intrinsics from camera_info (K row-major).
  const auto& K = f.info->K;
  obs.intrinsics.fx = K[0];
  obs.intrinsics.fy = K[4];
  obs.intrinsics.cx = K[2];
  obs.intrinsics.cy = K[5];
  obs.intrinsics.width = static_cast<int>(f.info->width);
  obs.intrinsics.height = static_cast<int>(f.info->height);
  if (!(K[0] > 0) || !(K[4] > 0) || !std::isfinite(K[2]) || !std::isfinite(K[5]))
    return publishFailure(h, "invalid_geometry", "camera_info has no valid intrinsics (K)");
  if (f.info->width != f.image->width || f.info->height != f.image->height)
    return publishFailure(h, "invalid_geometry", "camera_info size differs from the image size");
  try {
    obs.image = cv_bridge::toCvShare(f.image)->image;
    obs.encoding = f.image->encoding;
    if (f.depth) {
      obs.depth = cv_bridge::toCvShare(f.depth)->image;
      if (f.depth->encoding != "32FC1" && f.depth->encoding != "16UC1")
        return publishFailure(h, "invalid_depth", "depth encoding " + f.depth->encoding + " is not 32FC1 or 16UC1");
    }
  } catch (const cv_bridge::Exception& e) {
    return publishFailure(h, "invalid_image", std::string("image conversion: ") + e.what());
  }
  // Geometry from tf at the image's stamp: hold point (gripper origin), up and heading in the camera.
  Eigen::Isometry3d camera_gripper, camera_up;
  try {
    camera_gripper = tf2::transformToEigen(
        tf_buffer_.lookupTransform(h.frame_id, gripper_frame_, h.stamp, ros::Duration(tf_timeout_s_)));
    camera_up = tf2::transformToEigen(
        tf_buffer_.lookupTransform(h.frame_id, up_frame_, h.stamp, ros::Duration(tf_timeout_s_)));
  } catch (const tf2::TransformException& e) {
    return publishFailure(h, "transform_unavailable", std::string("tf: ") + e.what());
  }
  obs.hold_camera = camera_gripper.translation();
  obs.up_camera = camera_up.linear() * Vec3::UnitZ();
  obs.heading_camera = Vec3(camera_gripper.linear() * Vec3::UnitX());
  // Gripper heading about the up axis (for choosing fusion partners): the gripper x axis in the up frame.
  const Eigen::Isometry3d up_gripper = camera_up.inverse() * camera_gripper;
  const Vec3 gx = up_gripper.linear() * Vec3::UnitX();
  const double yaw = std::atan2(gx.y(), gx.x()) * 180.0 / M_PI;
  // Forget observations of another hold: too old, or the gripper moved (not only turned).
  while (!history_.empty() && (h.stamp < history_.back().stamp ||
                               (h.stamp - history_.front().stamp).toSec() > fusion_window_s_))
    history_.pop_front();
  std::vector<double> earlier_yaws;  // newest first
  for (auto it = history_.rbegin(); it != history_.rend(); ++it) earlier_yaws.push_back(it->gripper_yaw_deg);
  std::vector<recognition::CameraObservation> images{obs};
  for (std::size_t k : recognition::chooseFusionPartners(yaw, earlier_yaws, fusion_views_, fusion_min_separation_deg_))
    images.push_back(history_[history_.size() - 1 - k].observation);
  recognition::RecognitionResult res;
  auto code = [](const std::exception& e) {
    const auto* r = dynamic_cast<const recognition::RecognitionError*>(&e);
    return r ? std::string(recognition::toString(r->code())) : std::string("internal_error");
  };
  try {
    res = images.size() > 1 ? recognizer_->recognize(images) : recognizer_->recognize(obs);
  } catch (const std::exception& e) {
    // A failed fusion (e.g. a bad earlier frame) falls back to this image alone.
    if (images.size() > 1) {
      try {
        res = recognizer_->recognize(obs);
        images.resize(1);
      } catch (const std::exception& e2) {
        return publishFailure(h, code(e2), e2.what());
      }
    } else {
      return publishFailure(h, code(e), e.what());
    }
  }
  // A deep copy: obs's images share the buffers of this frame's messages (toCvShare), which are freed
  // once the frame is done, and a later fusion reads them again.
  Past past{h.stamp, yaw, obs};
  past.observation.image = obs.image.clone();
  past.observation.depth = obs.depth.clone();
  past.observation.mask = obs.mask.clone();
  history_.push_back(std::move(past));
  if (history_.size() > 16) history_.pop_front();
  // Poses: camera frame -> gripper frame.
  const Eigen::Isometry3d gripper_camera = camera_gripper.inverse();
  std_msgs::Header out_header;
  out_header.stamp = h.stamp;
  out_header.frame_id = gripper_frame_;
  std::vector<geometry_msgs::TransformStamped> frames;
  RecognitionResult out = resultMessage(res, out_header, gripper_camera, grasp_frame_prefix_, safe_grasp_frame_prefix_, &frames);
  out.images_fused = static_cast<int>(images.size());
  out.processing_ms = msSince(t0);
  tf_broadcaster_.sendTransform(frames);
  result_pub_.publish(out);
  poses_pub_.publish(out.grasp_poses);
  safe_poses_pub_.publish(out.safe_grasp_poses);
  if (debug_pub_.getNumSubscribers() > 0) {  // lazy: the overlay costs a render
    try {
      const cv::Mat dbg = recognizer_->debugImage(obs, res);
      debug_pub_.publish(cv_bridge::CvImage(h, "bgr8", dbg).toImageMsg());
    } catch (const std::exception& e) {
      ROS_WARN_THROTTLE_NAMED(5.0, "textile_recognizer", "debug image: %s", e.what());
    }
  }
  ROS_INFO_THROTTLE_NAMED(1.0, "textile_recognizer",
                          "%s held at (%.3f, %.3f) m, view %.0f deg, score %.2f (+%.2f), %zu image(s), %.0f ms",
                          out.textile_name.c_str(), out.hold_x, out.hold_y, out.view_angle_deg, out.score,
                          out.confidence, images.size(), out.processing_ms);
}

}  // namespace textile_handling
