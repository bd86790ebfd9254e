// The minimum-evidence rule of the recogniser (docs/recognition.md "Evidence"): when a result may be
// reported as a success. A match below the score or coverage floor, an image larger than the pixel
// limit, or a database that lost stored views of a selected textile (or has none yet for it) is a typed
// RecognitionError with the reason, never a low-confidence "success".
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/vision/bit_mask.h"

namespace textile_handling {
namespace recognition {

struct EvidenceOptions {
  /// Floor of the winner's silhouette IoU (refined if refined; the mean over images when fused).
  double min_score = 0.6;
  /// Floor of the winner's coverage: min(|Q and M| / |Q|, |Q and M| / |M|) of an image's canonical mask
  /// Q and the matched silhouette M rendered for it at their best shift, averaged over the images. A
  /// segmented region much larger than any stored shape (a dark or uniform frame, the background
  /// segmented as textile) covers its match but is covered by it only in part (measured 0.11-0.22).
  /// 0.6 rather than 0.7: drapes of another cloth model cover their best match 0.65-0.70 and are real
  /// textiles; their doubtful labels show in the per-point trust (grasp_point_trust.h) instead.
  double min_coverage = 0.6;
  /// Ceiling of the share of the image the colour model marks as textile (SegmentationResult::
  /// colour_fraction, every image). A cell camera sees the held textile against its backdrop; a frame
  /// that differs from the backdrop almost everywhere (dark, overexposed, covered lens, another
  /// backdrop) carries no colour evidence, even where depth still outlines a shape.
  double max_colour_fraction = 0.6;
  /// A selected textile whose loaded views (or hold points) fall short of what the database says its
  /// finished simulations stored by more than this fraction makes every result kIncompleteDatabase.
  double max_lost_view_fraction = 0.05;
  /// A selected textile without any finished simulation (still building, or never built) cannot be
  /// ruled out, so by default results are kIncompleteDatabase until it has entries; true: such
  /// textiles are left out (reported in every result's warnings) and the others are recognised.
  bool ignore_unbuilt_textiles = false;
  /// An image of a fused result whose coverage lies more than this below the best image's contradicts
  /// the others (RecognitionResult::contradicting_images: confidence halved, per-point trust weak).
  /// Consistent pairs of the same drape differ by 0.005-0.02 (test_textile_recognizer); an image of
  /// another hold point fused in by 0.15-0.35.
  double contradiction_gap = 0.1;
  /// ... or whose regret exceeds this (RecognitionResult::image_regret: the image alone matches another
  /// stored shape this much better than the fused winner): the fused winner only compromises with it.
  /// On foreign drapes the coverage gap missed most images of another drape (the compromise covers both
  /// images alike); their regrets were mostly 0.08-0.32, those of consistent pairs mostly below 0.17
  /// (docs/recognition.md, "A view that contradicts the others"). 1 disables it.
  double contradiction_regret = 0.2;

  /// Throws RecognitionError(kInvalidOptions) naming the bad field.
  void validate() const;
};

/// Which images of a fused result contradict the others (one flag per image): covered by the winner more
/// than contradiction_gap below the best image, or with a regret above contradiction_regret - except the
/// image with the least regret, so that one image always remains. `image_regret` may be empty (no
/// regret test).
std::vector<bool> contradictingImages(const std::vector<double>& image_coverage, const std::vector<double>& image_regret,
                                      const EvidenceOptions& options);

/// What one selected textile has in the database and what of it was loaded.
struct TextileCompleteness {
  std::string textile;
  db::StoredViewCount stored;          ///< finished simulations and their view_count sum
  std::int64_t loaded_views = 0;       ///< matcher entries
  std::int64_t loaded_hold_points = 0; ///< simulations with at least one loaded view
  std::int64_t damaged_views = 0;      ///< skipped by the loader (db::SkippedView)
  bool unbuilt() const { return stored.done_simulations == 0; }
};

/// Why the textile cannot be recognised reliably ("" if it can): no finished simulation (unbuilt), no
/// usable view, or more than max_lost_view_fraction of its views or simulations lost.
std::string completenessProblem(const TextileCompleteness& c, const EvidenceOptions& o);

/// Adds what one loaded index holds of c->textile to *c (views, hold points, damaged views) and appends
/// the textile's damaged views to *skipped.
void addCompleteness(const db::DrapeMatchIndex& index, TextileCompleteness* c, std::vector<db::SkippedView>* skipped);

/// The completeness problem of c, if any, goes to *problems (every result fails with
/// kIncompleteDatabase), or for an unbuilt textile with ignore_unbuilt_textiles to *warnings (every
/// result carries it).
void noteCompleteness(const TextileCompleteness& c, const EvidenceOptions& o, std::vector<std::string>* problems,
                      std::vector<std::string>* warnings);

/// One line per textile for the damaged views of `skipped` (count and the first few view / simulation
/// ids with the first reason).
std::vector<std::string> skippedViewLines(const std::vector<db::SkippedView>& skipped);

/// min(|Q and M| / |Q|, |Q and M| / |M|) at the shift within +-max_shift px that maximises the IoU; 0
/// for an empty mask.
double silhouetteCoverage(const vision::BitMask& query, const vision::BitMask& matched, int max_shift);

/// Throws RecognitionError(kInsufficientEvidence) with both values and floors when score or coverage
/// is below its floor (or not a number).
void checkEvidence(double score, double coverage, const EvidenceOptions& o);

/// Throws RecognitionError(kInsufficientEvidence) when the colour model marks more than
/// max_colour_fraction of the image as textile (a negative fraction, no colour model, passes).
void checkColourFraction(double colour_fraction, const EvidenceOptions& o);

/// Throws RecognitionError(kImageTooLarge) when width x height exceeds max_pixels (`what` names the image).
void checkPixelLimit(std::int64_t width, std::int64_t height, std::int64_t max_pixels, const std::string& what);

}  // namespace recognition
}  // namespace textile_handling
