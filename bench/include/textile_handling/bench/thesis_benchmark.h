// `drape_db bench`: the thesis's full-pipeline recognition experiment (section 11.6 of the notes)
// reproduced on held-out renders. A 64 x 46 cm cotton towel; 36 hold points (a 6 x 6 grid over one
// quadrant, edges and symmetry axes included), each simulated at the particles of its grid cell
// (bracket_hold_points) and mirrored to the other quadrants, silhouettes of 128 x 128 px over 1 m,
// a shift search of +-3 x +-2 cm (the defaults below; docs/database.md gives the reasons); held-out
// shapes of the same towel simulated with a perturbed material and at another particle resolution, at
// the mirror images of the 36 points in random quadrants; camera renders between the stored view angles
// with pixel noise; single-image and two-image accuracy, neighbour confusion, build and query times; and
// the query time at 10 000 silhouettes. Writes DIR/match_benchmark.csv (+ confusion CSV and a summary).
// Part of the benchmark library (textile_handling_bench, bench/), not of the database core.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/vision/silhouette_matcher.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

struct ThesisBenchmarkConfig {
  std::string out_dir = "out/drape_db_bench";
  bool quick = false;          ///< 3 x 3 hold points, fewer queries (a smoke run, not the experiment)
  bool resume = false;         ///< keep existing bench databases in out_dir (build time then covers only new work)
  int workers = 0;             ///< simulations at once (0 = hardware threads)
  int grid_nx = 6, grid_ny = 6;
  double spacing = 0.02;       ///< database particle spacing [m]
  double heldout_spacing = 0.016;  ///< held-out resolution [m]
  /// Canonical frame of the stored silhouettes: frame_px x frame_px pixels over frame_metres x
  /// frame_metres below the hold point.
  /// Database hold points simulated at the corners of their particle-grid cells
  /// (DrapeBuildConfig::bracket_hold_points); the held-out shapes always pin the nearest particle.
  bool bracket_hold_points = true;
  /// Simulated-time cap of every simulation [s] (slow-settling hold points need more than the builder's
  /// default at fine particle spacings).
  double max_time_s = 60.0;
  int frame_px = 128;
  double frame_metres = 1.0;
  /// Shift search range in metres (converted to pixels of the frame, rounded up): the hold point is
  /// located in the image, so the silhouettes only need aligning by the error of that location.
  /// Negative: the thesis's +-30 / +-5 px at 64 px per metre (scaled to the frame).
  double max_shift_x_m = 0.03, max_shift_y_m = 0.02;
  int pairs_per_shape = 4;     ///< image pairs per held-out shape
  int entries_10k = 10000;     ///< silhouettes of the query-time row
  std::uint64_t seed = 1;
  /// Called on the configuration of each database build before it runs, e.g. to attach progress
  /// callbacks (drape_db bench attaches its terminal progress bar). Empty: the builds report nothing.
  std::function<void(DrapeBuildConfig&)> prepare_build;
};

struct BenchmarkRow {
  std::string experiment;      ///< single_view, two_view, single_view_material, ..., query_time_10k
  std::string variant;         ///< held-out variant(s)
  long silhouettes = 0;        ///< entries in the matcher
  int hold_points = 0;         ///< hold points (groups) in the matcher
  int classes = 0;             ///< hold-point classes (up to symmetry)
  int queries = 0;
  double exact_rate = 0, within_one_rate = 0, within_one_diagonal_rate = 0, top5_rate = 0;
  double neighbour_share_of_errors = 0;
  double query_ms = 0, query_p95_ms = 0;
  double build_s = 0;          ///< database build wall time
  int simulations = 0;         ///< simulations run for the database
  std::string notes;
};

/// The canonical frame of the benchmark's silhouettes (frame_px over frame_metres, top margin 2 px per
/// 64 px). Throws std::invalid_argument for a bad size.
vision::CanonicalFrame benchmarkFrame(const ThesisBenchmarkConfig& config);
/// The shift search range of the benchmark in pixels of benchmarkFrame() (metric ranges rounded up).
vision::MatchOptions benchmarkMatchOptions(const ThesisBenchmarkConfig& config);

/// Runs the benchmark, prints a summary to stdout, writes the CSV files and returns the rows.
/// Throws on failure (database, I/O).
std::vector<BenchmarkRow> runThesisBenchmark(const ThesisBenchmarkConfig& config);

/// The CSV header and one row (columns: experiment, variant, silhouettes, hold_points, classes, queries,
/// query_ms, query_p95_ms, exact_rate, within_one_rate, within_one_diagonal_rate, top5_rate,
/// neighbour_share_of_errors, build_s, simulations, notes).
std::string benchmarkCsvHeader();
std::string benchmarkCsvRow(const BenchmarkRow& row);

}  // namespace db
}  // namespace textile_handling
