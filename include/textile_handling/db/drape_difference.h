// How far apart two drapes of the same textile are, in the terms recognition uses: node positions (one
// drape interpolated onto the other's grid), named points (corners and grasp points), and silhouettes in
// the database's canonical frame. The automatic resolution choice compares a run with a finer one by it;
// the speed/accuracy benchmark compares every configuration with a fine reference by it.
#pragma once

#include <vector>

#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

/// One drape: the particle grid of the textile it was simulated on and its node positions.
struct SimulatedDrape {
  const ParticleGrid* grid = nullptr;  ///< textile frame, spacing of the run
  VecX positions;                      ///< 3 x grid->numActive() world positions [m], node after node
};

struct DrapeDifferenceOptions {
  /// Silhouette views about the vertical axis through the view centre (default 8, 45 deg apart).
  vision::ViewSet views{8, 0.0, 45.0};
  vision::SilhouetteProjection projection;  ///< orthographic by default
  vision::CanonicalFrame frame;             ///< the database's default frame (1 x 1 m at 1/64 m per pixel)
  /// Textile-frame points [m] whose distance is reported separately (the textile's named points).
  std::vector<Vec2> named_points;
  /// Turn drape `a` about the vertical axis through the view centre to fit `b` best (least squares over
  /// the finer grid's nodes) before comparing. For drapes held at one point, whose turn about that point
  /// no force fixes and which recognition finds by its views anyway.
  bool align_yaw = false;
  /// Also try drape `a` mirrored through the vertical plane x = view_centre.x (each node keeps its
  /// material point; with align_yaw any vertical plane through the centre is the same) and keep the
  /// better of the two by the sum of squared node distances. For a sheet held at one point by a model
  /// whose energy does not change under a mirror (no front or back in the material), the mirror image of
  /// a rest shape is a rest shape too, and which of the two a run reaches depends on its start and
  /// rounding.
  bool align_mirror = false;
};

struct DrapeDifference {
  Real max_node_distance = 0;         ///< [m] largest distance over the finer grid's nodes
  Real mean_node_distance = 0;        ///< [m]
  Real max_named_point_distance = 0;  ///< [m] over DrapeDifferenceOptions::named_points (0 if none)
  Real mean_iou = 0;                  ///< silhouette IoU, mean over the views
  Real min_iou = 0;                   ///< worst view
  Real yaw_deg = 0;                   ///< the turn applied to `a` (align_yaw), about +z [deg]
  bool mirrored = false;              ///< `a` was compared mirrored (align_mirror)
};

/// Compares drape `a` with drape `b` of the same textile (grids of any spacings). The drape on the
/// coarser grid is interpolated at the finer grid's nodes (prolongPositions(), bilinear inside the outline,
/// extrapolated at its edge); node and named-point distances are taken there (a named point at the finer
/// grid's node nearest to it). Silhouettes: both meshes rendered with `view_centre` [m, world] as the
/// canonical frame's hold point, IoU without shift. Shapes: a.positions 3 x a.grid->numActive(), the
/// same for b. With options.align_yaw, drape a is first turned about the vertical axis through
/// `view_centre` by the least-squares angle (closed form) and everything is measured after the turn; with
/// options.align_mirror, a mirrored copy of a is aligned too and the closer of the two is measured. Throws
/// vision::InvalidArgumentError naming the input (null or empty grid, a positions size
/// that does not match, a non-finite position or view centre).
DrapeDifference measureDrapeDifference(const SimulatedDrape& a, const SimulatedDrape& b, const Vec3& view_centre,
                                       const DrapeDifferenceOptions& options = {});

}  // namespace db
}  // namespace textile_handling
