// Silhouette database and matcher: the thesis's similarity v2 (IoU) with a shift search, exact and
// pruned, plus multi-image fusion. ROS-free and OpenCV-free (hot header). See docs/vision.md.
//
// Score of a database entry E for a query Q:
//   S(Q, E) = max over |dx| <= max_dx, |dy| <= max_dy of IoU(Q, shift(E, dx, dy))   (bit_mask.h)
// The best entry per (textile, hold point) is what matters (max over its view angles). Results are
// ordered by score, ties broken by the smaller entry index; within an entry, ties between shifts are
// broken by shiftBefore() (smaller shift first). The pruned search returns exactly the brute-force
// result (same scores, entries and shifts), it only skips work that provably cannot change it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/vision/bit_mask.h"

namespace textile_handling {
namespace vision {

struct SilhouetteEntry {
  std::string textile_id;
  std::string hold_point_id;
  double view_angle_deg = 0;  ///< azimuth of the view (silhouette_renderer.h convention)
  BitMask mask;
};

struct MatchOptions {
  int max_dx = 30;  ///< shift search range [px], thesis default +-30 horizontally
  int max_dy = 5;   ///< and +-5 vertically
  int top_k = 5;    ///< number of (textile, hold point) results
  /// Reference mode: evaluate every entry at every shift with the plain bit-mask routines, no
  /// pruning (slow; for tests and for checking the pruned search).
  bool exhaustive = false;
  /// Optional coarser aggregation: when set, results are per value of (*group_of_entry)[e] (one result
  /// per such group: its best entry, or for queryFused its best (textile, hold point) member, whose
  /// views are still fused on their own) instead of per (textile, hold point). E.g. all hold points
  /// that a symmetry makes indistinguishable as one group, so that top-k means k such groups and the
  /// pruning works on them. Size must equal the database size; for queryFused all entries of one
  /// (textile, hold point) must share a group. Not owned.
  const std::vector<std::uint32_t>* group_of_entry = nullptr;
};

struct MatchResult {
  std::string textile_id;
  std::string hold_point_id;
  double view_angle_deg = 0;  ///< view of the best entry of this (textile, hold point)
  int dx = 0, dy = 0;         ///< best shift applied to the stored silhouette
  double score = 0;           ///< IoU at that shift
  /// score minus the best score of any other (textile, hold point) (0 if there is none): > 0 only for
  /// the winner, where it is the confidence margin over the runner-up.
  double margin = 0;
  std::size_t entry = 0;      ///< index of the best entry in the database
};

/// Work counters of one query (entries sum to the database size).
struct MatchStats {
  std::size_t entries = 0;            ///< database size
  std::size_t pruned_area = 0;        ///< rejected by the area bound (including the early stop)
  std::size_t pruned_projection = 0;  ///< rejected by the row/column projection bound
  std::size_t evaluated = 0;          ///< exact shift search run (may itself stop early)
  std::uint64_t shifts_evaluated = 0; ///< exact (dx, dy) intersection counts computed
};

struct QueryResult {
  std::vector<MatchResult> matches;  ///< at most top_k, best first; only scores > 0
  double margin = 0;                 ///< best minus second-best (textile, hold point) score
  MatchStats stats;
};

/// One image of a multi-image query: its mask and its view azimuth relative to the first image's
/// (relative_view_deg = 0 for the first image). Rotating the gripper (textile) by +phi about the
/// vertical axis between the images gives relative_view_deg = -phi.
struct FusionImage {
  BitMask mask;
  double relative_view_deg = 0;
};

struct FusedImageMatch {
  double view_angle_deg = 0;  ///< stored view used for this image
  std::size_t entry = 0;
  int dx = 0, dy = 0;
  double score = 0;           ///< best-shift IoU of this image against that entry
};

struct FusedMatch {
  std::string textile_id;
  std::string hold_point_id;
  double base_view_deg = 0;   ///< stored view angle matched to the first image
  double score = 0;           ///< mean of the per-image scores
  double margin = 0;          ///< as MatchResult::margin, on fused scores
  std::vector<FusedImageMatch> images;  ///< one per query image, in query order
};

struct FusedQueryResult {
  std::vector<FusedMatch> matches;
  double margin = 0;
  MatchStats stats;  ///< counts (image, entry) pairs: entries = images * database size
};

class SilhouetteMatcher {
 public:
  SilhouetteMatcher() = default;

  /// Adds an entry and returns its index. All entries must have the same (non-empty) window size.
  /// Throws std::invalid_argument for an empty window, a size different from the first entry's,
  /// a window wider or higher than 8192 px, or a non-finite view angle. An all-zero mask is allowed
  /// (it never matches).
  std::size_t add(const SilhouetteEntry& entry);
  void reserve(std::size_t n);
  void clear();

  std::size_t size() const { return meta_.size(); }
  bool empty() const { return meta_.empty(); }
  int width() const { return width_; }
  int height() const { return height_; }
  /// Metadata and mask of entry i (the mask is rebuilt from the packed store).
  SilhouetteEntry entry(std::size_t i) const;
  /// Number of distinct (textile, hold point) pairs.
  std::size_t numGroups() const { return groups_.size(); }
  /// The (textile, hold point) group of entry i (0 .. numGroups() - 1), in order of first appearance.
  std::size_t groupOf(std::size_t i) const { return static_cast<std::size_t>(meta_.at(i).group); }

  /// Top-k (textile, hold point) matches of one mask (or top-k groups of options.group_of_entry; the
  /// result names the best entry's textile and hold point). Throws std::invalid_argument for an empty
  /// database, a mask of a different size, an all-zero mask, or bad options (negative shifts, top_k < 1,
  /// a group_of_entry of the wrong size).
  QueryResult query(const BitMask& mask, const MatchOptions& options = {}) const;

  /// Multi-image fusion (docs/vision.md): for each (textile, hold point) and each of its stored view
  /// angles a (the base), image i is compared with the stored view nearest to a + relative_view_deg_i
  /// (circular distance; ties to the smaller angle in [0, 360); several entries at one angle: the best);
  /// the fused score is the mean over images of those best-shift IoUs, maximised over the base angle.
  /// Exact; pruned with per-image upper bounds. Throws as query() for each image, and for no images or
  /// a non-finite relative angle.
  FusedQueryResult queryFused(const std::vector<FusionImage>& images, const MatchOptions& options = {}) const;

 private:
  struct Meta {
    std::string textile_id, hold_point_id;
    double view_angle_deg = 0;
    int group = 0;
  };
  struct Group {
    std::string textile_id, hold_point_id;
    std::vector<std::uint32_t> entries;
  };
  friend struct MatcherAccess;

  int width_ = 0, height_ = 0, words_per_row_ = 0;
  int rows_padded_ = 0, cols_padded_ = 0;  // H, W rounded up to multiples of 8
  std::vector<Meta> meta_;
  std::vector<Group> groups_;
  std::map<std::pair<std::string, std::string>, int> group_index_;
  std::vector<std::uint64_t> words_;     // entry-major packed masks
  std::vector<std::int32_t> area_;
  std::vector<std::int16_t> bbox_;       // 4 per entry: x0, y0, x1, y1 (exclusive); all 0 if empty
  std::vector<std::int16_t> row_counts_; // rows_padded_ per entry, zero beyond H
  std::vector<std::int16_t> col_counts_; // cols_padded_ per entry, zero beyond W
  // Column counts as bytes (when H <= 255) for the 16-lane SIMD column bound; cols_padded16_ per entry.
  bool bytes_ = false;
  int cols_padded16_ = 0;
  std::vector<std::uint8_t> col_counts8_;
  std::vector<std::uint32_t> by_area_;   // entry indices sorted by (area, index)
};

}  // namespace vision
}  // namespace textile_handling
