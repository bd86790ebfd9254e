// measureDrapeDifference(): node, named-point and silhouette differences of two drapes of one textile.
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "textile_handling/db/drape_difference.h"
#include "textile_handling/vision/vision_errors.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

ParticleGrid towelGrid(Real spacing) {
  std::string error;
  ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), spacing, &error);
  EXPECT_FALSE(g.empty()) << error;
  return g;
}

/// A smooth hanging-like surface: the textile's y axis hangs down, x curls into a shallow arc.
Vec3 surface(const Vec2& q) { return Vec3(q.x(), 0.08 * std::sin(6.0 * q.x()), 1.0 - q.y()); }

VecX drapeOn(const ParticleGrid& g, const Vec3& shift = Vec3::Zero()) {
  VecX x(3 * g.numActive());
  for (Index i = 0; i < g.numActive(); ++i) x.segment<3>(3 * i) = surface(g.activePosition(i)) + shift;
  return x;
}

const Vec3 kCentre(0.32, 0.0, 1.0);

}  // namespace

TEST(DrapeDifference, IdenticalDrapesDoNotDiffer) {
  const ParticleGrid g = towelGrid(0.02);
  const DrapeDifference d = measureDrapeDifference({&g, drapeOn(g)}, {&g, drapeOn(g)}, kCentre);
  EXPECT_LT(d.max_node_distance, 1e-12);  // interpolation on the same grid: rounding only
  EXPECT_LT(d.mean_node_distance, 1e-12);
  EXPECT_DOUBLE_EQ(d.mean_iou, 1.0);
  EXPECT_DOUBLE_EQ(d.min_iou, 1.0);
}

TEST(DrapeDifference, SameSurfaceAtTwoResolutionsDiffersOnlyByInterpolation) {
  const ParticleGrid coarse = towelGrid(0.02), fine = towelGrid(0.01);
  DrapeDifferenceOptions o;
  o.named_points = {Vec2(0, 0), Vec2(0.64, 0.46), Vec2(0.32, 0.23)};
  const DrapeDifference d = measureDrapeDifference({&coarse, drapeOn(coarse)}, {&fine, drapeOn(fine)}, kCentre, o);
  // Bilinear interpolation of y = 0.08 sin(6x) over 2 cm cells: error <= h^2/8 * 0.08 * 36 = 0.14 mm.
  EXPECT_LT(d.max_node_distance, 2e-4);
  EXPECT_LT(d.max_named_point_distance, 2e-4);
  EXPECT_GT(d.min_iou, 0.95);
  // The argument order does not matter: the coarser drape is always the one interpolated.
  const DrapeDifference r = measureDrapeDifference({&fine, drapeOn(fine)}, {&coarse, drapeOn(coarse)}, kCentre, o);
  EXPECT_DOUBLE_EQ(r.max_node_distance, d.max_node_distance);
  EXPECT_DOUBLE_EQ(r.mean_iou, d.mean_iou);
}

TEST(DrapeDifference, AShiftedDrapeShowsInDistancesAndSilhouettes) {
  const ParticleGrid coarse = towelGrid(0.02), fine = towelGrid(0.01);
  DrapeDifferenceOptions o;
  o.named_points = {Vec2(0, 0)};
  const DrapeDifference d = measureDrapeDifference({&coarse, drapeOn(coarse, Vec3(0, 0, -0.1))},
                                                   {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_NEAR(d.max_node_distance, 0.1, 2e-4);
  EXPECT_NEAR(d.mean_node_distance, 0.1, 2e-4);
  EXPECT_NEAR(d.max_named_point_distance, 0.1, 2e-4);
  // 10 cm of a 46 cm drop: the silhouettes overlap by about 36/56.
  EXPECT_LT(d.mean_iou, 0.75);
  EXPECT_GT(d.mean_iou, 0.5);
  EXPECT_LE(d.min_iou, d.mean_iou);
}

TEST(DrapeDifference, BadInputIsNamed) {
  const ParticleGrid g = towelGrid(0.02);
  const ParticleGrid empty;
  auto field = [&](const SimulatedDrape& a, const SimulatedDrape& b, const Vec3& c) -> std::string {
    try {
      measureDrapeDifference(a, b, c);
    } catch (const vision::InvalidArgumentError& e) {
      return e.field();
    }
    return "no error";
  };
  EXPECT_EQ(field({nullptr, drapeOn(g)}, {&g, drapeOn(g)}, kCentre), "a.grid");
  EXPECT_EQ(field({&g, drapeOn(g)}, {&empty, VecX()}, kCentre), "b.grid");
  EXPECT_EQ(field({&g, VecX::Zero(6)}, {&g, drapeOn(g)}, kCentre), "a.positions");
  VecX nan = drapeOn(g);
  nan[4] = std::nan("");
  EXPECT_EQ(field({&g, drapeOn(g)}, {&g, nan}, kCentre), "b.positions");
  EXPECT_EQ(field({&g, drapeOn(g)}, {&g, drapeOn(g)}, Vec3(0, std::nan(""), 1)), "view_centre");
}

TEST(DrapeDifference, YawAlignmentUndoesATurnAboutTheHoldAxis) {
  const ParticleGrid coarse = towelGrid(0.02), fine = towelGrid(0.01);
  VecX turned = drapeOn(coarse);
  const Real yaw = 0.4;  // rad, about +z through kCentre
  for (Index i = 0; i < coarse.numActive(); ++i) {
    const Real x = turned[3 * i] - kCentre.x(), y = turned[3 * i + 1] - kCentre.y();
    turned[3 * i] = kCentre.x() + std::cos(yaw) * x - std::sin(yaw) * y;
    turned[3 * i + 1] = kCentre.y() + std::sin(yaw) * x + std::cos(yaw) * y;
  }
  DrapeDifferenceOptions o;
  const DrapeDifference raw = measureDrapeDifference({&coarse, turned}, {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_GT(raw.max_node_distance, 0.05);
  o.align_yaw = true;
  const DrapeDifference aligned = measureDrapeDifference({&coarse, turned}, {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_NEAR(aligned.yaw_deg, -0.4 * 180.0 / kPi, 0.05);
  EXPECT_LT(aligned.max_node_distance, 2e-4);
  EXPECT_GT(aligned.min_iou, 0.95);
}

TEST(DrapeDifference, MirrorAlignmentMatchesADrapeCurledTheOtherWay) {
  // The same surface curled to the other side (mirrored through the vertical plane y = centre.y) and
  // turned: a turn alone cannot match it; with align_mirror the mirror through x = centre.x plus a turn
  // of 180 degrees does.
  const ParticleGrid coarse = towelGrid(0.02), fine = towelGrid(0.01);
  VecX other = drapeOn(coarse);
  const Real yaw = 0.3;
  for (Index i = 0; i < coarse.numActive(); ++i) {
    const Real x = other[3 * i] - kCentre.x(), y = -(other[3 * i + 1] - kCentre.y());
    other[3 * i] = kCentre.x() + std::cos(yaw) * x - std::sin(yaw) * y;
    other[3 * i + 1] = kCentre.y() + std::sin(yaw) * x + std::cos(yaw) * y;
  }
  DrapeDifferenceOptions o;
  o.align_yaw = true;
  const DrapeDifference turned_only = measureDrapeDifference({&coarse, other}, {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_FALSE(turned_only.mirrored);
  EXPECT_GT(turned_only.max_node_distance, 0.05);
  o.align_mirror = true;
  const DrapeDifference mirrored = measureDrapeDifference({&coarse, other}, {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_TRUE(mirrored.mirrored);
  EXPECT_LT(mirrored.max_node_distance, 2e-4);
  EXPECT_GT(mirrored.min_iou, 0.95);
  // A drape curled the same way is not mirrored: the same figures as with the turn alone.
  o.align_mirror = false;
  const DrapeDifference same_way = measureDrapeDifference({&coarse, drapeOn(coarse)}, {&fine, drapeOn(fine)}, kCentre, o);
  o.align_mirror = true;
  const DrapeDifference same_way_m = measureDrapeDifference({&coarse, drapeOn(coarse)}, {&fine, drapeOn(fine)}, kCentre, o);
  EXPECT_FALSE(same_way_m.mirrored);
  EXPECT_EQ(same_way_m.max_node_distance, same_way.max_node_distance);
  EXPECT_EQ(same_way_m.mean_iou, same_way.mean_iou);
}
