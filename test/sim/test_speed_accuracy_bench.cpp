// The speed/accuracy benchmark's pieces: the front, its margin, and one scene run against a reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "textile_handling/bench/speed_accuracy.h"

using namespace textile_handling;

TEST(SpeedAccuracyFront, DominatedAndFailedRowsAreOffTheFront) {
  const Real nan = std::nan("");
  //                           cheap+bad  mid   dominated  expensive+good  failed
  const std::vector<Real> x = {1.0, 2.0, 3.0, 10.0, nan};
  const std::vector<Real> y = {0.10, 0.05, 0.06, 0.01, nan};
  const std::vector<bool> f = speedAccuracyFront(x, y);
  EXPECT_EQ(f, (std::vector<bool>{true, true, false, true, false}));
  EXPECT_DOUBLE_EQ(frontMargin(x, y, 1), 0.0);
  // Row 2 is beaten by row 1: 1.5x in cost, 1.2x in error -> 20 % in its weaker coordinate.
  EXPECT_NEAR(frontMargin(x, y, 2), 0.2, 1e-12);
}

TEST(SpeedAccuracyScene, ACoarseRunIsComparedWithAFinerReference) {
  AccuracyConfig c;
  c.model.label = "particle_kes";
  c.model.spec = ClothModelSpec("particle_kes");
  c.spacing = 0.06;
  AccuracyRunLimits limits;  // wall caps far above the runs' cost: this test asserts shapes, not speed
  limits.max_wall_s = 600;
  const AccuracyRun coarse = runAccuracyScene(AccuracyScene::kSquareCorner, c, limits);
  c.spacing = 0.03;
  const AccuracyRun ref = runAccuracyScene(AccuracyScene::kSquareCorner, c, limits, true);
  ASSERT_EQ(coarse.status, "rest") << coarse.note << " (" << coarse.wall_s << " s)";
  ASSERT_EQ(ref.status, "rest") << ref.note << " (" << ref.wall_s << " s)";
  EXPECT_TRUE(ref.held_at_one_point);
  const db::DrapeDifference d =
      db::measureDrapeDifference({&coarse.grid, coarse.positions}, {&ref.grid, ref.positions}, ref.view_centre,
                                 ref.differenceOptions());
  // The same square at two resolutions: the free corners differ (a 6 cm grid hangs flatter; measured 14 cm),
  // well below the 42 cm drop, and the silhouettes overlap clearly; the reference against itself is exact.
  EXPECT_LT(d.max_named_point_distance, 0.2);
  EXPECT_GT(d.max_named_point_distance, 0.0);
  EXPECT_GT(d.mean_iou, 0.5);
  const db::DrapeDifference self = db::measureDrapeDifference({&ref.grid, ref.positions}, {&ref.grid, ref.positions},
                                                              ref.view_centre, ref.differenceOptions());
  EXPECT_LT(self.max_node_distance, 1e-12);
  EXPECT_DOUBLE_EQ(self.mean_iou, 1.0);
  // A bad configuration comes back as an error row, not an exception.
  c.model.spec.set("jacobian", "no_such_choice");
  const AccuracyRun bad = runAccuracyScene(AccuracyScene::kSquareCorner, c, limits);
  EXPECT_EQ(bad.status, "error");
  EXPECT_TRUE(bad.failed());
  EXPECT_NE(bad.note.find("jacobian"), std::string::npos) << bad.note;
}

TEST(SpeedAccuracyScene, TheCompressionSceneRunsAFiveDofModel) {
  AccuracyConfig c;
  c.model.label = "yarn_woven";
  c.model.spec = ClothModelSpec("yarn_woven");
  c.spacing = 0.06;
  const AccuracyRun r = runAccuracyScene(AccuracyScene::kPushedEdges, c, AccuracyRunLimits{});
  EXPECT_EQ(r.status, "end") << r.note;
  EXPECT_EQ(r.positions.size(), 3 * static_cast<Eigen::Index>(r.nodes));
  // The moving edge travelled 12 cm towards the held one.
  Real max_x = 0;
  for (Index i = 0; i < r.nodes; ++i) max_x = std::max(max_x, r.positions[3 * i]);
  EXPECT_NEAR(max_x, 0.18, 0.01);
}

namespace {

// A small-sheet scene run with the particle model at 2 cm; its name round-trips.
AccuracyRun smallSheetAtTwoCentimetres(AccuracyScene scene, const std::string& name) {
  EXPECT_EQ(accuracySceneFromString(name), scene);
  EXPECT_EQ(toString(scene), name);
  AccuracyConfig c;
  c.model.spec = ClothModelSpec("particle_kes");
  c.spacing = 0.02;
  return runAccuracyScene(scene, c, AccuracyRunLimits{});
}

// The highest and the lowest node height [m].
std::pair<Real, Real> topAndBottom(const AccuracyRun& r) {
  Real top = -1e9, bottom = 1e9;
  for (Index i = 0; i < r.nodes; ++i) {
    top = std::max(top, r.positions[3 * i + 2]);
    bottom = std::min(bottom, r.positions[3 * i + 2]);
  }
  return {top, bottom};
}

}  // namespace

TEST(SpeedAccuracyScene, TheSmallSheetHangsFromTheMiddleOfAShortSide) {
  const AccuracyRun r = smallSheetAtTwoCentimetres(AccuracyScene::kSmallSheetEdge, "small_sheet_edge");
  ASSERT_EQ(r.status, "rest") << r.note;
  EXPECT_EQ(r.nodes, 45);  // 9 x 5 nodes on the 16 x 8 cm sheet at 2 cm
  EXPECT_TRUE(r.held_at_one_point);
  // Held at (0, 4 cm), it hangs its length down: the far corners about 16-17 cm below the 1 m hold.
  const auto [top, bottom] = topAndBottom(r);
  EXPECT_LT(top, 1.0 + 1e-3);
  EXPECT_GT(top - bottom, 0.13);
  EXPECT_LT(top - bottom, 0.18);
  EXPECT_NEAR(r.differenceOptions().frame.width_px * r.differenceOptions().frame.metres_per_pixel, 0.25, 1e-9);
}

TEST(SpeedAccuracyScene, TheSmallSquareHangsTenCentimetresFromACorner) {
  const AccuracyRun r = smallSheetAtTwoCentimetres(AccuracyScene::kSmallSquareCorner, "small_square_corner");
  ASSERT_EQ(r.status, "rest") << r.note;
  EXPECT_EQ(r.nodes, 36);  // 6 x 6 nodes on the 10 cm square at 2 cm
  EXPECT_TRUE(r.held_at_one_point);
  // It hangs from its corner: every node at or below the hold, the lowest about a diagonal (14 cm) down.
  const auto [top, bottom] = topAndBottom(r);
  EXPECT_LT(top, 1.0 + 1e-3);  // the hold is 1 m up (benchmarkTowelSpec)
  EXPECT_GT(top - bottom, 0.10);
  EXPECT_LT(top - bottom, 0.16);
  // Its silhouettes are compared in a window the square fills (0.25 m wide), not the towels' 0.8 m.
  const vision::CanonicalFrame frame = r.differenceOptions().frame;
  EXPECT_NEAR(frame.width_px * frame.metres_per_pixel, 0.25, 1e-9);
}
