// Worker of a build pass: one job, i.e. one simulation (or one done row loaded back) and the mirror
// rows derived from it, stored in one transaction.
#include <algorithm>
#include <chrono>
#include <exception>
#include <optional>
#include <stdexcept>
#include <utility>

#include "database_sql.h"
#include "drape_build_steps.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace db {
namespace internal {

namespace {

// How far the textile hangs below the held particle [m].
Real hangingDepth(const VecX& x, Index held) {
  Real lowest = x[3 * held + 2];
  for (Eigen::Index k = 0; k < x.size() / 3; ++k) lowest = std::min(lowest, x[3 * k + 2]);
  return x[3 * held + 2] - lowest;
}

}  // namespace

std::vector<ViewInput> renderRowViews(const PassContext& ctx, const VecX& x, Index held, double* seconds) {
  const auto r0 = std::chrono::steady_clock::now();
  const DrapeBuildConfig& c = ctx.config;
  const Vec3 hold = x.segment<3>(3 * held);
  std::vector<vision::SilhouetteView> v = vision::renderViews(x, ctx.mesh.triangles, hold, c.views, c.projection, c.frame);
  std::vector<ViewInput> out;
  out.reserve(v.size());
  for (auto& s : v) out.push_back({s.view_angle_deg, std::move(s.mask)});
  *seconds = secondsSince(r0);
  return out;
}

SimulationResult simulateRow(const PassContext& ctx, const BuildJob& job, std::string* failure) {
  const DrapeBuildConfig& c = ctx.config;
  SimulationResult src;
  src.simulation_id = job.id;
  failure->clear();
  try {
    const std::optional<Vec2> at = DrapeDatabaseBuilder::bracketHold(ctx.grid, ctx.plan[job.plan_index].position, ctx.corner);
    if (!at) throw std::invalid_argument("hold point has no particle at bracket corner " + std::to_string(ctx.corner));
    DrapeSceneSpec spec = DrapeDatabaseBuilder::sceneSpec(c, *at);
    double wall = 0;
    for (int attempt = 0; attempt < (c.retry_with_smaller_steps ? 2 : 1); ++attempt) {
      if (attempt == 1) {
        spec.settings.dt_max *= 0.25;
        spec.settings.error_tolerance *= 0.25;
        spec.settings.dt = std::min(spec.settings.dt, spec.settings.dt_max);
      }
      DrapeScene scene = buildDrapeScene(spec);
      // The first attempt uses the build's rest-shape method (which itself falls back to the dynamic
      // run if its quasi-static finish fails); the retry is dynamic, with smaller steps.
      RestShapeSettings method = c.rest_shape;
      if (attempt == 1) method.method = RestShapeMethod::kDynamic;
      const RestShapeResult rs = findRestShape(scene, method);
      wall += rs.wall_seconds;
      std::string why;
      if (rs.diverged || (!rs.rest_reached && c.require_rest)) why = rs.failure;
      if (!why.empty()) {
        *failure += (failure->empty() ? "" : "; retry with dt_max " + fmt17(spec.settings.dt_max) + " s: ") + why;
        continue;
      }
      failure->clear();
      src.positions = rs.positions;
      src.rest_reached = rs.rest_reached;
      src.sim_time_s = rs.sim_time;
      src.wall_time_s = wall;
      src.steps = rs.steps;
      src.rejected_steps = rs.rejected_steps;
      src.held_particle = scene.hold_particle;
      src.hanging_depth_m = hangingDepth(src.positions, scene.hold_particle);
      src.projection = ctx.projection;
      src.frame = c.frame;
      src.views = renderRowViews(ctx, src.positions, scene.hold_particle, &src.render_time_s);
      break;
    }
  } catch (const DrapeDatabaseError&) {
    throw;
  } catch (const std::exception& e) {
    *failure = std::string("simulation error: ") + e.what();
  }
  return failure->empty() ? src : SimulationResult{};
}

SimulationResult loadDoneRow(HangingDrapeDatabase& db, std::int64_t id) {
  SimulationResult src;
  const SimulationRecord rec = db.simulation(id);
  src.positions = db.positions(id);
  src.held_particle = rec.held_particle;
  src.rest_reached = rec.rest_reached;
  src.sim_time_s = rec.sim_time_s;
  src.steps = rec.steps;
  src.rejected_steps = rec.rejected_steps;
  src.hanging_depth_m = rec.hanging_depth_m;
  if (src.held_particle < 0 || 3 * src.held_particle >= src.positions.size())
    throw BlobFormatError("simulation " + std::to_string(id) + " has no valid held particle");
  for (StoredView& v : db.views(id)) src.views.push_back({v.view_angle_deg, std::move(v.mask)});
  return src;
}

JobOutcome runJob(HangingDrapeDatabase& db, const PassContext& ctx, const BuildJob& job, const RowSimulator& simulate) {
  JobOutcome out;
  SimulationResult src = job.simulate ? simulate(job, &out.failure) : loadDoneRow(db, job.id);
  if (job.simulate && out.failure.empty() && src.simulation_id != job.id)
    throw InvalidInputError("the simulation of row " + std::to_string(job.id) + " came back as row " +
                            std::to_string(src.simulation_id));
  if (!out.failure.empty()) {
    out.superseded = !db.markFailed(job.id, out.failure, /*skip_done=*/true);
    for (std::size_t k : job.derived)
      db.markFailed(ctx.ids[k], "source simulation " + std::to_string(job.id) + " failed: " + out.failure, true);
    return out;
  }
  std::vector<SimulationResult> derived = mirrorRows(ctx, src, job.id, job.derived);
  std::vector<SimulationResult> results;
  if (job.simulate) {
    out.wall_time_s = src.wall_time_s;
    results.push_back(std::move(src));
  }
  for (auto& d : derived) results.push_back(std::move(d));
  // One transaction: the simulation, its views, its mirrors and their views.
  if (!results.empty()) out.superseded = db.storeResults(results, /*skip_done=*/true) == 0;
  return out;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
