// The stored silhouettes of a drape database loaded into a SilhouetteMatcher (one SQL query, blobs
// copied straight into the matcher), and queries whose results are hold-point classes: hold points that
// the textile's mirror symmetry maps onto each other hang in mirrored shapes whose silhouette sets are
// identical, so silhouettes can only identify a hold point up to that symmetry (docs/database.md).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/vision/silhouette_matcher.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

struct MatchIndexOptions {
  std::string textile;              ///< only this textile (empty = all)
  std::optional<Real> spacing;      ///< only simulations at this particle spacing [m]
  bool include_derived = true;      ///< also the mirror-derived rows
};

/// One loaded simulation (= one (textile, hold point) group of the matcher).
struct IndexedHoldPoint {
  std::int64_t simulation_id = 0;
  std::string textile;
  Vec2 hold = Vec2::Zero();
  /// Row and column on the hold-point lattice of the loaded index: the rank of y and of x among the
  /// distinct coordinates of all loaded hold points of the textile (recomputed on loading, so rows of
  /// several builds share one lattice).
  int lattice_i = 0, lattice_j = 0;
  MirrorKind source = MirrorKind::kIdentity;
  std::size_t class_index = 0;
};

/// A stored view that the loader could not use (damaged mask blob, window size that does not match its
/// row): it is left out of the matcher and recorded here instead of failing the whole load.
struct SkippedView {
  std::int64_t view_id = 0;
  std::int64_t simulation_id = 0;
  std::string textile;
  std::string reason;
};

/// What the database says a textile has (finished simulations of the selection and the views they
/// stored, simulations.view_count), to compare with what was loaded.
struct StoredViewCount {
  std::int64_t done_simulations = 0;
  std::int64_t expected_views = 0;  ///< sum of view_count over the finished simulations
};

/// Hold points equivalent under the textile's symmetry (same canonical hold point).
struct HoldPointClass {
  std::string textile;
  Vec2 canonical_hold = Vec2::Zero();
  std::vector<std::size_t> members;  ///< indices into DrapeMatchIndex::hold_points
};

struct DrapeMatchIndex {
  vision::SilhouetteMatcher matcher;
  vision::CanonicalFrame frame;      ///< frame of every loaded mask
  std::string projection;
  std::vector<IndexedHoldPoint> hold_points;
  std::vector<HoldPointClass> classes;
  std::vector<std::int64_t> entry_view_ids;      ///< per matcher entry
  /// Class of every loaded matcher entry (index into classes): single-image queries aggregate per
  /// class in the matcher itself (SilhouetteMatcher MatchOptions::group_of_entry).
  std::vector<std::uint32_t> entry_class;
  std::map<std::string, std::size_t> hold_point_of_group;  ///< matcher hold_point_id -> hold_points index
  std::map<std::string, TextileSymmetry> symmetry;          ///< per textile name
  /// Views left out while loading (damaged), in view id order.
  std::vector<SkippedView> skipped_views;
  /// Per textile name: what the database says the selection holds (see StoredViewCount).
  std::map<std::string, StoredViewCount> stored;
  double load_seconds = 0;

  /// Matcher entries loaded for a textile.
  std::size_t loadedViews(const std::string& textile) const;

  /// The class of a textile's hold point (any point of the class, e.g. a mirrored one; 1 mm tolerance).
  std::optional<std::size_t> classOf(const std::string& textile, const Vec2& hold) const;
  /// True if some member of class a and some member of class b are equal or lattice neighbours
  /// (4-neighbours, or 8 with diagonal = true).
  bool classesNeighbour(std::size_t a, std::size_t b, bool diagonal) const;
};

/// Loads every done view (filtered) in one query. A view whose mask blob is damaged (BlobFormatError) or
/// does not match its row's window size is skipped and recorded in skipped_views. Throws NotFoundError
/// if no usable view matches (the message counts the skipped ones), InvalidInputError if the selection
/// mixes canonical frames or projections.
///
/// SQL note: every query selects finished simulations with the same filter (storedViewFilter() in the
/// source), so a further condition (e.g. an active generation) is added in one place.
DrapeMatchIndex loadDrapeMatchIndex(const HangingDrapeDatabase& db, const MatchIndexOptions& options = {});

/// Finished simulations and their stored view counts per textile name for a selection (the textile
/// filter of `options` applies; all textiles when it is empty).
std::map<std::string, StoredViewCount> countStoredViews(const HangingDrapeDatabase& db, const MatchIndexOptions& options = {});

/// Class index of a match against an entry that belongs to no loaded hold point (e.g. a foreign entry
/// added to the matcher as a distractor).
constexpr std::size_t kForeignClass = static_cast<std::size_t>(-1);

struct DrapeMatch {
  std::size_t class_index = 0;       ///< kForeignClass for entries outside the index's hold points
  std::string textile;
  Vec2 canonical_hold = Vec2::Zero();
  std::size_t hold_point = 0;        ///< the member that matched best (index into hold_points)
  std::int64_t simulation_id = 0;    ///< its simulation
  double view_angle_deg = 0;         ///< best view (single image) / base view (fusion)
  int dx = 0, dy = 0;                ///< best shift (single image; first image for fusion)
  double score = 0;
  double margin = 0;                 ///< winner only: score minus the runner-up class's score
};

struct DrapeQueryResult {
  std::vector<DrapeMatch> matches;   ///< at most top_k classes, best first
  double margin = 0;
  vision::MatchStats stats;
};

/// The thesis's shift search range, +-30 px horizontally and +-5 px vertically at 64 px per metre, in
/// metres (for frames of other resolutions).
constexpr double kThesisShiftXMetres = 30.0 / 64.0;
constexpr double kThesisShiftYMetres = 5.0 / 64.0;
/// Largest shift range [m] metricShiftOptions() accepts: a shift moves a silhouette within its canonical
/// window, and no textile window is 10 m wide; beyond it the pixel count would overflow.
constexpr double kMaxShiftMetres = 10.0;
/// Match options with the shift range given in metres, converted to whole pixels of `frame` (rounded up;
/// the known metric scale makes a range in metres mean the same at every canonical resolution) and
/// capped at the frame's width / height (a larger shift leaves no overlap).
/// Throws InvalidInputError for negative, non-finite or > kMaxShiftMetres ranges or top_k < 1.
vision::MatchOptions metricShiftOptions(const vision::CanonicalFrame& frame, double max_dx_m, double max_dy_m,
                                        int top_k = 5);

/// Top-k hold-point classes for one canonical mask (options as SilhouetteMatcher::query).
DrapeQueryResult queryDrape(const DrapeMatchIndex& index, const vision::BitMask& mask,
                            const vision::MatchOptions& options = {});
/// Top-k classes for several images with known relative view angles (SilhouetteMatcher::queryFused).
DrapeQueryResult queryDrapeFused(const DrapeMatchIndex& index, const std::vector<vision::FusionImage>& images,
                                 const vision::MatchOptions& options = {});

}  // namespace db
}  // namespace textile_handling
