// Scans of the compression scenes over fixed step sizes and the stability.csv table written by
// drape_bench (docs/choi_ko.md, "Stability under compression"). The scenes themselves are in the
// simulation core (sim/stability_scenes.h); this is the benchmark harness around them (benchmark
// library textile_handling_bench, bench/).
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "textile_handling/sim/stability_scenes.h"

namespace textile_handling {

/// One row of a stability table (the columns of DIR/stability.csv).
struct StabilityRow {
  std::string model;      ///< "choi_ko", "particle_kes" (a variant may append e.g. "/definite_fix")
  std::string scene;      ///< toString(CompressionScene)
  Real dt = 0;
  bool damping = false;
  StabilityResult result;
};

/// Runs `dts` (any order) for one model/scene/damping setting and returns one row per step.
std::vector<StabilityRow> scanStability(const CompressionSceneSpec& scene, const StabilityRunSpec& run,
                                        const std::vector<Real>& dts, const std::string& label = "");
/// Largest dt whose row is stable (0 if none).
Real largestStableDt(const std::vector<StabilityRow>& rows);
/// Writes the rows as CSV with a header row: model,scene,dt_s,damping,stable,reason,sim_time_s,
/// steps,peak_rms_speed_m_s,peak_edge_stretch,wall_s (damping and stable as 0/1).
void writeStabilityCsv(std::ostream& os, const std::vector<StabilityRow>& rows);

}  // namespace textile_handling
