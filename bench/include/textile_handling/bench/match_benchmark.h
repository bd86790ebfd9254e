// Query-time benchmark of the silhouette matcher (used by `drape_db bench`). Builds a synthetic
// database (procedural hanging-textile meshes rendered at 36 views, or random blobs) and times
// single-threaded queries. Nothing here asserts timings. See docs/vision.md. Part of the benchmark
// library (textile_handling_bench, bench/); the procedural hanging shapes also serve the vision and
// recognition tests.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/silhouette_matcher.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace vision {

/// Parameters of a procedural hanging textile (a stand-in for simulated rest shapes in benchmarks and
/// tests; not physics). The flat rectangle width x height [m] is held at (hold_u, hold_v) in its own
/// frame. A point at distance r from the hold point and at angle beta from the direction towards the
/// centroid (which hangs straight down, as for a rigid pendulum) is placed at angle gather * beta from
/// the downward vertical, at distance r, in the vertical plane; it is then displaced horizontally out
/// of that plane by fold_amplitude * r * sin(fold_waves * beta * 2 + fold_phase) (folds).
struct HangingShapeParams {
  double width = 0.64, height = 0.46;
  double hold_u = 0.0, hold_v = 0.46;
  double gather = 0.45;
  double fold_amplitude = 0.12;
  double fold_waves = 3.0;
  double fold_phase = 0.0;
  double spacing = 0.02;  ///< grid spacing of the generated mesh [m]
};

/// Mesh of a procedural hanging shape; the hold point is at `hold` (world) and is vertex hold_vertex.
struct SyntheticMesh {
  VecX positions;
  std::vector<Triangle> triangles;
  Vec3 hold = Vec3::Zero();
  Index hold_vertex = 0;
};
SyntheticMesh syntheticHangingMesh(const HangingShapeParams& params, const Vec3& hold = Vec3(0, 0, 1.0));

enum class BenchmarkDatabase {
  kHangingShapes,  ///< procedural hanging textiles, 36 views each; queries are perturbed renders
  kRandomBlobs,    ///< unions of random ellipses below the hold point; queries are fresh blobs
};

struct MatchBenchmarkConfig {
  BenchmarkDatabase database = BenchmarkDatabase::kHangingShapes;
  int entries = 10000;
  int queries = 200;
  CanonicalFrame frame;        ///< default 64 x 64
  MatchOptions options;        ///< default +-30 / +-5 px, top 5
  std::uint64_t seed = 1;
  int verify_queries = 0;      ///< also run this many queries exhaustively and compare (slow)
};

struct MatchBenchmarkReport {
  std::string database;
  std::size_t entries = 0;
  std::size_t groups = 0;
  int width = 0, height = 0;
  int queries = 0;
  double build_seconds = 0;
  double mean_ms = 0, median_ms = 0, p95_ms = 0, max_ms = 0;  ///< wall-clock time per query
  /// Process CPU time per query (std::clock): excludes time the query thread was preempted, so on a
  /// shared machine it estimates the wall time on an idle core.
  double mean_cpu_ms = 0, p95_cpu_ms = 0, max_cpu_ms = 0;
  double mean_entries_evaluated = 0;  ///< exact shift searches per query
  double mean_shifts_evaluated = 0;   ///< exact (dx, dy) evaluations per query
  int top1_correct = -1;              ///< queries whose true (textile, hold point) came first (-1: n/a)
  int verified = 0;                   ///< queries checked against the exhaustive search
  int verify_mismatches = 0;
};

/// Builds the configured synthetic database and times cfg.queries queries (single thread).
MatchBenchmarkReport runMatchBenchmark(const MatchBenchmarkConfig& cfg);

/// Times the given queries on an existing matcher (single thread). `truth` (optional, same length as
/// queries) names the expected "textile/hold point" for the top-1 count.
MatchBenchmarkReport benchmarkQueries(const SilhouetteMatcher& matcher, const std::vector<BitMask>& queries,
                                      const MatchOptions& options, const std::vector<std::string>& truth = {},
                                      int verify_queries = 0);

/// Human-readable multi-line summary.
std::string formatReport(const MatchBenchmarkReport& report);

}  // namespace vision
}  // namespace textile_handling
