// `drape_db bench`: the thesis's full-pipeline recognition experiment (section 11.6 of the notes)
// reproduced on held-out renders. A 64 x 46 cm cotton towel; 36 hold points (a 6 x 6 grid over one
// quadrant, edges and symmetry axes included) simulated and mirrored to the other quadrants; held-out
// shapes of the same towel simulated with a perturbed material and at another particle resolution, at
// the mirror images of the 36 points in random quadrants; camera renders between the stored view angles
// with pixel noise; single-image and two-image accuracy, neighbour confusion, build and query times; and
// the query time at 10 000 silhouettes. Writes DIR/match_benchmark.csv (+ confusion CSV and a summary).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

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
  int pairs_per_shape = 4;     ///< image pairs per held-out shape
  int entries_10k = 10000;     ///< silhouettes of the query-time row
  std::uint64_t seed = 1;
  bool progress = true;
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
