// Database members: several rest shapes per hold point made different ways (start, self-collision,
// material), one class per hold point in the index, the member recorded in every row, resumable.
#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "../test_support.h"
#include "test_database.h"
#include "textile_handling/db/drape_build_members.h"
#include "textile_handling/db/drape_match_index.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

using test_support::TestDatabase;

// 30 x 30 cm square, d = 3 cm, two hold points of the fundamental domain (mirrors derived).
DrapeBuildConfig smallSquare() {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.03;
  c.hold_points = {Vec2(0.0, 0.0), Vec2(0.15, 0.0)};
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.views.count = 12;
  c.views.step_deg = 30;
  c.workers = 2;
  return c;
}

}  // namespace

TEST(DrapeBuildMembers, NamesResolveAndBadListsAreRefused) {
  const std::vector<DrapeMemberSpec> all = drapeMembersByName("standard");
  EXPECT_EQ(all.size(), standardDrapeMembers().size());
  EXPECT_EQ(all.front().name, "base");
  std::set<std::string> names;
  for (const auto& m : all) {
    EXPECT_FALSE(m.description.empty()) << m.name;
    names.insert(m.name);
  }
  EXPECT_EQ(names.size(), all.size());
  for (const char* n : {"heap", "tilted", "soft_light", "stiff_heavy", "self_collision", "heap_collision"})
    EXPECT_EQ(names.count(n), 1u) << n;
  EXPECT_EQ(drapeMembersByName("base,heap").size(), 2u);
  EXPECT_THROW(drapeMembersByName("base,heap,heap"), InvalidInputError);
  EXPECT_THROW(drapeMembersByName("crumpled"), InvalidInputError);
  EXPECT_THROW(drapeMembersByName(""), InvalidInputError);
}

TEST(DrapeBuildMembers, EveryMemberHasItsOwnParameterTextAndTheBaseKeepsTheOldOne) {
  const DrapeBuildConfig base = smallSquare();
  std::set<std::string> texts;
  for (const DrapeMemberSpec& m : standardDrapeMembers()) {
    const DrapeBuildConfig c = memberBuildConfig(base, m);
    const std::string t = DrapeDatabaseBuilder::parametersText(c);
    EXPECT_TRUE(texts.insert(t).second) << m.name << " shares its parameter text";
    EXPECT_EQ(memberOfParameters(t), m.name);
  }
  EXPECT_EQ(DrapeDatabaseBuilder::parametersText(memberBuildConfig(base, drapeMembersByName("base").front())),
            DrapeDatabaseBuilder::parametersText(base));
  const DrapeBuildConfig soft = memberBuildConfig(base, drapeMembersByName("soft_light").front());
  const DrapeSceneSpec s = DrapeDatabaseBuilder::sceneSpec(soft, Vec2(0, 0));
  EXPECT_DOUBLE_EQ(s.material.areal_density, 0.8 * base.material.areal_density);
  EXPECT_NEAR(s.material.bendMomentSI(0, 10.0), 0.5 * base.material.bendMomentSI(0, 10.0), 1e-12);
  EXPECT_NEAR(s.material.shearForceSI(1, 0.1), 0.5 * base.material.shearForceSI(1, 0.1), 1e-12);
  // Heap starts: another fold per hold point, the same on a rebuild.
  const DrapeBuildConfig heap = memberBuildConfig(base, drapeMembersByName("heap").front());
  EXPECT_EQ(DrapeDatabaseBuilder::sceneSpec(heap, Vec2(0, 0)).start_heap.seed,
            DrapeDatabaseBuilder::sceneSpec(heap, Vec2(0, 0)).start_heap.seed);
  EXPECT_NE(DrapeDatabaseBuilder::sceneSpec(heap, Vec2(0, 0)).start_heap.seed,
            DrapeDatabaseBuilder::sceneSpec(heap, Vec2(0.15, 0)).start_heap.seed);
}

TEST(DrapeBuildMembers, MembersOfAHoldPointFormOneClassAndTheBuildResumes) {
  TestDatabase t("members");
  HangingDrapeDatabase db(t.path());
  const DrapeBuildConfig base = smallSquare();
  const std::vector<DrapeMemberSpec> members = drapeMembersByName("base,heap,soft_light");
  std::vector<std::string> seen;
  const std::vector<DrapeBuildReport> reports =
      buildDrapeMembers(db, base, members, [&](const DrapeMemberSpec& m) { seen.push_back(m.name); });
  ASSERT_EQ(reports.size(), 3u);
  EXPECT_EQ(seen, (std::vector<std::string>{"base", "heap", "soft_light"}));
  for (const DrapeBuildReport& r : reports) {
    EXPECT_EQ(r.failed_now, 0) << (r.failures.empty() ? "" : r.failures.front());
    EXPECT_EQ(r.simulated_now, 2);
  }
  const auto textile = db.findTextile("square");
  ASSERT_TRUE(textile);
  const std::map<std::string, int> stored = storedMembers(db, textile->id);
  ASSERT_EQ(stored.size(), 3u);
  // Two simulated hold points, each with its mirror images (the corner 4, the edge midpoint 4).
  for (const auto& [name, n] : stored) EXPECT_EQ(n, stored.at("base")) << name;
  // The heap member's shapes differ from the base's at the same hold point.
  std::map<std::string, VecX> corner;
  for (const SimulationRecord& s : db.simulations(textile->id, SimulationStatus::kDone))
    if (s.source == MirrorKind::kIdentity && s.hold.norm() < 1e-9) corner[memberOfParameters(s.parameters)] = db.positions(s.id);
  ASSERT_EQ(corner.size(), 3u);
  EXPECT_GT((corner["heap"] - corner["base"]).cwiseAbs().maxCoeff(), 1e-3);
  // One class per hold point (up to symmetry), holding every member's rows.
  MatchIndexOptions o;
  o.textile = "square";
  const DrapeMatchIndex index = loadDrapeMatchIndex(db, o);
  EXPECT_EQ(index.classes.size(), 2u);
  std::size_t rows = 0;
  for (const auto& cl : index.classes) rows += cl.members.size();
  EXPECT_EQ(rows, index.hold_points.size());
  EXPECT_EQ(static_cast<int>(rows), stored.at("base") * 3);
  // Resume: nothing left to run.
  for (const DrapeBuildReport& r : buildDrapeMembers(db, base, members)) EXPECT_EQ(r.simulated_now, 0);
}

TEST(DrapeBuildMembers, BadMaterialVariationWritesNothing) {
  TestDatabase t("members_bad");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();
  c.material_variation.bending = 0;
  EXPECT_THROW(DrapeDatabaseBuilder(db, c), InvalidInputError);
  c.material_variation.bending = std::nan("");
  EXPECT_THROW(DrapeDatabaseBuilder(db, c), InvalidInputError);
  c = smallSquare();
  c.member = "two\nlines";
  EXPECT_THROW(DrapeDatabaseBuilder(db, c), InvalidInputError);
  EXPECT_EQ(db.counts().simulations, 0);
}
