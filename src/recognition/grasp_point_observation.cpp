#include "textile_handling/recognition/grasp_point_observation.h"

#include <algorithm>
#include <cmath>

namespace textile_handling {
namespace recognition {

GraspPointObservation observeGraspPoint(const Vec3& p, const std::vector<GraspPointView>& views,
                                        const GraspPointObservationOptions& o) {
  GraspPointObservation out;
  for (const GraspPointView& v : views) {
    const int w = v.intrinsics.width, h = v.intrinsics.height;
    if (v.mask.type() != CV_8UC1 || v.mask.cols != w || v.mask.rows != h) continue;
    const bool has_depth = !v.depth.empty() && v.depth.type() == CV_32FC1 && v.depth.cols == w && v.depth.rows == h;
    const Vec3 c = v.rotation * p + v.translation;
    if (!(c.z() > 1e-6) || !c.allFinite()) continue;
    const double u = v.intrinsics.fx * c.x() / c.z() + v.intrinsics.cx;
    const double r = v.intrinsics.fy * c.y() / c.z() + v.intrinsics.cy;
    const int ui = static_cast<int>(std::lround(u)), ri = static_cast<int>(std::lround(r));
    bool in_mask = false;
    double gap = -1;
    for (int dy = -o.window_px; dy <= o.window_px; ++dy) {
      for (int dx = -o.window_px; dx <= o.window_px; ++dx) {
        const int x = ui + dx, y = ri + dy;
        if (x < 0 || y < 0 || x >= w || y >= h || v.mask.at<std::uint8_t>(y, x) == 0) continue;
        in_mask = true;
        if (!has_depth) continue;
        const float d = v.depth.at<float>(y, x);
        if (!(d > 0) || !std::isfinite(d)) continue;
        const double g = std::abs(d - c.z());
        if (gap < 0 || g < gap) gap = g;
      }
    }
    if (!in_mask) continue;
    ++out.images_in_mask;
    if (gap >= 0) {
      if (out.depth_gap_m < 0 || gap < out.depth_gap_m) out.depth_gap_m = gap;
      if (gap <= o.surface_tolerance_m) ++out.images_observed;
    }
  }
  return out;
}

}  // namespace recognition
}  // namespace textile_handling
