// Private to the recognition core: the stages of TextileRecognizer::recognize() and the state one call
// carries from stage to stage (RecognitionRun). recognize() runs them in this order:
//
//   checkLoadedState   the state can answer (images given, indices loaded, database complete)
//   prepareImages      hold geometry, segmentation and relative view azimuths per image
//   coarseQuery        canonical masks and the coarse (fused) query of every loaded index
//   refineClasses      the top classes' members re-rendered at fine azimuths
//   rankCandidates     one candidate per class, re-ranked by refined score; the confidence
//   fitDepth           with depth: the winner's member, azimuth and chirality by the depth fit
//   assembleResult     the winner's fields, top-k and the front/back ambiguity
//   addGraspPoses      the shape fit (depth) and the grasp poses; the matched silhouette
//   checkResultEvidence  coverage and the evidence floors; warnings and timing
//
// textile_recognizer_stages.cpp holds the stages up to rankCandidates, recognizer_depth_fit.cpp the rest.
#pragma once

#include <cstddef>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "recognizer_state.h"

namespace textile_handling {
namespace recognition {
namespace detail {

/// One camera image after geometry and segmentation.
struct PreparedImage {
  HoldGeometry g;
  cv::Mat mask;      // CV_8UC1 255 = textile
  cv::Mat depth_m;   // CV_32FC1 metres (NaN = none) or empty
  bool used_depth = false;
  double relative_view_deg = 0;
  double colour_fraction = -1;
};

/// A coarse match of one loaded index.
struct Coarse {
  std::shared_ptr<const LoadedIndex> li;
  db::DrapeMatch m;
};

/// The refined fit of one member (hold point) of a refined class.
struct MemberFit {
  std::size_t hold_point = 0;
  double angle = 0;          // base angle (first image)
  double coarse_angle = 0;
  double coarse_score = -1;  // mean best-shift IoU of its best stored base view (the cheap pass)
  double score = -1;
  int dx = 0, dy = 0;
  double depth_residual = -1;
  bool reflected = false;
  double reflection_view = 0;
};

/// One candidate per coarse class: its best member (refined) or the coarse match.
struct Candidate {
  std::size_t coarse = 0;
  HoldCandidate h;
  std::size_t member = 0;  // index into fits[coarse]
};

/// What one recognize() call carries between its stages. References stay valid for the call.
struct RecognitionRun {
  RecognitionRun(const db::HangingDrapeDatabase& database, const TextileRecognizer::State& state,
                 const std::vector<CameraObservation>& observations)
      : db(database), st(state), o(state.options), obs(observations) {}

  const db::HangingDrapeDatabase& db;
  const TextileRecognizer::State& st;
  const RecognizerOptions& o;
  const std::vector<CameraObservation>& obs;
  Clock::time_point t_start = Clock::now();
  Clock::time_point t_refine;  // start of the refinement (refine_ms covers the depth fit too)

  RecognitionResult res;
  std::vector<PreparedImage> imgs;
  std::map<std::string, std::vector<vision::BitMask>> canon;  // canonical masks per frame (frameKey)
  std::vector<Coarse> coarse;                  // best first, one per (textile, canonical hold point)
  double coarse_margin_all = 0;
  std::size_t n_refine = 0;                    // classes refined (the first n_refine of coarse)
  std::vector<std::vector<MemberFit>> fits;    // per coarse entry
  std::vector<Candidate> cands;                // best first
  double confidence = 0;
  /// Images of the caller's observations left out of this run because they contradicted the others
  /// (TextileRecognizer::recognize): counted as contradicting in the result.
  int left_out_contradicting = 0;

  /// The images' masks in canonical frame `f` (computed once per frame); kSegmentationFailed if a mask
  /// falls outside the window.
  const std::vector<vision::BitMask>& canonical(const vision::CanonicalFrame& f);
  std::shared_ptr<const TextileRecognizer::StoredShape> shape(std::int64_t simulation_id, const Vec2& hold) const {
    return loadStoredShape(db, st, simulation_id, hold);
  }
  /// Azimuth turning the stored shape into image i's hold frame for base view `base_angle` [deg].
  double rotationFor(double base_angle, std::size_t i) const {
    return imgs[i].g.camera_azimuth_deg - (base_angle + imgs[i].relative_view_deg);
  }
};

/// Silhouette of shape `x` (stored shape `s`'s mesh) at azimuth `angle` [deg] in frame `f`, with image
/// `im`'s pinhole projection when RefinementOptions::camera_projection (orthographic if that throws).
vision::BitMask renderFor(const RefinementOptions& ro, const VecX& x, const TextileRecognizer::StoredShape& s, double angle,
                          const PreparedImage& im, const vision::CanonicalFrame& f);

void checkLoadedState(const RecognitionRun& run, const std::string& database_path);
void prepareImages(RecognitionRun& run);
/// The coarse query's options for one loaded index (the metric shift range in its canonical pixels).
vision::MatchOptions coarseMatchOptions(const RecognitionRun& run, const LoadedIndex& li);
/// Image i's best single-image coarse score over every loaded index (0 if nothing matches).
double bestSingleImageScore(RecognitionRun& run, std::size_t i);
void coarseQuery(RecognitionRun& run);
void refineClasses(RecognitionRun& run);
void rankCandidates(RecognitionRun& run);
void fitDepth(RecognitionRun& run);
void assembleResult(RecognitionRun& run);
void addGraspPoses(RecognitionRun& run);
void checkResultEvidence(RecognitionRun& run);

}  // namespace detail
}  // namespace recognition
}  // namespace textile_handling
