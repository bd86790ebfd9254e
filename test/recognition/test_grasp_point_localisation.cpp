// locateGraspPoints / findOutlineCorners (grasp_point_localisation.h) and graspPointUncertainty
// (grasp_point_trust.h): predicted corners move to the outline corners a view with depth shows, the
// gripper's apex is ignored, unseen points keep their prediction, close labels are flagged, views that
// see different lowest points or place a corner differently are told apart; error bounds order the
// evidence, grow with the move, a doubtful label and a disagreeing view, and shrink where views agree.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include <opencv2/imgproc.hpp>

#include "textile_handling/recognition/grasp_point_localisation.h"
#include "textile_handling/recognition/grasp_point_trust.h"
#include "textile_handling/recognition/recognition_errors.h"

using namespace textile_handling;
using namespace textile_handling::recognition;

namespace {

// A square towel hanging from one corner, seen face on: a diamond in the plane y = 0 of the poses' frame
// (x right, z up, hold at the origin), 1.5 m in front of a 640 x 480 camera (camera x = x, y = -z, z = y).
const Vec3 kLeft(-0.25, 0, -0.25), kRight(0.25, 0, -0.25), kBottom(0, 0, -0.5);

// `bottom`: where the diamond's lowest corner hangs (another drape in a second view).
GraspPointView diamondView(bool with_depth = true, const Vec3& bottom = kBottom) {
  GraspPointView v;
  v.intrinsics = vision::PinholeIntrinsics{525.0, 525.0, 319.5, 239.5, 640, 480};
  v.rotation << 1, 0, 0, 0, 0, -1, 0, 1, 0;
  v.translation = Vec3(0, -0.3, 1.5);
  std::vector<cv::Point> poly;
  for (const Vec3& p : {Vec3(0, 0, 0), kRight, bottom, kLeft}) {
    const Vec3 c = v.rotation * p + v.translation;
    poly.emplace_back(static_cast<int>(std::lround(525.0 * c.x() / c.z() + 319.5)),
                      static_cast<int>(std::lround(525.0 * c.y() / c.z() + 239.5)));
  }
  v.mask = cv::Mat::zeros(480, 640, CV_8UC1);
  cv::fillPoly(v.mask, std::vector<std::vector<cv::Point>>{poly}, cv::Scalar(255));
  if (with_depth) {
    v.depth = cv::Mat(480, 640, CV_32FC1, cv::Scalar(std::nanf("")));
    v.depth.setTo(1.5f, v.mask);
  }
  return v;
}

// The diamond with 3 mm depth noise. With `fold_depth_m` > 0 its lowest point is the bottom of a fold seen
// slightly from the side: in the last 3 cm, the left half of the outline is the layer behind (going back
// up), `fold_depth_m` farther from the camera, instead of one flat sheet ending at a corner.
GraspPointView noisyDiamondView(double fold_depth_m, std::uint64_t seed) {
  GraspPointView v = diamondView();
  cv::RNG rng(seed);
  for (int y = 0; y < v.depth.rows; ++y)
    for (int x = 0; x < v.depth.cols; ++x) {
      if (v.mask.at<std::uint8_t>(y, x) == 0) continue;
      const double height = -1.5 * (y - 239.5) / 525.0 - 0.3 - kBottom.z();  // above the tip [m] (camera y = -z - 0.3)
      const bool back_layer = height < 0.03 && x < 319.5;
      v.depth.at<float>(y, x) = static_cast<float>(1.5 + (back_layer ? fold_depth_m : 0.0) + rng.gaussian(0.003));
    }
  return v;
}

GraspPointLocation located(GraspPointEvidence evidence, double shift_m, double label_margin_m, int images = 1,
                           double disagreement_m = 0) {
  GraspPointLocation L;
  L.evidence = evidence;
  L.shift_m = shift_m;
  L.label_margin_m = label_margin_m;
  L.images = images;
  L.disagreeing_images = disagreement_m > 0 ? 1 : 0;
  L.disagreement_m = disagreement_m;
  return L;
}

}  // namespace

TEST(GraspPointLocalisation, OutlineCornersOfAHangingDiamondSkipTheGrippersApex) {
  const std::vector<OutlineCorner> corners = findOutlineCorners(diamondView(), {});
  ASSERT_EQ(corners.size(), 3u);  // left, right, bottom; the top apex is the hold point
  int lowest = 0;
  for (const OutlineCorner& c : corners) {
    const double d = std::min({(c.position - kLeft).norm(), (c.position - kRight).norm(), (c.position - kBottom).norm()});
    EXPECT_LT(d, 0.01);
    EXPECT_NEAR(c.angle_deg, 90.0, 20.0);
    if (c.lowest) {
      ++lowest;
      EXPECT_LT((c.position - kBottom).norm(), 0.01);
    }
  }
  EXPECT_EQ(lowest, 1);
  // Without depth there is no 3-D outline corner.
  EXPECT_TRUE(findOutlineCorners(diamondView(false), {}).empty());
}

TEST(GraspPointLocalisation, AFoldsBottomIsRoughWhereACornersTipIsFlat) {
  // The depth noise is estimated from the image itself, so the roughness is what lies beyond it.
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    const std::vector<OutlineCorner> flat = findOutlineCorners(noisyDiamondView(0, seed), {});
    const std::vector<OutlineCorner> fold = findOutlineCorners(noisyDiamondView(0.02, seed), {});
    const auto lowest = [](const std::vector<OutlineCorner>& cs) {
      return *std::find_if(cs.begin(), cs.end(), [](const OutlineCorner& c) { return c.lowest; });
    };
    ASSERT_EQ(flat.size(), 3u);
    ASSERT_FALSE(fold.empty());
    const OutlineCorner f = lowest(flat), b = lowest(fold);
    EXPECT_NEAR(f.depth_noise_m, 0.003, 0.0006) << seed;
    EXPECT_NEAR(b.depth_noise_m, 0.003, 0.0006) << seed;
    EXPECT_LT(f.tipRoughness(), 0.0007) << f.tip_depth_residual_m << " seed " << seed;
    EXPECT_GT(b.tipRoughness(), 0.002) << b.tip_depth_residual_m << " seed " << seed;
    // The same prediction, located at each: the corner is safe, the fold's bottom is not.
    const std::vector<Vec3> predicted = {Vec3(0.01, 0, -0.49)};
    const GraspPointLocation at_corner = locateGraspPoints(predicted, {true}, {false}, {noisyDiamondView(0, seed)})[0];
    const GraspPointLocation at_fold = locateGraspPoints(predicted, {true}, {false}, {noisyDiamondView(0.02, seed)})[0];
    ASSERT_EQ(at_corner.evidence, GraspPointEvidence::kLowestPoint);
    ASSERT_EQ(at_fold.evidence, GraspPointEvidence::kLowestPoint);
    EXPECT_DOUBLE_EQ(at_corner.tip_roughness_m, f.tipRoughness());
    const GraspPointTrustOptions t;
    EXPECT_LE(graspPointUncertainty(at_corner, 0.9, 0, t), t.safe_bound_m) << seed;
    EXPECT_GT(graspPointUncertainty(at_fold, 0.9, 0, t), t.safe_bound_m) << seed;
    // Two images placing it: the flatter one counts (a corner seen edge-on can look rough).
    const GraspPointLocation both =
        locateGraspPoints(predicted, {true}, {false}, {noisyDiamondView(0.02, seed), noisyDiamondView(0, seed + 10)})[0];
    EXPECT_EQ(both.images, 2);
    EXPECT_LT(both.tip_roughness_m, 0.0007);
  }
}

TEST(GraspPointLocalisation, PredictedCornersMoveToTheDataAndUnseenPointsStay) {
  const std::vector<Vec3> predicted = {
      Vec3(-0.23, 0, -0.27),   // left corner, 2.8 cm off
      Vec3(0.25, 0.02, -0.23), // right corner, 2.8 cm off
      Vec3(0.02, 0, -0.42),    // bottom corner, 8.2 cm off (the lowest outline corner may move it 20 cm)
      Vec3(0, 0.10, -0.25),    // a corner folded behind the cloth: no outline corner near it
      Vec3(0.01, 0, -0.02),    // a corner next to the gripper: the apex is not a textile corner
      Vec3(-0.23, 0, -0.27)};  // a grasp point (not a corner) at the left corner's prediction
  const std::vector<bool> is_corner = {true, true, true, true, true, false};
  const std::vector<bool> observed = {false, false, false, false, true, true};
  const std::vector<GraspPointLocation> L = locateGraspPoints(predicted, is_corner, observed, {diamondView()});
  ASSERT_EQ(L.size(), predicted.size());
  EXPECT_EQ(L[0].evidence, GraspPointEvidence::kOutlineCorner);
  EXPECT_LT((L[0].position - kLeft).norm(), 0.01);
  EXPECT_EQ(L[1].evidence, GraspPointEvidence::kOutlineCorner);
  EXPECT_LT((L[1].position - kRight).norm(), 0.01);
  EXPECT_EQ(L[2].evidence, GraspPointEvidence::kLowestPoint);
  EXPECT_LT((L[2].position - kBottom).norm(), 0.01);
  EXPECT_NEAR(L[2].shift_m, (L[2].position - predicted[2]).norm(), 1e-12);
  EXPECT_EQ(L[2].images, 1);
  EXPECT_GT(L[2].label_margin_m, 0.15);  // the other predicted corners are far from the bottom
  for (std::size_t i : {3u, 4u, 5u}) EXPECT_EQ(L[i].position, predicted[i]) << i;
  EXPECT_EQ(L[3].evidence, GraspPointEvidence::kModel);
  EXPECT_EQ(L[4].evidence, GraspPointEvidence::kSurface);
  EXPECT_EQ(L[5].evidence, GraspPointEvidence::kSurface);
  EXPECT_FALSE(std::isfinite(L[3].label_margin_m));

  // Disabled, or a view without depth: every prediction stays.
  GraspPointLocalisationOptions off;
  off.enabled = false;
  for (const auto& located : {locateGraspPoints(predicted, is_corner, observed, {diamondView()}, off),
                              locateGraspPoints(predicted, is_corner, observed, {diamondView(false)})})
    for (std::size_t i = 0; i < predicted.size(); ++i) EXPECT_EQ(located[i].position, predicted[i]);
  EXPECT_THROW(locateGraspPoints(predicted, {true}, observed, {diamondView()}), RecognitionError);

  // Beyond the short radius a side corner stays. The lowest outline corner does not go to a corner the
  // shape hangs 11 cm higher (A, 11.7 cm away), and not to the low one (B, 15.8 cm away) either while A is
  // nearer: that label would be doubtful. With A out of the way, B takes it.
  const std::vector<GraspPointLocation> far =
      locateGraspPoints({Vec3(-0.25, 0, -0.19), Vec3(0.1, 0, -0.44), Vec3(0.15, 0, -0.55)}, {true, true, true},
                        {false, false, false}, {diamondView()});
  EXPECT_EQ(far[0].evidence, GraspPointEvidence::kModel);
  EXPECT_EQ(far[1].evidence, GraspPointEvidence::kModel);
  EXPECT_EQ(far[2].evidence, GraspPointEvidence::kModel);
  const std::vector<GraspPointLocation> low =
      locateGraspPoints({Vec3(0.1, 0, -0.30), Vec3(0.15, 0, -0.55)}, {true, true}, {false, false}, {diamondView()});
  EXPECT_EQ(low[0].evidence, GraspPointEvidence::kModel);
  EXPECT_EQ(low[1].evidence, GraspPointEvidence::kLowestPoint);
  EXPECT_LT((low[1].position - kBottom).norm(), 0.01);
}

TEST(GraspPointLocalisation, TwoPredictionsNearOneOutlineCornerGiveASmallLabelMargin) {
  const std::vector<Vec3> predicted = {Vec3(-0.01, 0, -0.48), Vec3(0.03, 0, -0.47)};
  const std::vector<GraspPointLocation> L = locateGraspPoints(predicted, {true, true}, {false, false}, {diamondView()});
  EXPECT_EQ(L[0].evidence, GraspPointEvidence::kLowestPoint);  // the nearer prediction takes it
  EXPECT_LT(L[0].label_margin_m, 0.03);
  EXPECT_EQ(L[1].evidence, GraspPointEvidence::kModel);
  // Its bound then covers the neighbour: not safe.
  const GraspPointTrustOptions t;
  EXPECT_GT(graspPointUncertainty(L[0], 0.9, 0, t), t.safe_bound_m);
  // A long move to an outline corner about as near to another prediction is not made.
  const std::vector<GraspPointLocation> far =
      locateGraspPoints({Vec3(-0.06, 0, -0.44), Vec3(0.07, 0, -0.43)}, {true, true}, {true, false}, {diamondView()});
  EXPECT_EQ(far[0].evidence, GraspPointEvidence::kSurface);
  EXPECT_EQ(far[0].position, Vec3(-0.06, 0, -0.44));
  EXPECT_EQ(far[1].evidence, GraspPointEvidence::kModel);
}

TEST(GraspPointLocalisation, ViewsThatAgreeAndViewsThatSeeAnotherLowestPoint) {
  const std::vector<Vec3> predicted = {Vec3(0.02, 0, -0.46)};  // the bottom corner, 4.5 cm off
  // Two views of the same drape: both place it at the bottom, one location from two images.
  const std::vector<GraspPointLocation> same =
      locateGraspPoints(predicted, {true}, {false}, {diamondView(), diamondView()});
  EXPECT_EQ(same[0].evidence, GraspPointEvidence::kLowestPoint);
  EXPECT_EQ(same[0].images, 2);
  EXPECT_EQ(same[0].disagreeing_images, 0);
  EXPECT_LT((same[0].position - kBottom).norm(), 0.01);
  // The second view's lowest sharp turn hangs 5 cm higher, 2.2 cm from the prediction: it is not the
  // textile's lowest point (the first view shows a lower one), and the first view places the corner
  // 6.4 cm from it: the nearer location is kept as an ordinary outline corner, with the dispute.
  const Vec3 high_bottom(0.04, 0, -0.45);
  const std::vector<OutlineCorner> alone = findOutlineCorners(diamondView(true, high_bottom), {});
  ASSERT_FALSE(alone.empty());
  EXPECT_TRUE(std::any_of(alone.begin(), alone.end(), [](const OutlineCorner& c) { return c.lowest; }));
  const std::vector<GraspPointLocation> disputed =
      locateGraspPoints(predicted, {true}, {false}, {diamondView(), diamondView(true, high_bottom)});
  EXPECT_EQ(disputed[0].evidence, GraspPointEvidence::kOutlineCorner);
  EXPECT_EQ(disputed[0].images, 1);
  EXPECT_LT((disputed[0].position - high_bottom).norm(), 0.01);
  EXPECT_EQ(disputed[0].disagreeing_images, 1);
  EXPECT_NEAR(disputed[0].disagreement_m, (kBottom - high_bottom).norm(), 0.01);
  const GraspPointTrustOptions t;
  EXPECT_GT(graspPointUncertainty(disputed[0], 0.9, 0, t), t.safe_bound_m);
  const std::vector<GraspPointLocation> one = locateGraspPoints(predicted, {true}, {false}, {diamondView()});
  EXPECT_EQ(one[0].images, 1);
  EXPECT_LT(graspPointUncertainty(same[0], 0.9, 0, t), graspPointUncertainty(one[0], 0.9, 0, t));
}

TEST(GraspPointTrust, BoundsOrderTheEvidenceAndGrowWithDoubt) {
  const GraspPointTrustOptions t;
  const double inf = std::numeric_limits<double>::infinity();
  using E = GraspPointEvidence;
  const double lowest = graspPointUncertainty(located(E::kLowestPoint, 0.01, inf), 0.9, 0, t);
  const double outline = graspPointUncertainty(located(E::kOutlineCorner, 0.01, inf), 0.9, 0, t);
  const double surface = graspPointUncertainty(located(E::kSurface, 0, inf, 0), 0.9, 0, t);
  const double model = graspPointUncertainty(located(E::kModel, 0, inf, 0), 0.9, 0, t);
  EXPECT_LE(lowest, outline);
  EXPECT_LT(outline, surface);
  EXPECT_LT(surface, model);
  EXPECT_LE(lowest, t.safe_bound_m);
  EXPECT_GT(surface, t.safe_bound_m);
  // A longer move, a doubtful label, a poor silhouette match, a contradicting image: larger bounds.
  EXPECT_GT(graspPointUncertainty(located(E::kLowestPoint, 0.10, inf), 0.9, 0, t), lowest);
  EXPECT_GT(graspPointUncertainty(located(E::kLowestPoint, 0.01, 0.01), 0.9, 0, t), lowest);
  EXPECT_DOUBLE_EQ(graspPointUncertainty(located(E::kModel, 0, inf, 0), 0.5, 0, t), 2 * model);
  EXPECT_DOUBLE_EQ(graspPointUncertainty(located(E::kLowestPoint, 0.01, inf), 0.9, 1, t), 2 * lowest);
  // A rough tip (the depth bends there beyond the noise, as at a fold's bottom): roughness_gain per metre.
  GraspPointLocation rough = located(E::kLowestPoint, 0.01, inf);
  rough.tip_roughness_m = 0.002;
  EXPECT_NEAR(graspPointUncertainty(rough, 0.9, 0, t), lowest + t.roughness_gain * 0.002, 1e-12);
  EXPECT_GT(graspPointUncertainty(rough, 0.9, 0, t), t.safe_bound_m);
  // Another image placed it 5 cm away: its bound covers that, not safe.
  const double disputed = graspPointUncertainty(located(E::kLowestPoint, 0.01, inf, 1, 0.05), 0.9, 0, t);
  EXPECT_NEAR(disputed, lowest + 0.05, 1e-12);
  EXPECT_GT(disputed, t.safe_bound_m);
  // Two images agree: a smaller bound, which a weaker silhouette match or a contradicting image (the
  // images saw the same corner) does not double.
  const double agreed = graspPointUncertainty(located(E::kLowestPoint, 0.01, inf, 2), 0.9, 0, t);
  EXPECT_NEAR(agreed, lowest - t.agreeing_m, 1e-12);
  EXPECT_DOUBLE_EQ(graspPointUncertainty(located(E::kLowestPoint, 0.01, inf, 2), 0.5 * (t.weak_score + t.weak_score_agreeing), 1, t),
                   agreed);
  EXPECT_DOUBLE_EQ(graspPointUncertainty(located(E::kLowestPoint, 0.01, inf, 2), t.weak_score_agreeing - 0.01, 0, t), 2 * agreed);
  // Bad options name their field.
  GraspPointTrustOptions bad;
  bad.surface_m = std::nan("");
  EXPECT_THROW(bad.validate(), RecognitionError);
  bad = {};
  bad.shift_gain = -1;
  EXPECT_THROW(bad.validate(), RecognitionError);
  bad = {};
  bad.weak_score_agreeing = 1.5;
  EXPECT_THROW(bad.validate(), RecognitionError);
  bad = {};
  bad.roughness_gain = std::nan("");
  EXPECT_THROW(bad.validate(), RecognitionError);
  bad = {};
  bad.agreeing_m = -0.01;
  EXPECT_THROW(bad.validate(), RecognitionError);
  GraspPointLocalisationOptions lb;
  lb.max_corner_angle_deg = 180;
  EXPECT_THROW(lb.validate(), RecognitionError);
}
