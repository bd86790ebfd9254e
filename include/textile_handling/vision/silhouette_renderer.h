// Silhouettes of a simulated (hanging) textile mesh in the canonical frame of the thesis: hold point
// at the top centre, metric scale kept, one view per azimuth about the vertical axis through the hold
// point. ROS-free and OpenCV-free. Conventions: docs/vision.md.
//
// World: z up, metres. A view at azimuth theta (degrees) looks horizontally along
//   d(theta) = (-sin theta, cos theta, 0), with image right r(theta) = (cos theta, sin theta, 0) and image
//   down = -z; theta = 0 looks along +y with +x to the right. Increasing theta orbits the camera
//   counter-clockwise (seen from above) around the hold axis. Rotating the textile (gripper) by +phi
//   about +z is the same as changing the view azimuth by -phi.
//
// Canonical frame (CanonicalFrame): a W x H pixel window of fixed metric size (metres_per_pixel) whose
// top centre holds the hold point: the hold point maps to the continuous pixel position
// (W / 2, top_margin_px) (pixel (i, j) covers [i, i+1) x [j, j+1)). A pixel is foreground when the
// silhouette covers at least coverage_threshold of its area (estimated on a supersample x supersample
// sub-grid for meshes, computed exactly by area for camera masks).
#pragma once

#include <array>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/bit_mask.h"

namespace textile_handling {

struct ParticleTopology;
class ParticleGrid;

namespace vision {

using Triangle = std::array<Index, 3>;

/// Triangles of a particle grid: every complete grid cell (particle p, its right neighbour, the
/// right neighbour's up neighbour, p's up neighbour) gives the two triangles (p, right, right-up) and
/// (p, right-up, up). Cells with a missing corner (or inconsistent neighbours) are skipped.
std::vector<Triangle> trianglesFromTopology(const ParticleTopology& topology);

/// A coarser triangulation of the same sheet for silhouettes: blocks of stride x stride grid cells whose
/// (stride + 1)^2 nodes are all active become one cell (two triangles over its four corner nodes); every
/// complete grid cell outside such a block keeps its own two triangles, so the sheet's parameter domain
/// is covered exactly as by trianglesFromTopology() on the grid's 4-neighbour topology. Vertex indices are
/// the grid's compact indices. Why: a silhouette at about a pixel per `stride` cells looks the same (the
/// chord of a block bends off the surface by stride^2 d^2 / (8 R) for a bend of radius R), and the
/// rasteriser's cost is mostly per triangle. stride 1 gives the full triangulation. Throws
/// InvalidArgumentError for stride < 1.
std::vector<Triangle> coarseGridTriangles(const ParticleGrid& grid, int stride);

/// Canonical silhouette window. Default: 64 x 64 px covering 1.0 x 1.0 m below the hold point
/// (1/64 m per pixel), hold point 2 px below the top edge.
struct CanonicalFrame {
  int width_px = 64;
  int height_px = 64;
  double metres_per_pixel = 1.0 / 64.0;
  double top_margin_px = 2.0;
  /// Meshes are rasterised on a (supersample x supersample) sub-grid per pixel.
  int supersample = 4;
  /// Minimum covered fraction of a pixel's area for it to be foreground, in (0, 1].
  /// 0.25 keeps an edge-on sheet (one sub-pixel column wide) visible as a 1 px sliver.
  double coverage_threshold = 0.25;

  /// A frame of the given metric size: width_px pixels across width_m, height rounded to whole pixels.
  static CanonicalFrame fromMetric(double width_m, double height_m, int width_px);
  /// Throws std::invalid_argument with a reason if a field is out of range.
  void validate() const;
};

/// Pinhole intrinsics (pixel centres at integer coordinates, as in OpenCV/ROS camera_info).
struct PinholeIntrinsics {
  double fx = 525.0;
  double fy = 525.0;
  double cx = 319.5;
  double cy = 239.5;
  int width = 640;   ///< image size [px]; used by the shaded renderer (0 = not set)
  int height = 480;
};

enum class ProjectionType { kOrthographic, kPinhole };

/// How a view is projected before it is put into the canonical frame.
///  - Orthographic: parallel projection along the view direction; the canonical scale is the metric
///    scale itself.
///  - Pinhole: a camera on the view direction at horizontal distance camera_distance from the hold
///    axis, at height hold.z + camera_height, looking horizontally along d(theta). The image is mapped
///    to the canonical frame with the metric scale at the hold point's depth (camera_distance / fx),
///    exactly as canonicaliseCameraMask() does for a real camera, so the perspective (near parts look
///    bigger) is kept. The intrinsics cancel in this mapping (fx, fy, cx, cy only set the camera's own
///    pixel grid); they are kept so that the same struct describes the real camera.
struct SilhouetteProjection {
  ProjectionType type = ProjectionType::kOrthographic;
  PinholeIntrinsics intrinsics;
  double camera_distance = 1.5;  ///< [m], pinhole only; must exceed the textile's reach from the axis
  double camera_height = 0.0;    ///< camera centre height relative to the hold point [m], pinhole only

  static SilhouetteProjection orthographic() { return {}; }
  static SilhouetteProjection pinhole(const PinholeIntrinsics& k, double distance, double height = 0.0) {
    SilhouetteProjection p;
    p.type = ProjectionType::kPinhole;
    p.intrinsics = k;
    p.camera_distance = distance;
    p.camera_height = height;
    return p;
  }
};

/// View azimuths: count views at start_deg + i * step_deg. Default: the thesis's 36 views, 10 deg apart.
struct ViewSet {
  int count = 36;
  double start_deg = 0.0;
  double step_deg = 10.0;
  std::vector<double> angles() const;  ///< throws std::invalid_argument if count < 1 or step not finite
};

/// A rendered view.
struct SilhouetteView {
  double view_angle_deg = 0;
  BitMask mask;
};

/// Unit view direction d(theta), image-right r(theta) (both horizontal) for an azimuth in degrees.
Vec3 viewDirection(double azimuth_deg);
Vec3 viewRight(double azimuth_deg);

/// Renders the canonical silhouette of a triangle mesh (positions: 3 per vertex, world frame, metres)
/// held at `hold` (world, metres), seen at azimuth `azimuth_deg`.
/// Throws std::invalid_argument for: positions not a multiple of 3, non-finite positions or hold
/// point, no triangles, triangle indices out of range, an invalid frame, non-finite azimuth, or (pinhole)
/// a non-positive camera distance / focal length or a vertex not in front of the camera.
/// Parts outside the canonical window are clipped.
BitMask renderSilhouette(const VecX& positions, const std::vector<Triangle>& triangles, const Vec3& hold,
                         double azimuth_deg, const SilhouetteProjection& projection = {},
                         const CanonicalFrame& frame = {});

/// Same, with the hold point given as the index of the held particle.
BitMask renderSilhouette(const VecX& positions, const std::vector<Triangle>& triangles, Index hold_particle,
                         double azimuth_deg, const SilhouetteProjection& projection = {},
                         const CanonicalFrame& frame = {});

/// All views of `views` (default: 36 views in 10 deg steps). Throws as renderSilhouette(), and for
/// views.count < 1.
std::vector<SilhouetteView> renderViews(const VecX& positions, const std::vector<Triangle>& triangles,
                                        const Vec3& hold, const ViewSet& views = {},
                                        const SilhouetteProjection& projection = {},
                                        const CanonicalFrame& frame = {});

/// Canonical-frame position (continuous pixel coordinates, pixel (i, j) covers [i, i+1) x [j, j+1)) of a
/// world point in a given view; for tests and for marking points of interest on silhouettes.
Vec2 canonicalPixel(const Vec3& point, const Vec3& hold, double azimuth_deg,
                    const SilhouetteProjection& projection = {}, const CanonicalFrame& frame = {});

namespace detail {
/// Rasterises 2-D triangles (continuous canvas coordinates) into a byte canvas (row-major, w x h,
/// value 1 = covered). Pixel centres inside a triangle are covered; in addition every canvas row whose
/// centre line crosses a triangle gets at least one pixel (the one under the span's midpoint), so that
/// degenerate (edge-on) triangles still leave a one-pixel-wide trace.
void rasterTriangles(const std::vector<Vec2>& pts, const std::vector<Triangle>& tris, int w, int h,
                     std::vector<std::uint8_t>& canvas);
/// The same for the canvas rows [row0, row1) only: `canvas` holds those rows (row r at (r - row0) * w).
void rasterTriangleRows(const std::vector<Vec2>& pts, const std::vector<Triangle>& tris, int w, int h, int row0,
                        int row1, std::uint8_t* canvas);
/// Box-filters an (s*W) x (s*H) byte canvas to a W x H mask: pixel set when >= threshold*s*s sub-pixels.
BitMask downsampleCoverage(const std::vector<std::uint8_t>& canvas, int width, int height, int s,
                           double threshold);
/// The same for the mask rows [y0, y1) and columns [x0, x1) into `m` (W wide): `canvas` holds the canvas
/// rows [s*y0, s*y1).
void downsampleCoverageRows(const std::uint8_t* canvas, int width, int y0, int y1, int x0, int x1, int s,
                            double threshold, BitMask& m);
}  // namespace detail

}  // namespace vision
}  // namespace textile_handling
