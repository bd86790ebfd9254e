#include "textile_handling/db/drape_difference.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/grid_prolongation.h"
#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace db {
namespace {

constexpr const char* kFunction = "measureDrapeDifference";

void checkDrape(const SimulatedDrape& d, const std::string& name) {
  if (d.grid == nullptr || d.grid->empty() || d.grid->numActive() == 0)
    throw vision::InvalidArgumentError(kFunction, name + ".grid", name + ".grid is null or empty");
  if (d.positions.size() != 3 * static_cast<Eigen::Index>(d.grid->numActive()))
    throw vision::InvalidArgumentError(kFunction, name + ".positions",
                                       name + ".positions has " + std::to_string(d.positions.size()) +
                                           " values, the grid needs 3 x " + std::to_string(d.grid->numActive()));
  if (!d.positions.allFinite())
    throw vision::InvalidArgumentError(kFunction, name + ".positions", name + ".positions holds a non-finite value");
}

// Turns node positions (3 per node) by `yaw` [rad] about the vertical axis through `centre`.
void turnAboutVertical(const Vec3& centre, Real yaw, VecX& x) {
  const Real c = std::cos(yaw), s = std::sin(yaw);
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) {
    const Real dx = x[3 * i] - centre.x(), dy = x[3 * i + 1] - centre.y();
    x[3 * i] = centre.x() + c * dx - s * dy;
    x[3 * i + 1] = centre.y() + s * dx + c * dy;
  }
}

// Mirrors node positions (3 per node) through the vertical plane x = centre.x.
void mirrorThroughVertical(const Vec3& centre, VecX& x) {
  for (Eigen::Index i = 0; i < x.size() / 3; ++i) x[3 * i] = 2 * centre.x() - x[3 * i];
}

// The least-squares turn of pa onto pb about the vertical axis through `centre` (2-D Procrustes: the angle
// maximising sum (R p_a) . p_b over horizontal offsets) [rad].
Real bestYaw(const VecX& pa, const VecX& pb, const Vec3& centre) {
  Real sin_sum = 0, cos_sum = 0;
  for (Eigen::Index i = 0; i < pa.size() / 3; ++i) {
    const Real ax = pa[3 * i] - centre.x(), ay = pa[3 * i + 1] - centre.y();
    const Real bx = pb[3 * i] - centre.x(), by = pb[3 * i + 1] - centre.y();
    cos_sum += ax * bx + ay * by;
    sin_sum += ax * by - ay * bx;
  }
  return std::atan2(sin_sum, cos_sum);
}

}  // namespace

DrapeDifference measureDrapeDifference(const SimulatedDrape& a, const SimulatedDrape& b, const Vec3& view_centre,
                                       const DrapeDifferenceOptions& options) {
  checkDrape(a, "a");
  checkDrape(b, "b");
  if (!view_centre.allFinite())
    throw vision::InvalidArgumentError(kFunction, "view_centre", "view_centre is not finite");

  // Both drapes on the finer grid (fewer nodes = coarser; equal counts: a is "fine"), interpolated once.
  const bool a_fine = a.grid->numActive() >= b.grid->numActive();
  const ParticleGrid& fine_grid = a_fine ? *a.grid : *b.grid;
  VecX pa = a_fine ? a.positions : prolongPositions(*a.grid, a.positions, fine_grid);
  const VecX pb = a_fine ? prolongPositions(*b.grid, b.positions, fine_grid) : b.positions;
  VecX a_for_silhouettes = a.positions;
  DrapeDifference out;
  // Interpolation weights sum to 1, so turning or mirroring the interpolated drape equals interpolating the
  // turned or mirrored one.
  auto align = [&](bool mirror, VecX& p, VecX& for_silhouettes) {
    if (mirror) {
      mirrorThroughVertical(view_centre, p);
      mirrorThroughVertical(view_centre, for_silhouettes);
    }
    Real yaw = 0;
    if (options.align_yaw) {
      yaw = bestYaw(p, pb, view_centre);
      turnAboutVertical(view_centre, yaw, p);
      turnAboutVertical(view_centre, yaw, for_silhouettes);
    }
    return yaw;
  };
  if (options.align_mirror) {
    VecX pm = pa, m_for_silhouettes = a_for_silhouettes;
    const Real yaw = align(false, pa, a_for_silhouettes), yaw_m = align(true, pm, m_for_silhouettes);
    out.yaw_deg = yaw * 180.0 / kPi;
    if ((pm - pb).squaredNorm() < (pa - pb).squaredNorm()) {
      pa.swap(pm);
      a_for_silhouettes.swap(m_for_silhouettes);
      out.yaw_deg = yaw_m * 180.0 / kPi;
      out.mirrored = true;
    }
  } else {
    out.yaw_deg = align(false, pa, a_for_silhouettes) * 180.0 / kPi;
  }
  const Index n = fine_grid.numActive();
  Real sum = 0;
  for (Index i = 0; i < n; ++i) {
    const Real e = (pa.segment<3>(3 * i) - pb.segment<3>(3 * i)).norm();
    sum += e;
    out.max_node_distance = std::max(out.max_node_distance, e);
  }
  out.mean_node_distance = sum / static_cast<Real>(n);
  for (const Vec2& p : options.named_points) {
    if (!p.allFinite())
      throw vision::InvalidArgumentError(kFunction, "options.named_points", "a named point is not finite");
    const Index i = fine_grid.nearestActive(p);
    out.max_named_point_distance =
        std::max(out.max_named_point_distance, (pa.segment<3>(3 * i) - pb.segment<3>(3 * i)).norm());
  }

  // Silhouettes of both meshes, each on its own triangulation.
  const std::vector<vision::Triangle> tri_a = vision::trianglesFromTopology(ParticleTopology::fromGrid(*a.grid));
  const std::vector<vision::Triangle> tri_b = vision::trianglesFromTopology(ParticleTopology::fromGrid(*b.grid));
  const std::vector<double> angles = options.views.angles();
  out.min_iou = 1;
  Real iou_sum = 0;
  for (double az : angles) {
    const vision::BitMask ma =
        vision::renderSilhouette(a_for_silhouettes, tri_a, view_centre, az, options.projection, options.frame);
    const vision::BitMask mb =
        vision::renderSilhouette(b.positions, tri_b, view_centre, az, options.projection, options.frame);
    const Real v = vision::iou(ma, mb);
    iou_sum += v;
    out.min_iou = std::min(out.min_iou, v);
  }
  out.mean_iou = iou_sum / static_cast<Real>(angles.size());
  return out;
}

}  // namespace db
}  // namespace textile_handling
