#include "textile_handling/bench/stability_scan.h"

#include <algorithm>
#include <ostream>

namespace textile_handling {

std::vector<StabilityRow> scanStability(const CompressionSceneSpec& scene, const StabilityRunSpec& run,
                                        const std::vector<Real>& dts, const std::string& label) {
  std::vector<StabilityRow> rows;
  for (Real dt : dts) {
    StabilityRunSpec r = run;
    r.dt = dt;
    StabilityRow row;
    row.model = label.empty() ? run.model.name : label;
    row.scene = toString(scene.scene);
    row.dt = dt;
    row.damping = run.damping;
    row.result = runCompressionScene(scene, r);
    rows.push_back(row);
  }
  return rows;
}

Real largestStableDt(const std::vector<StabilityRow>& rows) {
  Real best = 0;
  for (const auto& r : rows)
    if (r.result.stable) best = std::max(best, r.dt);
  return best;
}

void writeStabilityCsv(std::ostream& os, const std::vector<StabilityRow>& rows) {
  os << "model,scene,dt_s,damping,stable,reason,sim_time_s,steps,peak_rms_speed_m_s,peak_edge_stretch,wall_s\n";
  for (const auto& r : rows) {
    std::string reason = r.result.reason;
    std::replace(reason.begin(), reason.end(), ',', ';');
    std::replace(reason.begin(), reason.end(), '"', '\'');
    os << r.model << ',' << r.scene << ',' << r.dt << ',' << (r.damping ? 1 : 0) << ',' << (r.result.stable ? 1 : 0)
       << ",\"" << reason << "\"," << r.result.sim_time << ',' << r.result.steps << ',' << r.result.peak_rms_speed
       << ',' << r.result.peak_edge_stretch << ',' << r.result.wall_time << '\n';
  }
}

}  // namespace textile_handling
