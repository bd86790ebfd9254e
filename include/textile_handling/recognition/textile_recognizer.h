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
#include "textile_handling/recognition/grasp_point_trust.h"
#include "textile_handling/recognition/grasp_poses.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/recognition/recognition_evidence.h"
#include "textile_handling/recognition/segmentation.h"
#include "textile_handling/recognition/shape_fitting.h"
#include "textile_handling/vision/silhouette_matcher.h"

namespace textile_handling {
namespace recognition {

struct RefinementOptions {
  bool enabled = true;
  /// Coarse hold-point classes (best first) whose members are refined.
  int classes = 3;
  /// Members of a refined class rendered at fine azimuths: those whose stored views match best (the
  /// cheap first pass); 0 = all. A class holds up to 4 mirror rows per build member (docs/database.md,
  /// "Members"), so without a cap refinement time grows with the members; 4 keeps the cost of a
  /// one-member database.
  int members = 4;
  /// Shift search [canonical px] of the refinement (the hold pixel is known, so shifts stay small).
  int max_shift_px = 4;
  /// Fine azimuth step [deg] and half range around the best stored view [deg] (0 = half the stored view
  /// spacing + 1 deg).
  double step_deg = 1.0;
  double half_range_deg = 0.0;
  /// The fine azimuths are searched coarse to fine: every coarse_step_deg first, then step_deg around
  /// the best of those (coarse_step_deg <= step_deg: every step).
  double coarse_step_deg = 3.0;
  /// Render the candidates with the camera's own pinhole projection (distance, height); false: the
  /// index's projection (orthographic for default databases).
  bool camera_projection = true;
  /// Rank the refined classes by their refined score (ahead of the unrefined ones).
  bool rerank = true;
  /// With depth: every member of the winning class within depth_member_slack of its best refined
  /// score, as stored and mirrored front-to-back (consider_reflections), at azimuths within
  /// +-depth_yaw_range_deg of its silhouette optimum (depth_yaw_step_deg steps, then step_deg) whose
  /// silhouette score stays within depth_score_slack of that optimum, is rendered into the depth camera;
  /// the lowest cost (1 - IoU) + depth_weight_per_m * depth misfit (see depth_truncation_m) wins: its
  /// member, azimuth and chirality are the result (the class stays the silhouette's).
  bool use_depth = true;
  double depth_member_slack = 0.08;
  double depth_score_slack = 0.05;
  double depth_weight_per_m = 50.0;  ///< 1 cm of depth misfit weighs like 0.5 IoU
  double depth_yaw_range_deg = 30.0;
  double depth_yaw_step_deg = 6.0;
  /// With depth, also try every such member mirrored front-to-back (reflectAcrossView(): the same
  /// silhouette, the other chirality; a towel grasped while lying face down hangs as the mirror image of
  /// the face-up simulation).
  bool consider_reflections = true;
  /// Fused images: the depth misfit is the median over every image with depth (the mean of two; false:
  /// the first image with depth only).
  bool depth_all_images = true;
  /// Fewer overlapping depth pixels than this: no depth decision.
  int depth_min_pixels = 100;
  /// The depth fit is the mean of min(|predicted - measured|, depth_truncation_m) over the pixels of the
  /// segmented mask where both exist (robust to a few wrong pixels, yet sensitive to a wrong layer).
  double depth_truncation_m = 0.10;
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
  /// Coarse shift search range in metres (converted per index frame), used instead of match.max_dx /
  /// max_dy when both are >= 0. The hold point is located in the image, so silhouettes only need aligning
  /// by that error: +-3 x +-2 cm (docs/database.md measured it better than the thesis's +-47 x +-8 cm).
  double max_shift_x_m = 0.03;
  double max_shift_y_m = 0.02;
  SegmentationOptions segmentation;
  CameraGeometryOptions geometry;
  CanonicalisationOptions canonicalisation;
  RefinementOptions refinement;
  /// With depth in the first image: the chosen shape is deformed onto the measured surface before the
  /// grasp poses are read (shape_fitting.h).
  ShapeFitOptions shape_fit;
  GraspPoseOptions grasp;
  /// When a grasp point counts as seen by an image (GraspPose::observation).
  GraspPointObservationOptions observation;
  /// Corners moved to the images' outline corners (grasp_point_localisation.h).
  GraspPointLocalisationOptions localisation;
  /// Per-point error bounds and the safe flag (grasp_point_trust.h).
  GraspPointTrustOptions trust;
  /// Stored rest shapes kept in memory (loaded on demand).
  std::size_t mesh_cache_size = 64;
  /// When a result may be a success (floors, lost database entries, unbuilt textiles).
  EvidenceOptions evidence;
  /// Largest image (and depth image) accepted, in pixels: 25 MP holds every cell camera (5472 x 3648 =
  /// 20 MP) while bounding the per-image work (segmentation buffers are a few bytes per pixel).
  std::int64_t max_image_pixels = 25'000'000;

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
  double depth_residual_m = -1;         ///< truncated mean |predicted - measured| depth [m], -1 = not computed
  /// The stored shape mirrored across the vertical plane through the hold axis perpendicular to
  /// d(reflection_view_deg) (stored-shape frame) fits better (depth decided).
  bool reflected = false;
  double reflection_view_deg = 0;
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
  /// One view direction and no depth decision: the shape mirrored front-to-back (across the vertical
  /// plane perpendicular to the view) explains the silhouette equally well, so each pose's depth along
  /// the viewing direction may be mirrored through the hold point (docs/recognition.md).
  bool front_back_ambiguous = false;
  bool depth_used = false;              ///< depth took part in segmentation
  bool depth_decided = false;           ///< depth chose the azimuth, member and chirality
  double depth_residual_m = -1;
  bool reflected = false;               ///< see HoldCandidate::reflected
  double reflection_view_deg = 0;
  std::vector<HoldCandidate> top_k;     ///< best first (top_k[0] is the winner)
  std::vector<GraspPose> grasp_poses;   ///< hold frame of the first image (+ camera frame copies)
  /// The fit of the chosen shape to the first image's depth (applied = false: stored shape as matched).
  ShapeFitReport shape_fit;

  // ---- diagnostics ----
  std::vector<HoldGeometry> geometry;   ///< per image
  std::vector<double> relative_view_deg;
  std::vector<cv::Mat> image_masks;     ///< segmentation per image (CV_8UC1)
  std::vector<vision::BitMask> query_masks;  ///< canonical masks per image (winner's index frame)
  vision::BitMask matched_mask;         ///< winner rendered for the first image, same frame
  vision::CanonicalFrame frame;
  double segmentation_ms = 0, query_ms = 0, refine_ms = 0, total_ms = 0;

  // ---- evidence ----
  double coverage = 0;                  ///< see EvidenceOptions::min_coverage (mean over the images)
  std::vector<double> image_coverage;   ///< per image: its own coverage by the winner
  /// Per image of a fused result: the best score that image reaches alone (the single-image coarse
  /// query, every loaded index) minus the winner's score on it (best-shift IoU of the winner rendered for
  /// that image, the same shift range). Large: the image alone points elsewhere, and the fused winner
  /// only compromises with it. Empty for one image.
  std::vector<double> image_regret;
  /// Images of a fused result that the fused winner explains much worse than the best image
  /// (EvidenceOptions::contradiction_gap): views that contradict the others. Each halves the confidence;
  /// any makes the match weak for the per-point trust (every bound doubled, except for points two or
  /// more images placed at one outline corner). A contradicting view does not decide the answer
  /// (answer_images).
  int contradicting_images = 0;
  /// The images the answer rests on (indices into the observations, the first always among them). All
  /// of them unless some contradict. Then the images split into those the fused winner explains (within
  /// the gap of the best) and the others; the first image's group is the consistent one unless the other
  /// group is larger (then the fused answer stands). The answer is recognised again from the consistent
  /// group alone: with three or more images that is the answer; with two (the first image alone), it is
  /// the answer only if it names another hold-point class than the fused one, which otherwise stands
  /// (flagged, both images). The per-image fields (geometry, relative_view_deg, image_masks,
  /// query_masks, image_coverage) list the answer's images only.
  std::vector<int> answer_images;
  double colour_fraction = -1;          ///< first image; see EvidenceOptions::max_colour_fraction
  std::size_t skipped_views = 0;        ///< damaged stored views left out at the last load
  /// Load problems that did not stop the recognition: damaged views skipped, unbuilt textiles ignored.
  std::vector<std::string> warnings;
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
  /// Reloads if the database's content changed since the last load (fingerprint: textiles, finished
  /// simulations with their ids and finish times, views; a resimulation that replaces every row is
  /// detected too); returns whether it reloaded.
  bool reloadIfChanged();
  /// Restricts recognition to one textile (0 = all) and reloads; kUnknownTextile for an unknown id
  /// (the previous filter stays).
  void setTextileFilter(std::int64_t textile_id);

  bool ready() const;                   ///< an index with at least one silhouette is loaded
  std::size_t silhouetteCount() const;
  std::size_t holdPointCount() const;
  std::vector<std::string> loadWarnings() const;  ///< textiles skipped at the last load, with reasons
  /// Damaged stored views left out at the last load (the textile's other views are used).
  std::vector<db::SkippedView> skippedViews() const;
  /// Warnings every result of the current load carries (RecognitionResult::warnings).
  std::vector<std::string> resultWarnings() const;
  std::vector<db::TextileRecord> textiles() const;  ///< textiles of the database
  db::TextileRecord textile(std::int64_t id) const;  ///< throws kUnknownTextile
  RecognizerOptions options() const;  ///< a copy (the filter may change)

  /// Recognises one image. Throws RecognitionError (never crashes on bad input): see the codes; a result
  /// that returns met the minimum evidence (RecognizerOptions::evidence).
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
  /// The recognition stages on `observations` (recognize() decides which images take part);
  /// `left_out_contradicting` images of the caller's set were left out as contradicting.
  RecognitionResult recognizeImages(const State& state, const std::vector<CameraObservation>& observations,
                                    int left_out_contradicting) const;
  /// The stored rest shape of a simulation (cached per loaded state: ids can be reused after a
  /// resimulation); `expected_hold` guards against a database that changed under a running recognition.
  std::shared_ptr<const StoredShape> shape(const State& state, std::int64_t simulation_id, const Vec2& expected_hold) const;

  std::shared_ptr<const db::HangingDrapeDatabase> db_;
  RecognizerOptions options_;
  mutable std::mutex mutex_;            // state_ and the filter
  std::shared_ptr<const State> state_;
};

/// Images to fuse with one taken at gripper heading `yaw_deg` (the cell turns the gripper between
/// images of the same hold): indices into `earlier_yaws_deg` (the earlier images' headings, newest
/// first) of up to max_views - 1 images, newest first, each at least min_separation_deg away from
/// this image and from every image chosen before it.
std::vector<std::size_t> chooseFusionPartners(double yaw_deg, const std::vector<double>& earlier_yaws_deg, int max_views,
                                              double min_separation_deg);

}  // namespace recognition
}  // namespace textile_handling
