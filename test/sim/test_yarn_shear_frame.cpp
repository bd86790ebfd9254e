// The picture-frame shear test of the yarn_woven model (bench/include/textile_handling/bench/
// yarn_shear_frame.h): friction makes loading and unloading differ (a hysteresis loop), the frame's
// stiffness rises sharply beyond the jamming angle, and a weave with more floats resists shear less
// (plain > 2/2 twill > 5-harness satin). docs/yarn_model.md, "Shear frame".
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "../test_support.h"
#include "textile_handling/bench/yarn_shear_frame.h"

namespace textile_handling {
namespace {

using test_support::ThreadScope;

// 7 x 7 yarns of the default fabric at 1 yarn/mm, closed to phi = 0.4 rad (shear 1.17 rad, past the
// jamming shear pi / 2 - phi_j = 1.07 rad) in steps of 0.05 rad and opened again.
std::vector<ShearFramePoint> frame(const std::string& weave) {
  ShearFrameSpec s;
  s.model.fabric.weave = namedWeave(weave);
  s.yarns = 7;
  s.min_angle = 0.4;
  s.angle_step = 0.05;
  s.relax_time = 0.03;
  return runShearFrame(s);
}

Real momentAt(const std::vector<ShearFramePoint>& points, Real shear, bool loading) {
  for (const ShearFramePoint& p : points)
    if (p.loading == loading && std::abs(p.shear_angle - shear) < 1e-6) return p.moment;
  ADD_FAILURE() << "no point at shear " << shear;
  return 0;
}

TEST(YarnShearFrame, HysteresisJammingAndWeaveOrder) {
  ThreadScope threads(1);
  std::map<std::string, std::vector<ShearFramePoint>> runs;
  for (const char* weave : {"plain", "twill_2_2", "satin_5"}) runs[weave] = frame(weave);
  const WovenFabric fabric;
  const Real jamming_shear = kPi / 2 - fabric.jammingAngle();
  for (const auto& [weave, points] : runs) {
    ASSERT_EQ(points.size(), 46u) << weave;  // 23 steps closing, 23 opening back to pi / 2
    // Hysteresis: at the same angle the frame pushes harder closing than opening; the loop encloses
    // dissipated work.
    for (Real shear : {0.3, 0.6, 0.9})
      EXPECT_GT(momentAt(points, shear, true), momentAt(points, shear, false) + 5e-5) << weave << " at " << shear;
    Real area = 0;
    for (std::size_t k = 1; k < points.size(); ++k)
      area += 0.5 * (points[k].moment + points[k - 1].moment) * (points[k].shear_angle - points[k - 1].shear_angle);
    EXPECT_GT(area, 5e-5) << weave;
    // Jamming: the loading stiffness past the jamming shear is many times the stiffness between 0.4
    // and 0.9 rad, where friction and elastic shear alone resist.
    const Real mid = (momentAt(points, 0.9, true) - momentAt(points, 0.4, true)) / 0.5;
    const Real last = (momentAt(points, 1.15, true) - momentAt(points, 1.1, true)) / 0.05;
    ASSERT_GT(1.1, jamming_shear);
    EXPECT_GT(mid, 0) << weave;
    EXPECT_GT(last, 10 * mid) << weave;
  }
  // More floats, less shear resistance (the source's shear-frame figure).
  for (Real shear : {0.4, 0.8}) {
    EXPECT_GT(momentAt(runs["plain"], shear, true), momentAt(runs["twill_2_2"], shear, true)) << shear;
    EXPECT_GT(momentAt(runs["twill_2_2"], shear, true), momentAt(runs["satin_5"], shear, true)) << shear;
  }
}

}  // namespace
}  // namespace textile_handling
