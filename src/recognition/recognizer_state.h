// Private to the recognition core: the loaded state of a TextileRecognizer (match indices, textiles,
// completeness problems, the rest-shape cache) and the functions that load it from the drape database
// (recognizer_index_loading.cpp). Not installed; only src/recognition/*.cpp include it.
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/sim/cloth_topology.h"

namespace textile_handling {
namespace recognition {
namespace detail {

/// One loaded match index with its stored views regrouped per hold point for the refinement.
struct LoadedIndex {
  db::DrapeMatchIndex index;
  /// Stored views per hold point (index into index.hold_points), sorted by angle [deg].
  std::vector<std::vector<std::pair<double, vision::BitMask>>> views;
  double view_step_deg = 360.0;  ///< smallest spacing of stored view angles
};

using Clock = std::chrono::steady_clock;

[[noreturn]] inline void fail(RecognitionErrorCode c, const std::string& what) { throw RecognitionError(c, what); }

/// Distance of two azimuths on the circle [deg], in [0, 180].
inline double circularDistance(double a, double b) {
  const double d = std::abs(wrapDegrees(a) - wrapDegrees(b));
  return std::min(d, 360.0 - d);
}

/// An azimuth wrapped to (-180, 180] [deg].
inline double signedWrap(double a) {
  a = wrapDegrees(a);
  return a > 180.0 ? a - 360.0 : a;
}

/// Text that changes whenever a reload would load something else (textiles, generations, finished
/// simulations and their views). Throws what the database throws.
std::string databaseFingerprint(const db::HangingDrapeDatabase& db);

/// Loads the indices of the textiles `o` selects. Throws RecognitionError: kUnknownTextile (filter),
/// kDatabase (anything the database throws while loading).
std::shared_ptr<const TextileRecognizer::State> loadState(const db::HangingDrapeDatabase& db, const RecognizerOptions& o);

/// Opens the database read-only; kDatabase on failure.
std::shared_ptr<const db::HangingDrapeDatabase> openDatabase(const std::string& path);

/// The stored rest shape of a simulation, from the state's cache or loaded (and cached). kDatabase if
/// it cannot be loaded or no longer holds `expected_hold` (the database changed under the state).
std::shared_ptr<const TextileRecognizer::StoredShape> loadStoredShape(const db::HangingDrapeDatabase& db,
                                                                      const TextileRecognizer::State& st,
                                                                      std::int64_t simulation_id, const Vec2& expected_hold);

}  // namespace detail

struct TextileRecognizer::State {
  RecognizerOptions options;
  std::vector<std::shared_ptr<const detail::LoadedIndex>> indices;
  std::map<std::string, db::TextileRecord> textiles;  // all textiles, by name
  std::string fingerprint;
  std::size_t silhouettes = 0, hold_points = 0;
  std::vector<std::string> warnings;
  std::vector<db::SkippedView> skipped;       // damaged views left out
  std::vector<std::string> problems;          // completeness problems: every result is kIncompleteDatabase
  std::vector<std::string> result_warnings;   // carried by every result
  mutable std::mutex cache_mutex;  // rest shapes loaded on demand
  mutable std::map<std::int64_t, std::shared_ptr<const StoredShape>> cache;
};

struct TextileRecognizer::StoredShape {
  db::SimulationRecord record;
  db::TextileRecord textile;
  VecX positions;
  std::vector<vision::Triangle> triangles;
  /// A coarser triangulation for silhouettes (vision::coarseGridTriangles): blocks of about one pixel of
  /// the finest loaded canonical frame.
  std::vector<vision::Triangle> silhouette_triangles;
  ParticleGrid grid;
  Index held = -1;
};

}  // namespace recognition
}  // namespace textile_handling
