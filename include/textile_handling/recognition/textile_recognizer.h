// The recognition core that the textile_recognizer node calls (ROS-free): camera image(s) of a textile
// held by a gripper -> which textile, held at which point, seen from which azimuth, and the grasp poses
// of its corners and predefined grasp points in the gravity-aligned hold frame. Pipeline, frames,
// options and limits: docs/recognition.md.
//
//   geometry      computeHoldGeometry(): hold pixel, metric scale, virtual horizontal camera, hold frame
//   segmentation  segmentTextile() (+ depthClusterMask() / pointCloudClusterMask() with depth)
//   canonical     canonicaliseObservationMask() into each loaded index's canonical frame
//   coarse match  db::queryDrape() / db::queryDrapeFused() per textile index -> hold-point classes
//   refinement    the top classes' members re-rendered with the camera's own pinhole projection at
//                 1-degree azimuth steps around their best stored view (and, with depth, the member whose
//                 predicted depth fits the measured one best among mirror-equivalent members)
//   grasp poses   the chosen member's named points placed in the hold frame (grasp_poses.h)
//
// Thread safety: recognize() and debugImage() are const and may run concurrently with each other and
// with reload() / reloadIfChanged() (the loaded state is swapped atomically; a running recognition
// finishes on the state it started with).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/recognition/camera_geometry.h"
#include "textile_handling/recognition/grasp_poses.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/recognition/segmentation.h"
#include "textile_handling/vision/silhouette_matcher.h"

namespace textile_handling {
namespace recognition {

struct RefinementOptions {
  bool enabled = true;
  /// Coarse hold-point classes (best first) whose members are refined.
  int classes = 3;
  /// Shift search [canonical px] of the refinement (the hold pixel is known, so shifts stay small).
  int max_shift_px = 4;
  /// Fine azimuth step [deg] and half range around the best stored view [deg] (0 = half the stored view
  /// spacing + 1 deg).
  double step_deg = 1.0;
  double half_range_deg = 0.0;
  /// Render the candidates with the camera's own pinhole projection (distance, height); false: the
  /// index's projection (orthographic for default databases).
  bool camera_projection = true;
  /// Rank the refined classes by their refined score (ahead of the unrefined ones).
  bool rerank = true;
  /// With depth: for every member of the winning class within depth_score_slack of its best refined
  /// score, the azimuth within +-depth_yaw_range_deg of its silhouette optimum (in depth_yaw_step_deg
  /// steps, then step_deg) whose silhouette score stays within depth_score_slack of that optimum and
  /// whose rendered depth fits the measured depth best (median |predicted - measured| over the mask);
  /// the member with the best fit wins. This also tells mirror-equivalent members apart (front/back).
  bool use_depth = true;
  double depth_score_slack = 0.03;
  double depth_yaw_range_deg = 30.0;
  double depth_yaw_step_deg = 2.0;
  /// Fewer overlapping depth pixels than this: no depth decision.
  int depth_min_pixels = 100;
};

struct RecognizerOptions {
  /// Restrict recognition to one textile, by id (> 0) or by name (non-empty); unknown: kUnknownTextile.
  std::int64_t textile_id = 0;
  std::string textile_name;
  /// Only simulations at this particle spacing [m].
  std::optional<double> spacing;
  bool include_derived = true;
  /// Coarse matcher options; top_k is the number of candidates reported.
  vision::MatchOptions match;
  SegmentationOptions segmentation;
  CameraGeometryOptions geometry;
  CanonicalisationOptions canonicalisation;
  RefinementOptions refinement;
  GraspPoseOptions grasp;
  /// Stored rest shapes kept in memory (loaded on demand).
  std::size_t mesh_cache_size = 64;

  /// Throws RecognitionError(kInvalidOptions) naming the bad field.
  void validate() const;
};

/// One camera image of the held textile with its geometry.
struct CameraObservation {
  cv::Mat image;                     ///< bgr8 / rgb8 (CV_8UC3) or mono8 (CV_8UC1)
  std::string encoding = "bgr8";
  cv::Mat depth;                     ///< optional, registered: CV_32FC1 [m] or CV_16UC1 [mm]
  std::vector<Vec3> points;          ///< optional cloud in the optical frame [m] (used when depth is empty)
  cv::Mat mask;                      ///< optional ready mask (CV_8UC1, image size): skips segmentation
  vision::PinholeIntrinsics intrinsics;
  Vec3 hold_camera = Vec3(0, 0, 1);  ///< hold (gripper) point in the optical frame [m]
  Vec3 up_camera = Vec3(0, -1, 0);   ///< gravity up in the optical frame
  /// Heading reference for the hold frame's x axis, in the optical frame (e.g. the gripper's x axis).
  std::optional<Vec3> heading_camera;
  /// Multi-image only: view azimuth of this image relative to the first (turning the gripper by +phi
  /// gives -phi); if absent, taken from the camera azimuths in the hold frames (needs headings fixed to
  /// the gripper).
  std::optional<double> relative_view_deg;
};

/// One hold-point candidate.
struct HoldCandidate {
  std::int64_t textile_id = 0;
  std::string textile_name;
  std::size_t class_index = 0;          ///< within its index
  Vec2 canonical_hold = Vec2::Zero();   ///< class key: the hold point folded into the fundamental domain
  Vec2 hold_point = Vec2::Zero();       ///< the member used (textile frame [m]): the labelling of the poses
  std::vector<Vec2> equivalent_hold_points;  ///< every member of the class
  int lattice_i = 0, lattice_j = 0;     ///< lattice indices of hold_point
  db::MirrorKind member_source = db::MirrorKind::kIdentity;  ///< how the member's row was made
  std::int64_t simulation_id = 0;
  double view_angle_deg = 0;            ///< stored-shape azimuth matched to the first image (refined if refined)
  double coarse_view_angle_deg = 0;     ///< stored view of the coarse match
  int dx = 0, dy = 0;                   ///< best shift [canonical px], first image
  double coarse_score = 0;              ///< coarse IoU (db::queryDrape)
  double score = 0;                     ///< refined IoU if refined, else the coarse one
  bool refined = false;
  double depth_residual_m = -1;         ///< median |predicted - measured| depth, -1 = not computed
};

struct RecognitionResult {
  // ---- the winner ----
  std::int64_t textile_id = 0;
  std::string textile_name;
  Vec2 hold_point = Vec2::Zero();       ///< textile frame [m]; see HoldCandidate::hold_point
  Vec2 canonical_hold_point = Vec2::Zero();
  std::vector<Vec2> equivalent_hold_points;
  int lattice_i = 0, lattice_j = 0;
  std::int64_t simulation_id = 0;
  double view_angle_deg = 0;            ///< stored-shape azimuth seen by the first camera
  double camera_azimuth_deg = 0;        ///< first camera's azimuth in its hold frame
  double rotation_deg = 0;              ///< stored shape -> hold frame rotation about z (camera - view)
  double score = 0;                     ///< IoU of the winner (refined if refined)
  double confidence = 0;                ///< margin: score minus the runner-up class's score
  double coarse_margin = 0;             ///< the coarse matcher's margin
  /// The hold frame cannot tell front from back: a single silhouette without depth, and the class has
  /// mirror (not half-turn) equivalent members; the poses may be mirrored front-to-back (see docs).
  bool front_back_ambiguous = false;
  bool depth_used = false;              ///< depth took part in segmentation
  bool depth_decided = false;           ///< depth chose among mirror-equivalent members
  double depth_residual_m = -1;
  std::vector<HoldCandidate> top_k;     ///< best first (top_k[0] is the winner)
  std::vector<GraspPose> grasp_poses;   ///< hold frame of the first image (+ camera frame copies)

  // ---- diagnostics ----
  std::vector<HoldGeometry> geometry;   ///< per image
  std::vector<double> relative_view_deg;
  std::vector<cv::Mat> image_masks;     ///< segmentation per image (CV_8UC1)
  std::vector<vision::BitMask> query_masks;  ///< canonical masks per image (winner's index frame)
  vision::BitMask matched_mask;         ///< winner rendered for the first image, same frame
  vision::CanonicalFrame frame;
  double segmentation_ms = 0, query_ms = 0, refine_ms = 0, total_ms = 0;
};

class TextileRecognizer {
 public:
  /// Opens the database read-only and loads the index. Throws RecognitionError: kDatabase (cannot open,
  /// not a drape database, damaged), kUnknownTextile (filter), kInvalidOptions. An empty database is
  /// not an error here: ready() is false and recognize() throws kEmptyDatabase until a reload finds
  /// finished simulations.
  explicit TextileRecognizer(const std::string& database_path, RecognizerOptions options = {});
  /// Uses an open database (shared with e.g. a builder in the same process).
  explicit TextileRecognizer(std::shared_ptr<const db::HangingDrapeDatabase> database, RecognizerOptions options = {});
  ~TextileRecognizer();
  TextileRecognizer(const TextileRecognizer&) = delete;
  TextileRecognizer& operator=(const TextileRecognizer&) = delete;

  /// Reloads the index (after the database changed). On failure the old index stays and the error is
  /// thrown (kDatabase, kUnknownTextile).
  void reload();
  /// Reloads if the database's counts (textiles, finished simulations, views) changed since the last
  /// load; returns whether it reloaded.
  bool reloadIfChanged();
  /// Restricts recognition to one textile (0 = all) and reloads; kUnknownTextile for an unknown id
  /// (the previous filter stays).
  void setTextileFilter(std::int64_t textile_id);

  bool ready() const;                   ///< an index with at least one silhouette is loaded
  std::size_t silhouetteCount() const;
  std::size_t holdPointCount() const;
  std::vector<std::string> loadWarnings() const;  ///< textiles skipped at the last load, with reasons
  std::vector<db::TextileRecord> textiles() const;  ///< textiles of the database
  db::TextileRecord textile(std::int64_t id) const;  ///< throws kUnknownTextile
  RecognizerOptions options() const;  ///< a copy (the filter may change)

  /// Recognises one image. Throws RecognitionError (never crashes on bad input): see the codes.
  RecognitionResult recognize(const CameraObservation& observation) const;
  /// Several images of the same hanging textile with known relative view azimuths (fusion).
  RecognitionResult recognize(const std::vector<CameraObservation>& observations) const;

  /// Debug picture of a result: the image with the segmented mask tinted, the matched shape's outline
  /// (rendered into the camera) and the grasp points with their names. Throws as recognize().
  cv::Mat debugImage(const CameraObservation& observation, const RecognitionResult& result) const;

  struct State;
  struct StoredShape;

 private:
  std::shared_ptr<const State> state() const;
  std::shared_ptr<const StoredShape> shape(std::int64_t simulation_id) const;

  std::shared_ptr<const db::HangingDrapeDatabase> db_;
  RecognizerOptions options_;
  mutable std::mutex mutex_;            // state_ and the filter
  std::shared_ptr<const State> state_;
  mutable std::mutex cache_mutex_;
  mutable std::map<std::int64_t, std::shared_ptr<const StoredShape>> cache_;
};

}  // namespace recognition
}  // namespace textile_handling
