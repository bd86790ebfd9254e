#include "textile_handling/recognition/textile_recognizer.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "recognizer_stages.h"
#include "recognizer_state.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace recognition {

using detail::databaseFingerprint;
using detail::fail;
using detail::loadState;
using detail::openDatabase;

void RecognizerOptions::validate() const {
  auto bad = [](const std::string& what) { fail(RecognitionErrorCode::kInvalidOptions, what); };
  if (textile_id < 0) bad("textile_id must be >= 0 (0 = all textiles)");
  if (spacing && (!(*spacing > 0) || !std::isfinite(*spacing))) bad("spacing must be finite and > 0");
  if (match.top_k < 1 || match.max_dx < 0 || match.max_dy < 0) bad("match: top_k must be >= 1 and shift ranges >= 0");
  const RefinementOptions& r = refinement;
  if (r.classes < 1) bad("refinement.classes must be >= 1");
  if (r.members < 0) bad("refinement.members must be >= 0 (0 = all)");
  if (r.max_shift_px < 0 || r.max_shift_px > 64) bad("refinement.max_shift_px must be in 0..64");
  if (!(r.step_deg > 0 && r.step_deg <= 30)) bad("refinement.step_deg must be in (0, 30]");
  if (!(r.coarse_step_deg >= 0 && r.coarse_step_deg <= 30)) bad("refinement.coarse_step_deg must be in [0, 30]");
  if (!(r.half_range_deg >= 0 && r.half_range_deg <= 180)) bad("refinement.half_range_deg must be in [0, 180]");
  if (!(r.depth_score_slack >= 0 && r.depth_score_slack <= 1)) bad("refinement.depth_score_slack must be in [0, 1]");
  if (!(r.depth_yaw_range_deg >= 0 && r.depth_yaw_range_deg <= 180) || !(r.depth_yaw_step_deg > 0 && r.depth_yaw_step_deg <= 30))
    bad("refinement.depth_yaw_range_deg must be in [0, 180] and depth_yaw_step_deg in (0, 30]");
  if (r.depth_min_pixels < 1) bad("refinement.depth_min_pixels must be >= 1");
  if ((max_shift_x_m >= 0) != (max_shift_y_m >= 0) || !std::isfinite(max_shift_x_m) || !std::isfinite(max_shift_y_m))
    bad("max_shift_x_m and max_shift_y_m must both be finite and >= 0 (metric ranges), or both < 0 (pixel ranges of match)");
  const ShapeFitOptions& sf = shape_fit;
  if (sf.iterations < 1 || sf.iterations > 100) bad("shape_fit.iterations must be in 1..100");
  if (!(sf.edge_weight > 0) || !std::isfinite(sf.edge_weight)) bad("shape_fit.edge_weight must be finite and > 0");
  if (!(sf.anchor_weight >= 0) || !std::isfinite(sf.anchor_weight) || !(sf.silhouette_weight >= 0) ||
      !std::isfinite(sf.silhouette_weight))
    bad("shape_fit.anchor_weight and silhouette_weight must be finite and >= 0");
  if (!(sf.visibility_slack_m > 0) || !(sf.max_correspondence_m > 0) || !std::isfinite(sf.max_correspondence_m) ||
      !std::isfinite(sf.visibility_slack_m))
    bad("shape_fit.visibility_slack_m and max_correspondence_m must be finite and > 0");
  if (sf.uncovered_step_px < 1 || sf.uncovered_step_px > 64) bad("shape_fit.uncovered_step_px must be in 1..64");
  if (!(r.depth_truncation_m > 0) || !std::isfinite(r.depth_truncation_m)) bad("refinement.depth_truncation_m must be finite and > 0");
  if (!(r.depth_member_slack >= 0 && r.depth_member_slack <= 1) || !(r.depth_weight_per_m >= 0) || !std::isfinite(r.depth_weight_per_m))
    bad("refinement.depth_member_slack must be in [0, 1] and depth_weight_per_m finite and >= 0");
  if (mesh_cache_size < 1) bad("mesh_cache_size must be >= 1");
  if (!(grasp.boundary_tolerance_m >= 0) || !std::isfinite(grasp.boundary_tolerance_m))
    bad("grasp.boundary_tolerance_m must be finite and >= 0");
  if (!(observation.surface_tolerance_m > 0) || !std::isfinite(observation.surface_tolerance_m) ||
      observation.window_px < 0 || observation.window_px > 32)
    bad("observation.surface_tolerance_m must be finite and > 0 and observation.window_px in 0..32");
  localisation.validate();
  trust.validate();
  if (canonicalisation.max_canvas_px < 16) bad("canonicalisation.max_canvas_px must be >= 16");
  if (max_image_pixels < 1) bad("max_image_pixels must be >= 1");
  evidence.validate();
  if (!std::isfinite(canonicalisation.clear_above_hold_m)) bad("canonicalisation.clear_above_hold_m must be finite");
  segmentation.validate();
}

TextileRecognizer::TextileRecognizer(const std::string& path, RecognizerOptions options)
    : TextileRecognizer(openDatabase(path), std::move(options)) {}

TextileRecognizer::TextileRecognizer(std::shared_ptr<const db::HangingDrapeDatabase> database, RecognizerOptions options)
    : db_(std::move(database)), options_(std::move(options)) {
  if (!db_) fail(RecognitionErrorCode::kDatabase, "no database given");
  options_.validate();
  state_ = loadState(*db_, options_);
}

TextileRecognizer::~TextileRecognizer() = default;

void TextileRecognizer::reload() {
  RecognizerOptions o = options();
  auto st = loadState(*db_, o);
  std::lock_guard<std::mutex> lock(mutex_);
  state_ = std::move(st);
}

bool TextileRecognizer::reloadIfChanged() {
  const auto st = state();
  std::string now;
  try {
    now = databaseFingerprint(*db_);
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, std::string("reading the database: ") + e.what());
  }
  if (now == st->fingerprint) return false;
  reload();
  return true;
}

void TextileRecognizer::setTextileFilter(std::int64_t textile_id) {
  RecognizerOptions o = options();
  o.textile_id = textile_id;
  o.textile_name.clear();
  o.validate();
  auto st = loadState(*db_, o);  // throws kUnknownTextile, keeping the old filter
  std::lock_guard<std::mutex> lock(mutex_);
  options_ = o;
  state_ = std::move(st);
}

RecognizerOptions TextileRecognizer::options() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return options_;
}

std::shared_ptr<const TextileRecognizer::State> TextileRecognizer::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

bool TextileRecognizer::ready() const { return state()->silhouettes > 0; }
std::size_t TextileRecognizer::silhouetteCount() const { return state()->silhouettes; }
std::size_t TextileRecognizer::holdPointCount() const { return state()->hold_points; }
std::vector<std::string> TextileRecognizer::loadWarnings() const { return state()->warnings; }
std::vector<db::SkippedView> TextileRecognizer::skippedViews() const { return state()->skipped; }
std::vector<std::string> TextileRecognizer::resultWarnings() const { return state()->result_warnings; }

std::vector<db::TextileRecord> TextileRecognizer::textiles() const {
  std::vector<db::TextileRecord> out;
  for (const auto& [name, t] : state()->textiles) out.push_back(t);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

db::TextileRecord TextileRecognizer::textile(std::int64_t id) const {
  for (const auto& [name, t] : state()->textiles)
    if (t.id == id) return t;
  try {
    return db_->textile(id);  // added since the last load
  } catch (const db::NotFoundError&) {
    fail(RecognitionErrorCode::kUnknownTextile, "textile id " + std::to_string(id) + " is not in the database");
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, e.what());
  }
}

std::shared_ptr<const TextileRecognizer::StoredShape> TextileRecognizer::shape(const State& st, std::int64_t simulation_id,
                                                                            const Vec2& expected_hold) const {
  return detail::loadStoredShape(*db_, st, simulation_id, expected_hold);
}

RecognitionResult TextileRecognizer::recognize(const CameraObservation& observation) const {
  return recognize(std::vector<CameraObservation>{observation});
}

// A view that contradicts the others must not flip the answer (RecognitionResult::answer_images).
RecognitionResult TextileRecognizer::recognize(const std::vector<CameraObservation>& obs) const {
  const auto st = state();
  RecognitionResult fused = recognizeImages(*st, obs, 0);
  fused.answer_images.clear();
  for (std::size_t i = 0; i < obs.size(); ++i) fused.answer_images.push_back(static_cast<int>(i));
  if (fused.contradicting_images == 0 || obs.size() < 2) return fused;
  // Two groups: the images the fused winner explains (contradictingImages) and the others. The answer
  // rests on the first image's group unless the other group is larger.
  const std::vector<bool> odd = contradictingImages(fused.image_coverage, fused.image_regret, st->options.evidence);
  std::vector<int> explained, other;
  for (std::size_t i = 0; i < obs.size(); ++i) (i < odd.size() && odd[i] ? other : explained).push_back(static_cast<int>(i));
  const bool first_explained = !explained.empty() && explained.front() == 0;
  const std::vector<int>& keep = first_explained ? explained : other;
  const std::vector<int>& against = first_explained ? other : explained;
  if (keep.size() < against.size() || keep.size() == obs.size()) return fused;  // the majority's answer stands
  std::vector<CameraObservation> consistent;
  for (int i : keep) consistent.push_back(obs[static_cast<std::size_t>(i)]);
  RecognitionResult anchored;
  try {
    anchored = recognizeImages(*st, consistent, static_cast<int>(obs.size() - keep.size()));
  } catch (const RecognitionError&) {
    return fused;  // the consistent images alone are not enough evidence: the flagged fused answer stands
  }
  // With two images, the left-out one only flipped the answer if the first alone answers another class;
  // otherwise the fused result (two views) stands, flagged. With more, the consistent group's answer.
  if (obs.size() == 2 && anchored.textile_id == fused.textile_id &&
      (anchored.canonical_hold_point - fused.canonical_hold_point).norm() < 1e-6)
    return fused;
  anchored.answer_images = keep;
  anchored.total_ms += fused.total_ms;
  std::string left_out;
  for (std::size_t i = 0; i < obs.size(); ++i)
    if (std::find(keep.begin(), keep.end(), static_cast<int>(i)) == keep.end())
      left_out += (left_out.empty() ? "" : ", ") + std::to_string(i);
  anchored.warnings.push_back("image(s) " + left_out + " contradict the others (evidence.contradiction_gap / contradiction_regret): left out of the "
                              "answer, confidence halved per image, grasp points less trusted");
  return anchored;
}

// The stages and what they pass on: src/recognition/recognizer_stages.h.
RecognitionResult TextileRecognizer::recognizeImages(const State& state, const std::vector<CameraObservation>& obs,
                                                     int left_out_contradicting) const {
  const State* st = &state;
  detail::RecognitionRun run(*db_, *st, obs);
  run.left_out_contradicting = left_out_contradicting;
  detail::checkLoadedState(run, db_->path());
  detail::prepareImages(run);
  detail::coarseQuery(run);
  detail::refineClasses(run);
  detail::rankCandidates(run);
  detail::fitDepth(run);
  detail::assembleResult(run);
  detail::addGraspPoses(run);
  detail::checkResultEvidence(run);
  return std::move(run.res);
}


cv::Mat TextileRecognizer::debugImage(const CameraObservation& obs, const RecognitionResult& r) const {
  if (r.geometry.empty() || r.simulation_id <= 0)
    fail(RecognitionErrorCode::kInvalidOptions, "debugImage needs the result of a successful recognize()");
  const HoldGeometry& g = r.geometry.front();
  cv::Mat out;
  if (!obs.image.empty())
    out = toBgr8(obs.image, obs.encoding).clone();
  else
    out = cv::Mat(g.intrinsics.height, g.intrinsics.width, CV_8UC3, cv::Scalar(0, 0, 0));
  if (out.cols != g.intrinsics.width || out.rows != g.intrinsics.height)
    fail(RecognitionErrorCode::kInvalidImage, "the observation does not match the result's camera");
  if (!r.image_masks.empty() && r.image_masks[0].size() == out.size()) {
    cv::Mat tint(out.size(), CV_8UC3, cv::Scalar(0, 200, 0));
    cv::Mat blended;
    cv::addWeighted(out, 0.6, tint, 0.4, 0, blended);
    blended.copyTo(out, r.image_masks[0]);
  }
  // Matched shape rendered into the camera.
  const auto sp = shape(*state(), r.simulation_id, r.hold_point);
  const VecX x = r.reflected ? reflectAcrossView(sp->positions, sp->held, r.reflection_view_deg) : sp->positions;
  const VecX ph = placeInHoldFrame(x, sp->held, r.rotation_deg);
  VecX pc(ph.size());
  for (Eigen::Index v = 0; v < ph.size() / 3; ++v) pc.segment<3>(3 * v) = g.holdToCamera(ph.segment<3>(3 * v));
  vision::ShadedRenderOptions rop;
  rop.intrinsics = g.intrinsics;
  rop.noise_sigma = 0;
  rop.render_depth = false;
  rop.render_mask = true;
  rop.render_colour = false;
  const vision::ShadedImage img = vision::renderShaded(pc, sp->triangles, rop);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(img.mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_SIMPLE);
  cv::drawContours(out, contours, -1, cv::Scalar(0, 0, 255), 2);
  auto project = [&](const Vec3& p, cv::Point* px) {
    if (!(p.z() > 1e-6)) return false;
    *px = cv::Point(static_cast<int>(std::lround(g.intrinsics.fx * p.x() / p.z() + g.intrinsics.cx)),
                    static_cast<int>(std::lround(g.intrinsics.fy * p.y() / p.z() + g.intrinsics.cy)));
    return true;
  };
  for (const GraspPose& gp : r.grasp_poses) {
    cv::Point a, b;
    if (!project(gp.position_camera, &a)) continue;
    const cv::Scalar colour = gp.kind == "corner" ? cv::Scalar(255, 0, 255) : cv::Scalar(255, 255, 0);
    cv::circle(out, a, 5, colour, 2);
    if (project(gp.position_camera + 0.05 * gp.rotation_camera.col(2), &b)) cv::line(out, a, b, cv::Scalar(255, 0, 0), 1);
    cv::putText(out, gp.name, a + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.4, colour, 1);
  }
  cv::Point h;
  if (project(g.hold_camera, &h)) cv::drawMarker(out, h, cv::Scalar(0, 255, 255), cv::MARKER_CROSS, 14, 2);
  std::ostringstream os;
  os.precision(3);
  os << r.textile_name << "  hold (" << r.hold_point.x() << ", " << r.hold_point.y() << ") m  view " << r.view_angle_deg
     << " deg  score " << r.score << "  conf " << r.confidence;
  cv::putText(out, os.str(), cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3);
  cv::putText(out, os.str(), cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1);
  return out;
}

std::vector<std::size_t> chooseFusionPartners(double yaw_deg, const std::vector<double>& earlier_yaws_deg, int max_views,
                                              double min_separation_deg) {
  std::vector<std::size_t> chosen;
  std::vector<double> yaws{yaw_deg};
  for (std::size_t k = 0; k < earlier_yaws_deg.size() && static_cast<int>(yaws.size()) < max_views; ++k) {
    bool distinct = true;  // the partner must differ from every image already chosen
    for (double y : yaws) distinct = distinct && std::fabs(std::remainder(earlier_yaws_deg[k] - y, 360.0)) >= min_separation_deg;
    if (!distinct) continue;
    chosen.push_back(k);
    yaws.push_back(earlier_yaws_deg[k]);
  }
  return chosen;
}

}  // namespace recognition
}  // namespace textile_handling