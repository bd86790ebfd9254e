// chooseConfiguration(): the model rule, the resolution search and its evidence, bad options.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "textile_handling/db/automatic_configuration.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

/// The 30 x 30 cm square hung by a corner (small enough for several resolutions in a test).
DrapeSceneSpec hangingSquare(const std::string& hold = "corner_ul") {
  DrapeSceneSpec s = benchmarkTowelSpec(0.03, hold);
  s.textile = presetTextile("square");
  return s;
}

AutomaticChoiceOptions coarseCandidates() {
  AutomaticChoiceOptions o;
  o.spacings = {0.06, 0.04, 0.03, 0.02};
  o.views = vision::ViewSet{8, 0.0, 45.0};
  return o;
}

}  // namespace

TEST(AutomaticConfiguration, AnyAgreementTakesTheCoarsestCandidate) {
  AutomaticChoiceOptions o = coarseCandidates();
  o.named_point_tolerance_m = 10;
  o.min_mean_iou = 0;
  const AutomaticChoice c = chooseConfiguration({hangingSquare()}, o);
  EXPECT_TRUE(c.converged);
  EXPECT_EQ(c.model.name, "particle_kes");
  EXPECT_DOUBLE_EQ(c.spacing, 0.06);
  EXPECT_EQ(c.settings.integrator, IntegratorType::kSemiImplicitEuler);
  EXPECT_EQ(c.settings.policy, StepPolicy::kErrorControlled);
  // The coarsest against every finer candidate, in order.
  ASSERT_EQ(c.evidence.size(), 3u);
  const Real finer[] = {0.04, 0.03, 0.02};
  for (std::size_t j = 0; j < 3; ++j) {
    EXPECT_DOUBLE_EQ(c.evidence[j].spacing, 0.06);
    EXPECT_DOUBLE_EQ(c.evidence[j].finer_spacing, finer[j]);
    EXPECT_EQ(c.evidence[j].status, "compared");
    EXPECT_TRUE(c.evidence[j].agrees);
    EXPECT_GT(c.evidence[j].mean_iou, 0.3);  // the same drape at two resolutions, not two unrelated masks
  }
  EXPECT_NE(c.text().find("evidence particle_kes hold corner_ul d 0.06 vs 0.04"), std::string::npos) << c.text();
  EXPECT_NE(c.text().find("evidence particle_kes hold corner_ul d 0.06 vs 0.02"), std::string::npos) << c.text();
}

TEST(AutomaticConfiguration, AgreeingWithTheNextFinerAloneIsNotEnough) {
  // Distances of the coarsest drape to each finer one, then a tolerance that the next finer meets and a
  // finer one does not: the coarsest must be rejected although its first comparison agrees.
  AutomaticChoiceOptions o = coarseCandidates();
  o.named_point_tolerance_m = 10;
  o.min_mean_iou = 0;
  const AutomaticChoice all = chooseConfiguration({hangingSquare()}, o);
  ASSERT_EQ(all.evidence.size(), 3u);
  const Real next = all.evidence[0].named_point_distance;
  const Real farther = std::max(all.evidence[1].named_point_distance, all.evidence[2].named_point_distance);
  ASSERT_LT(next, farther) << all.text();  // the 6 cm square is closer to 4 cm than to 2 cm
  o.named_point_tolerance_m = 0.5 * (next + farther);
  const AutomaticChoice c = chooseConfiguration({hangingSquare()}, o);
  EXPECT_LT(c.spacing, 0.06) << c.text();
  ASSERT_GE(c.evidence.size(), 2u);
  EXPECT_DOUBLE_EQ(c.evidence[0].finer_spacing, 0.04);
  EXPECT_TRUE(c.evidence[0].agrees) << c.text();
  bool rejected = false;
  for (const AutomaticChoiceEvidence& e : c.evidence)
    if (e.spacing == 0.06 && !e.agrees) rejected = true;
  EXPECT_TRUE(rejected) << c.text();
}

TEST(AutomaticConfiguration, NoAgreementTakesTheFinestAndSaysSo) {
  AutomaticChoiceOptions o = coarseCandidates();
  o.named_point_tolerance_m = 1e-9;
  const AutomaticChoice c = chooseConfiguration({hangingSquare()}, o);
  EXPECT_FALSE(c.converged);
  EXPECT_DOUBLE_EQ(c.spacing, 0.02);
  EXPECT_EQ(c.evidence.size(), 3u);  // each candidate rejected at its first comparison
  EXPECT_NE(c.text().find("the finest that completes was taken"), std::string::npos);
}

/// The square's samples as the soft_light member makes them (bending and shear x0.5, density x0.8).
AutomaticChoiceOptions::MemberSamples softLight(const std::vector<DrapeSceneSpec>& samples, const std::string& name = "soft_light") {
  AutomaticChoiceOptions::MemberSamples m{name, samples};
  for (DrapeSceneSpec& s : m.scenes) s.material = scaledMaterial(s.material, 0.5, 0.5, 0.8, s.material.name + "_varied");
  return m;
}

TEST(AutomaticConfiguration, WithoutConvergenceACoarserGridWithMembersIsTakenWhenItCostsLess) {
  // Named points can never agree, so nothing converges; silhouettes are compared with a loose bound, so the
  // rule's silhouette condition holds and its work condition decides.
  AutomaticChoiceOptions o = coarseCandidates();
  o.spacings = {0.06, 0.03};
  o.named_point_tolerance_m = 1e-9;
  o.min_mean_iou = 0.3;
  const std::vector<DrapeSceneSpec> samples = {hangingSquare("corner_ul"), hangingSquare("centre")};
  // Ten members offered: a 6 cm run does about a sixth of the 3 cm run's work, so some fit and not all.
  for (const char* name : {"m1", "m2", "m3", "m4", "m5", "m6", "m7", "m8", "m9", "m10"})
    o.member_samples.push_back(softLight(samples, name));
  const AutomaticChoice c = chooseConfiguration(samples, o);
  EXPECT_FALSE(c.converged);
  ASSERT_FALSE(c.members.empty()) << c.text();
  EXPECT_LT(c.members.size(), 10u) << c.text();
  EXPECT_EQ(c.members.front(), "m1");  // in the order offered
  EXPECT_DOUBLE_EQ(c.spacing, 0.06);
  EXPECT_GT(c.work_with_members, 0);
  EXPECT_LT(c.work_with_members, c.work_finest) << c.text();
  EXPECT_NE(c.text().find("a coarser one with members was taken"), std::string::npos) << c.text();
  EXPECT_NE(c.text().find("members base, m1"), std::string::npos) << c.text();
  EXPECT_NE(c.text().find("over the finest's: stop"), std::string::npos) << c.text();
  // Every sample compared at 6 cm against 3 cm, once each.
  int compared = 0;
  for (const AutomaticChoiceEvidence& e : c.evidence) compared += e.spacing == 0.06 && e.finer_spacing == 0.03;
  EXPECT_EQ(compared, 2) << c.text();
}

TEST(AutomaticConfiguration, TheMembersRuleKeepsTheFinestWhenSilhouettesDisagreeOrItConverged) {
  const std::vector<DrapeSceneSpec> samples = {hangingSquare()};
  AutomaticChoiceOptions o = coarseCandidates();
  o.spacings = {0.06, 0.03};
  o.named_point_tolerance_m = 1e-9;
  o.min_mean_iou = 1.0;  // no two grids draw identical silhouettes
  o.member_samples = {softLight(samples)};
  const AutomaticChoice strict = chooseConfiguration(samples, o);
  EXPECT_FALSE(strict.converged);
  EXPECT_TRUE(strict.members.empty());
  EXPECT_DOUBLE_EQ(strict.spacing, 0.03);
  EXPECT_NE(strict.members_reason.find("no members: d 0.06 on hold corner_ul: silhouette IoU"), std::string::npos)
      << strict.text();
  EXPECT_NE(strict.text().find("the finest that completes was taken"), std::string::npos) << strict.text();

  // A member whose samples do not complete is not taken (its spacing cannot be rasterised).
  o.min_mean_iou = 0.3;
  AutomaticChoiceOptions::MemberSamples broken = softLight(samples, "broken");
  broken.scenes[0].textile.outline.clear();
  o.member_samples = {broken, softLight(samples)};
  const AutomaticChoice stopped = chooseConfiguration(samples, o);
  EXPECT_TRUE(stopped.members.empty()) << stopped.text();
  EXPECT_DOUBLE_EQ(stopped.spacing, 0.03);
  EXPECT_NE(stopped.members_reason.find("broken error:"), std::string::npos) << stopped.text();

  // Converged: the rule is not asked.
  o.named_point_tolerance_m = 10;
  o.min_mean_iou = 0;
  o.member_samples = {softLight(samples)};
  const AutomaticChoice converged = chooseConfiguration(samples, o);
  EXPECT_TRUE(converged.converged);
  EXPECT_TRUE(converged.members.empty());
  EXPECT_TRUE(converged.members_reason.empty());

  // Member samples that do not match the samples are refused.
  o.member_samples = {softLight({hangingSquare(), hangingSquare("centre")})};
  EXPECT_THROW(chooseConfiguration(samples, o), InvalidInputError);
}

TEST(AutomaticConfiguration, AFailingFinestCandidateIsNeverChosen) {
  // 10 micrometres cannot be rasterised (a 30 cm square would need 9e8 nodes): every comparison with it
  // fails, nothing converges, and the choice falls back to the finest candidate that completes.
  AutomaticChoiceOptions o = coarseCandidates();
  o.spacings = {0.06, 0.04, 1e-5};
  o.named_point_tolerance_m = 10;
  o.min_mean_iou = 0;
  const AutomaticChoice c = chooseConfiguration({hangingSquare()}, o);
  EXPECT_FALSE(c.converged);
  EXPECT_DOUBLE_EQ(c.spacing, 0.04) << c.text();
  bool failure_named = false;
  for (const AutomaticChoiceEvidence& e : c.evidence)
    failure_named |= e.finer_spacing == 1e-5 && !e.agrees && e.status.find("d 1e-05") != std::string::npos;
  EXPECT_TRUE(failure_named) << c.text();
  // No candidate completes: an error naming the runs, not a choice that fails.
  o.spacings = {2e-5, 1e-5};
  try {
    chooseConfiguration({hangingSquare()}, o);
    ADD_FAILURE() << "a choice among candidates that all fail";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("no candidate spacing completes"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("d 1e-05"), std::string::npos) << e.what();
  }
}

TEST(AutomaticConfiguration, TheChoiceIsTheCoarsestSpacingWhoseEvidenceAgrees) {
  AutomaticChoiceOptions o = coarseCandidates();
  o.named_point_tolerance_m = 0.04;
  o.min_mean_iou = 0.7;
  const AutomaticChoice c = chooseConfiguration({hangingSquare("corner_ul"), hangingSquare("centre")}, o);
  ASSERT_FALSE(c.evidence.empty());
  for (const AutomaticChoiceEvidence& e : c.evidence) {
    if (e.spacing > c.spacing) {
      // A coarser candidate was rejected: its last comparison disagrees.
      continue;
    }
    if (c.converged && e.spacing == c.spacing) {
      EXPECT_TRUE(e.agrees) << c.text();
      EXPECT_LE(e.named_point_distance, 0.04);
      EXPECT_GE(e.mean_iou, 0.7);
    }
  }
  for (Real coarser : {0.06, 0.04, 0.03}) {
    if (coarser <= c.spacing) continue;
    bool rejected = false;
    for (const AutomaticChoiceEvidence& e : c.evidence)
      if (e.spacing == coarser && !e.agrees) rejected = true;
    EXPECT_TRUE(rejected) << "candidate " << coarser << " skipped without a disagreeing comparison\n" << c.text();
  }
  if (c.converged) {
    // Both sampled holds agreed with every finer candidate.
    int at_choice = 0, finer = 0;
    for (const AutomaticChoiceEvidence& e : c.evidence) at_choice += e.spacing == c.spacing;
    for (Real f : {0.04, 0.03, 0.02}) finer += f < c.spacing;
    EXPECT_EQ(at_choice, 2 * finer);
  }
}

TEST(AutomaticConfiguration, ModelRule) {
  AutomaticChoiceOptions loose = coarseCandidates();
  loose.spacings = {0.06, 0.05};
  loose.named_point_tolerance_m = 10;
  loose.min_mean_iou = 0;
  DrapeSceneSpec table = hangingSquare();
  table.hold.clear();
  table.pinned_regions = {Eigen::Matrix<Real, 4, 1>(0.1, 0.1, 0.2, 0.2)};
  const AutomaticChoice t = chooseConfiguration({table}, loose);
  EXPECT_EQ(t.model.name, "choi_ko");
  EXPECT_NE(t.model_reason.find("supported"), std::string::npos);
  loose.question = YarnScaleQuestion::kPullOut;
  const AutomaticChoice y = chooseConfiguration({hangingSquare()}, loose);
  EXPECT_EQ(y.model.name, "yarn_woven");
  EXPECT_NE(y.text().find("pull_out"), std::string::npos);
}

TEST(AutomaticConfiguration, TheLoosestStepToleranceThatAgreesIsTaken) {
  // Generous agreement: the coarsest spacing, then the loosest step tolerance that completes and agrees.
  AutomaticChoiceOptions o = coarseCandidates();
  o.spacings = {0.06, 0.04};
  o.named_point_tolerance_m = 10;
  o.min_mean_iou = 0;
  o.error_tolerance_factors = {2, 4};
  const DrapeSceneSpec square = hangingSquare();
  const Real own = square.settings.error_tolerance;
  const AutomaticChoice loose = chooseConfiguration({square}, o);
  EXPECT_DOUBLE_EQ(loose.spacing, 0.06);
  EXPECT_DOUBLE_EQ(loose.settings.error_tolerance, 4 * own);
  ASSERT_EQ(loose.evidence.size(), 2u);  // 0.06 vs 0.04, then 4x against the own tolerance at 0.06
  EXPECT_DOUBLE_EQ(loose.evidence[1].spacing, 0.06);
  EXPECT_DOUBLE_EQ(loose.evidence[1].error_tolerance, 4 * own);
  EXPECT_DOUBLE_EQ(loose.evidence[1].reference_error_tolerance, own);
  EXPECT_EQ(loose.evidence[1].status, "compared");
  EXPECT_GT(loose.evidence[1].named_point_distance, 0);  // another run, not the own one again
  EXPECT_NE(loose.text().find("d 0.06 step tolerance"), std::string::npos) << loose.text();
  EXPECT_NE(loose.text().find("(step error tolerance"), std::string::npos) << loose.text();

  // Agreement stricter than any two runs meet: no spacing agrees (the finest is taken) and no looser step
  // tolerance agrees, so the own one is kept; both factors were tried, the loosest first.
  o.named_point_tolerance_m = 1e-9;
  const AutomaticChoice strict = chooseConfiguration({square}, o);
  EXPECT_FALSE(strict.converged);
  EXPECT_DOUBLE_EQ(strict.spacing, 0.04);
  EXPECT_DOUBLE_EQ(strict.settings.error_tolerance, own);
  ASSERT_EQ(strict.evidence.size(), 3u);
  EXPECT_DOUBLE_EQ(strict.evidence[1].error_tolerance, 4 * own);
  EXPECT_DOUBLE_EQ(strict.evidence[2].error_tolerance, 2 * own);
  EXPECT_FALSE(strict.evidence[1].agrees);
  EXPECT_FALSE(strict.evidence[2].agrees);
}

TEST(AutomaticConfiguration, BadOptionsAreNamed) {
  auto message = [](const AutomaticChoiceOptions& o, std::vector<DrapeSceneSpec> samples) -> std::string {
    try {
      chooseConfiguration(samples, o);
    } catch (const InvalidInputError& e) {
      return e.what();
    }
    return "no error";
  };
  AutomaticChoiceOptions o = coarseCandidates();
  o.spacings = {0.02};
  EXPECT_NE(message(o, {hangingSquare()}).find("spacings"), std::string::npos);
  o = coarseCandidates();
  o.spacings = {0.02, std::nan("")};
  EXPECT_NE(message(o, {hangingSquare()}).find("spacings"), std::string::npos);
  o = coarseCandidates();
  o.named_point_tolerance_m = -1;
  EXPECT_NE(message(o, {hangingSquare()}).find("named_point_tolerance_m"), std::string::npos);
  o = coarseCandidates();
  o.min_mean_iou = 2;
  EXPECT_NE(message(o, {hangingSquare()}).find("min_mean_iou"), std::string::npos);
  o = coarseCandidates();
  o.error_tolerance_factors = {0.5};
  EXPECT_NE(message(o, {hangingSquare()}).find("error_tolerance_factors"), std::string::npos);
  EXPECT_NE(message(coarseCandidates(), {}).find("no sample"), std::string::npos);
  EXPECT_THROW(yarnScaleQuestionFromString("unravel"), InvalidInputError);
}

TEST(AutomaticConfiguration, SpreadSampleTakesFarApartPoints) {
  const std::vector<Vec2> pts = {Vec2(0, 0), Vec2(0.01, 0), Vec2(0.3, 0.3), Vec2(0.3, 0), Vec2(0.15, 0.15)};
  const std::vector<Vec2> s = spreadSample(pts, 3);
  ASSERT_EQ(s.size(), 3u);
  EXPECT_EQ(s[0], Vec2(0, 0));
  EXPECT_EQ(s[1], Vec2(0.3, 0.3));
  EXPECT_EQ(s[2], Vec2(0.3, 0));
  EXPECT_EQ(spreadSample(pts, 10).size(), 5u);
  EXPECT_TRUE(spreadSample({}, 3).empty());
}
