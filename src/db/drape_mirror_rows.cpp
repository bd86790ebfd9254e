// Mirror derivation of a build: the rows of a simulated hold point's mirror images, from its result.
#include <chrono>
#include <cmath>
#include <utility>

#include "drape_build_steps.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace db {

vision::BitMask flipLeftRight(const vision::BitMask& mask) {
  vision::BitMask out(mask.width(), mask.height());
  for (int y = 0; y < mask.height(); ++y)
    for (int x = 0; x < mask.width(); ++x)
      if (mask.get(x, y)) out.set(mask.width() - 1 - x, y);
  return out;
}

bool mirroredViews(const std::vector<ViewInput>& source, MirrorKind m, const std::vector<double>& angles,
                   std::vector<ViewInput>* out) {
  out->clear();
  auto wrap = [](double a) {
    a = std::fmod(a, 360.0);
    return a < 0 ? a + 360.0 : a;
  };
  std::vector<ViewInput> result;
  for (double a : angles) {
    double src_angle = a;
    bool flip = true;
    switch (m) {
      case MirrorKind::kMirrorX: src_angle = -a; break;
      case MirrorKind::kMirrorY: src_angle = 180.0 - a; break;
      case MirrorKind::kMirrorXY: src_angle = a + 180.0; flip = false; break;
      case MirrorKind::kIdentity: flip = false; break;
    }
    src_angle = wrap(src_angle);
    const ViewInput* found = nullptr;
    for (const ViewInput& v : source) {
      const double d = std::abs(wrap(v.view_angle_deg) - src_angle);
      if (std::min(d, 360.0 - d) < 1e-6) {
        found = &v;
        break;
      }
    }
    if (!found) return false;
    result.push_back({a, flip ? flipLeftRight(found->mask) : found->mask});
  }
  *out = std::move(result);
  return true;
}

namespace internal {

std::vector<SimulationResult> mirrorRows(const PassContext& ctx, const SimulationResult& src, std::int64_t source_id,
                                         const std::vector<std::size_t>& derived) {
  std::vector<SimulationResult> rows;
  if (derived.empty()) return rows;
  // The mirror images are placed relative to the source's held particle (mirrorPositions).
  const Vec3 hold_world = src.positions.segment<3>(3 * src.held_particle);
  for (std::size_t k : derived) {
    const MirrorKind m = ctx.plan[k].mirror;
    const std::vector<Index>& perm = ctx.mesh.perms.at(m);
    if (static_cast<Eigen::Index>(perm.size()) * 3 != src.positions.size())
      throw BlobFormatError("simulation " + std::to_string(source_id) + " has " +
                            std::to_string(src.positions.size() / 3) + " particles, the grid has " +
                            std::to_string(perm.size()));
    SimulationResult d;
    d.simulation_id = ctx.ids[k];
    d.positions = mirrorPositions(src.positions, perm, m, hold_world);
    d.held_particle = perm[static_cast<std::size_t>(src.held_particle)];
    d.rest_reached = src.rest_reached;
    d.sim_time_s = src.sim_time_s;
    d.wall_time_s = 0;
    d.steps = src.steps;
    d.rejected_steps = src.rejected_steps;
    d.hanging_depth_m = src.hanging_depth_m;
    d.projection = ctx.projection;
    d.frame = ctx.config.frame;
    // Views: the source's silhouettes mirrored (exact, and mirror-equivalent hold points get
    // identical silhouette sets); re-rendered only if the view set is not closed under the mirror.
    const auto r0 = std::chrono::steady_clock::now();
    if (!mirroredViews(src.views, m, ctx.view_angles, &d.views))
      d.views = renderRowViews(ctx, d.positions, d.held_particle, &d.render_time_s);
    else
      d.render_time_s = secondsSince(r0);
    rows.push_back(std::move(d));
  }
  return rows;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
