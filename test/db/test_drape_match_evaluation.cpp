// Counting of the held-out evaluation (drape_match_evaluation.h) on a hand-built index: exact, lattice
// neighbours, top-5 and answers outside the index (foreign distractors).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "textile_handling/db/drape_match_evaluation.h"
#include "textile_handling/db/drape_match_index.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

// A filled rectangle [x0, x1) x [y0, y1) in a 64 x 64 window.
vision::BitMask box(int x0, int y0, int x1, int y1) {
  vision::BitMask m(64, 64);
  for (int y = y0; y < y1; ++y) m.setSpan(y, x0, x1);
  return m;
}

// Three hold points on one lattice row (0,0), (0,1), (0,2), one view each, shapes of growing width.
DrapeMatchIndex threePointIndex() {
  DrapeMatchIndex index;
  for (int k = 0; k < 3; ++k) {
    IndexedHoldPoint hp;
    hp.simulation_id = 10 + k;
    hp.textile = "cloth";
    hp.hold = Vec2(0.1 * k, 0.0);
    hp.lattice_i = 0;
    hp.lattice_j = k;
    hp.class_index = static_cast<std::size_t>(k);
    index.hold_points.push_back(hp);
    HoldPointClass c;
    c.textile = "cloth";
    c.canonical_hold = hp.hold;
    c.members = {static_cast<std::size_t>(k)};
    index.classes.push_back(c);
    index.hold_point_of_group[std::to_string(hp.simulation_id)] = static_cast<std::size_t>(k);
    vision::SilhouetteEntry e;
    e.textile_id = "cloth";
    e.hold_point_id = std::to_string(hp.simulation_id);
    e.view_angle_deg = 0;
    e.mask = box(24, 2, 40 + 8 * k, 50);
    index.matcher.add(e);
    index.entry_view_ids.push_back(100 + k);
  }
  index.symmetry["cloth"] = TextileSymmetry{};
  return index;
}

}  // namespace

TEST(DrapeMatchEvaluation, CountsExactNeighbourAndTop5) {
  const DrapeMatchIndex index = threePointIndex();
  EvaluationOptions o;
  o.match.max_dx = 2;
  o.match.max_dy = 2;
  HeldOutPair p;
  p.truth_class = 0;
  p.a1 = 3;
  p.a2 = 93;
  p.m1 = box(24, 2, 40, 50);  // exactly hold point 0
  p.m2 = box(24, 2, 48, 50);  // exactly hold point 1: a 4-neighbour of the truth
  const auto [single, fused] = evaluatePairs(index, {p}, o);
  EXPECT_EQ(single.queries, 2);
  EXPECT_EQ(single.exact, 1);
  EXPECT_EQ(single.within_one, 2);
  EXPECT_EQ(single.top5, 2);
  EXPECT_EQ(fused.queries, 1);
}

TEST(DrapeMatchEvaluation, TopFiveCountsTheTruthBehindAForeignWinner) {
  // A foreign distractor (an entry of no loaded hold point) that wins the query is a wrong answer, but
  // the true class ranked behind it is still among the top five (it used to be dropped from top-5).
  DrapeMatchIndex index = threePointIndex();
  vision::SilhouetteEntry foreign;
  foreign.textile_id = "distractor";
  foreign.hold_point_id = "999";
  foreign.mask = box(24, 2, 41, 50);
  index.matcher.add(foreign);
  EvaluationOptions o;
  o.match.max_dx = 0;
  o.match.max_dy = 0;
  HeldOutPair p;
  p.truth_class = 0;
  p.a1 = 3;
  p.a2 = 93;
  p.m1 = box(24, 2, 41, 50);  // the distractor exactly; hold point 0 second (IoU 16/17)
  p.m2 = box(24, 2, 41, 50);
  const auto [single, fused] = evaluatePairs(index, {p}, o);
  ASSERT_EQ(single.queries, 2);
  EXPECT_EQ(single.exact, 0);
  EXPECT_EQ(single.within_one, 0);
  EXPECT_EQ(single.top5, 2);
  EXPECT_EQ((single.confusion.at({0, kForeignClass})), 2);
  EXPECT_EQ(fused.top5, 1);
}

TEST(DrapeMatchEvaluation, ShiftRangesInMetresFollowTheFrame) {
  vision::CanonicalFrame f64;  // 64 px per metre
  const vision::MatchOptions thesis = metricShiftOptions(f64, kThesisShiftXMetres, kThesisShiftYMetres);
  EXPECT_EQ(thesis.max_dx, 30);
  EXPECT_EQ(thesis.max_dy, 5);
  const vision::CanonicalFrame f128 = vision::CanonicalFrame::fromMetric(1.0, 1.0, 128);
  const vision::MatchOptions t128 = metricShiftOptions(f128, kThesisShiftXMetres, kThesisShiftYMetres, 3);
  EXPECT_EQ(t128.max_dx, 60);
  EXPECT_EQ(t128.max_dy, 10);
  EXPECT_EQ(t128.top_k, 3);
  const vision::MatchOptions small = metricShiftOptions(f128, 0.05, 0.03);
  EXPECT_EQ(small.max_dx, 7);  // 6.4 px, rounded up
  EXPECT_EQ(small.max_dy, 4);  // 3.84 px
  EXPECT_EQ(metricShiftOptions(f128, 0.0, 0.0).max_dx, 0);
  EXPECT_THROW(metricShiftOptions(f128, -0.01, 0.0), InvalidInputError);
  EXPECT_THROW(metricShiftOptions(f128, std::nan(""), 0.0), InvalidInputError);
  EXPECT_THROW(metricShiftOptions(f128, 0.01, 0.01, 0), InvalidInputError);
}

TEST(DrapeMatchEvaluation, ShiftRangesAreBoundedWithoutOverflow) {
  const vision::CanonicalFrame f128 = vision::CanonicalFrame::fromMetric(1.0, 1.0, 128);
  // Beyond the frame a shift leaves no overlap: capped at the frame size, not an overflowed int.
  const vision::MatchOptions wide = metricShiftOptions(f128, 5.0, 5.0);
  EXPECT_EQ(wide.max_dx, f128.width_px);
  EXPECT_EQ(wide.max_dy, f128.height_px);
  try {
    metricShiftOptions(f128, 1e9, 1e9);
    ADD_FAILURE() << "a 1e9 m shift range was accepted";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("shift range"), std::string::npos) << e.what();
  }
  EXPECT_THROW(metricShiftOptions(f128, 0.0, kMaxShiftMetres * 1.01), InvalidInputError);
}
