// TextileRegistry (the core of the register_textile / resimulate / list_textiles services): requests
// are validated before anything is stored, builds run on the worker thread and report progress, a
// rebuild replaces a textile's entries, and the stored data stay consistent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <string>
#include <unistd.h>
#include <vector>

#include "textile_handling/db/database_errors.h"
#include "registry_test_support.h"
#include "textile_handling/registry/textile_registry.h"

namespace textile_handling {
namespace registry {
namespace {

using test_support::napkin;
using test_support::smallOptions;
using test_support::tempDb;

struct Events {
  std::mutex mu;
  std::vector<BuildProgressEvent> progress;
  std::vector<std::int64_t> changed;
};

TEST(TextileRegistry, RegisterBuildsInTheBackgroundAndReportsProgress) {
  Events ev;
  TextileRegistry reg(
      tempDb("register"), smallOptions(),
      [&](const BuildProgressEvent& e) {
        std::lock_guard<std::mutex> l(ev.mu);
        ev.progress.push_back(e);
      },
      [&](std::int64_t id) {
        std::lock_guard<std::mutex> l(ev.mu);
        ev.changed.push_back(id);
      });
  const QueuedBuild q = reg.registerTextile(napkin());
  EXPECT_GT(q.textile_id, 0);
  // 0.3 m square, lattice 0.15 m: 3 x 3 hold points (the quadrant's are simulated, the rest mirrored).
  EXPECT_EQ(q.hold_points, 9);
  ASSERT_TRUE(reg.waitIdle(300.0));
  const auto list = reg.list();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].record.outline.name, "napkin");
  EXPECT_EQ(list[0].record.outline.named_points.size(), 3u);
  EXPECT_EQ(list[0].counts.done, 9);
  EXPECT_EQ(list[0].counts.failed, 0);
  EXPECT_EQ(list[0].counts.views, 9 * 4);
  std::lock_guard<std::mutex> l(ev.mu);
  ASSERT_GE(ev.progress.size(), 3u);
  EXPECT_EQ(ev.progress.front().state, "queued");
  EXPECT_EQ(ev.progress[1].state, "running");
  EXPECT_EQ(ev.progress.back().state, "done") << ev.progress.back().message;
  EXPECT_EQ(ev.progress.back().textile_id, q.textile_id);
  // Running events after a finished simulation carry the builder's estimate; the last one is 0.
  bool saw_estimate = false;
  for (const auto& e : ev.progress) {
    if (e.state != "running" || e.done == 0) continue;
    EXPECT_GE(e.eta_s, 0.0);
    EXPECT_GE(e.elapsed_s, 0.0);
    if (e.done < e.total && e.eta_s > 0) saw_estimate = true;
    if (e.done == e.total) EXPECT_EQ(e.eta_s, 0.0);
  }
  EXPECT_TRUE(saw_estimate);
  EXPECT_FALSE(ev.changed.empty());
  EXPECT_EQ(ev.changed.back(), q.textile_id);
}

TEST(TextileRegistry, MalformedRequestsAreRejectedAndStoreNothing) {
  TextileRegistry reg(tempDb("bad"), smallOptions());
  auto rejected = [&](const TextileRegistration& r, const std::string& needle, const std::string& what) {
    test_support::expectRefused(reg, r, needle, what);
  };
  TextileRegistration r = napkin();
  r.name = "";
  rejected(r, "name", "empty name");
  r = napkin("../etc/passwd");
  rejected(r, "name", "path-like name");
  r = napkin();
  r.outline = {Vec2(0, 0), Vec2(0.3, 0.3), Vec2(0.3, 0), Vec2(0, 0.3)};  // bow tie
  r.named_points.clear();
  rejected(r, "outline", "self-intersecting polygon");
  r = napkin();
  r.outline = {Vec2(0, 0), Vec2(0.3, 0)};
  r.named_points.clear();
  rejected(r, "outline", "two vertices");
  r = napkin();
  r.outline = {Vec2(0, 0), Vec2(0.3, 0), Vec2(0.6, 0)};
  r.named_points.clear();
  rejected(r, "outline", "collinear (degenerate) polygon");
  r = napkin();
  r.outline[2] = Vec2(std::nan(""), 0.3);
  rejected(r, "outline", "NaN vertex");
  r = napkin();
  r.named_points.push_back({"outside", "grasp", Vec2(1.0, 1.0)});
  rejected(r, "outline", "grasp point outside");
  r = napkin();
  r.material_name = "silk_unknown";
  rejected(r, "silk_unknown", "unknown material");
  r = napkin();
  r.material_yaml = "name: broken\nareal_density: -3\n";
  rejected(r, "material", "bad material yaml");
  r = napkin();
  r.hold_point_spacing = std::nan("");
  rejected(r, "hold_point_spacing", "NaN spacing");
  r = napkin();
  r.hold_point_spacing = -0.1;
  rejected(r, "hold_point_spacing", "negative spacing");
  r = napkin();
  r.model = "yarn_level";
  rejected(r, "yarn_level", "unknown model");
  r = napkin();
  r.hold_point_spacing = 0.001;  // 301 x 301 lattice
  rejected(r, "limit", "absurd lattice");
  EXPECT_TRUE(reg.list().empty());
  // A valid one is stored; the same name again is rejected and the first stays.
  reg.registerTextile(napkin());
  rejected(napkin(), "already exists", "duplicate name");
  EXPECT_EQ(reg.list().size(), 1u);
  ASSERT_TRUE(reg.waitIdle(300.0));
}

TEST(TextileRegistry, ResimulateReplacesTheEntriesWithTheNewSettings) {
  TextileRegistry reg(tempDb("resim"), smallOptions());
  const QueuedBuild q = reg.registerTextile(napkin());
  ASSERT_TRUE(reg.waitIdle(300.0));
  const StoredRestShape before = reg.restShape(q.textile_id, Vec2(0, 0));
  EXPECT_EQ(before.positions.size(), 3 * 7 * 7);  // d = 5 cm
  ResimulationRequest r;
  r.textile_id = q.textile_id;
  r.spacing = 0.03;
  r.material_name = "linear_test";
  const QueuedBuild q2 = reg.resimulate(r);
  EXPECT_EQ(q2.hold_points, 9);
  ASSERT_TRUE(reg.waitIdle(300.0));
  const auto list = reg.list();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].counts.done, 9);  // replaced, not added
  EXPECT_EQ(list[0].record.material.name, reg.resolveMaterial("linear_test", "").name);
  const StoredRestShape after = reg.restShape(q.textile_id, Vec2(0, 0));
  EXPECT_EQ(after.positions.size(), 3 * 11 * 11);  // d = 3 cm
  EXPECT_FALSE(after.triangles.empty());
  EXPECT_TRUE(after.hold.isApprox(Vec2(0, 0)));
  // The held particle hangs at the top.
  for (Index k = 0; k < after.positions.size() / 3; ++k)
    EXPECT_LE(after.positions[3 * k + 2], after.positions[3 * after.held_particle + 2] + 1e-9);
}

TEST(TextileRegistry, EveryBuildMakesTheConfiguredMembers) {
  RegistryOptions o = smallOptions();
  o.members = db::drapeMembersByName("base,soft_light");
  TextileRegistry reg(tempDb("members"), o);
  const QueuedBuild q = reg.registerTextile(napkin());
  ASSERT_TRUE(reg.waitIdle(300.0));
  auto list = reg.list();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].counts.done, 2 * 9);
  db::HangingDrapeDatabase db(reg.databasePath());
  std::map<std::string, int> stored = db::storedMembers(db, q.textile_id);
  EXPECT_EQ(stored, (std::map<std::string, int>{{"base", 9}, {"soft_light", 9}}));
  // A resimulation builds both members into the new generation and promotes them together.
  ResimulationRequest r;
  r.textile_id = q.textile_id;
  r.spacing = 0.06;
  reg.resimulate(r);
  ASSERT_TRUE(reg.waitIdle(300.0));
  list = reg.list();
  EXPECT_EQ(list[0].counts.done, 2 * 9);
  stored = db::storedMembers(db, q.textile_id);
  EXPECT_EQ(stored, (std::map<std::string, int>{{"base", 9}, {"soft_light", 9}}));
}

TEST(TextileRegistry, ChoiKoModelIsSelectableAtRegistration) {
  TextileRegistry reg(tempDb("choiko"), smallOptions());
  TextileRegistration r = napkin("napkin_ck");
  r.model = "choi_ko";
  const QueuedBuild q = reg.registerTextile(r);
  ASSERT_TRUE(reg.waitIdle(300.0));
  db::HangingDrapeDatabase check(reg.databasePath());
  const auto sims = check.simulations(q.textile_id);
  ASSERT_FALSE(sims.empty());
  for (const auto& s : sims) EXPECT_EQ(s.model, "choi_ko");
  EXPECT_EQ(check.counts(q.textile_id).done + check.counts(q.textile_id).failed, 9);
}

TEST(TextileRegistry, UnknownIdsAndBadResimulationsAreErrors) {
  TextileRegistry reg(tempDb("unknown"), smallOptions());
  ResimulationRequest r;
  r.textile_id = 42;
  EXPECT_THROW(reg.resimulate(r), db::NotFoundError);
  EXPECT_THROW(reg.restShape(42, Vec2::Zero()), db::NotFoundError);
  EXPECT_THROW(reg.ensureBuilt(42), db::NotFoundError);
  const std::int64_t id = reg.ensurePreset("square");
  EXPECT_EQ(reg.ensurePreset("square"), id);  // idempotent
  EXPECT_THROW(reg.ensurePreset("blanket"), db::InvalidInputError);
  EXPECT_THROW(reg.restShape(id, Vec2::Zero()), db::NotFoundError);  // nothing simulated yet
  r.textile_id = id;
  r.model = "no_such_model";
  EXPECT_THROW(reg.resimulate(r), db::InvalidInputError);
  r.model.clear();
  r.spacing = std::nan("");
  EXPECT_THROW(reg.resimulate(r), db::InvalidInputError);
  EXPECT_EQ(reg.pendingJobs(), 0);
  EXPECT_EQ(reg.list().size(), 1u);
}

TEST(TextileRegistry, StoppingWithQueuedJobsLeavesAConsistentResumableDatabase) {
  const std::string path = tempDb("stop");
  std::int64_t id = 0;
  {
    TextileRegistry reg(path, smallOptions());
    id = reg.registerTextile(napkin()).textile_id;
    reg.registerTextile(napkin("napkin2"));
  }  // destructor: stops after the running simulation
  db::HangingDrapeDatabase check(path);
  EXPECT_TRUE(check.consistencyProblems().empty());
  EXPECT_EQ(check.textiles().size(), 2u);
  // A new registry resumes the interrupted build.
  TextileRegistry reg(path, smallOptions());
  reg.ensureBuilt(id);
  ASSERT_TRUE(reg.waitIdle(300.0));
  EXPECT_EQ(check.counts(id).done, 9);
  EXPECT_TRUE(check.consistencyProblems().empty());
}

}  // namespace
}  // namespace registry
}  // namespace textile_handling
