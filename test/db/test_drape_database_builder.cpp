// The database builder: hold-point plan, mirrored entries, resume, failures, validation, determinism.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "../test_support.h"
#include "test_database.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/sim/cloth_topology.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

using test_support::TestDatabase;

// 30 x 30 cm square, d = 3 cm, lattice 10 cm: quadrant x, y in {0, .10, .15} -> 9 simulated, 25 in all.
DrapeBuildConfig smallSquare() {
  DrapeBuildConfig c;
  c.textile = presetTextile("square");
  c.spacing = 0.03;
  c.lattice_spacing = 0.10;
  c.frame = vision::CanonicalFrame::fromMetric(0.5, 0.5, 64);
  c.workers = 2;
  return c;
}

double azimuthMod(double a) {
  a = std::fmod(a, 360.0);
  return a < 0 ? a + 360.0 : a;
}

}  // namespace

TEST(DrapeDatabaseBuilder, SimulatesOneQuadrantAndDerivesTheMirrors) {
  TestDatabase t("mirror");
  HangingDrapeDatabase db(t.path());
  DrapeDatabaseBuilder b(db, smallSquare());
  EXPECT_TRUE(b.symmetricGrid());
  EXPECT_EQ(b.symmetry().name(), "xy");
  const DrapeBuildReport r = b.build();
  EXPECT_EQ(r.planned, 25);
  EXPECT_EQ(r.to_simulate, 9);
  EXPECT_EQ(r.simulated_now, 9);
  EXPECT_EQ(r.failed_now, 0);
  EXPECT_EQ(r.derived_now, 16);
  const DatabaseCounts c = db.counts();
  EXPECT_EQ(c.done, 25);
  EXPECT_EQ(c.derived, 16);
  EXPECT_EQ(c.views, 25 * 36);
  EXPECT_TRUE(db.consistencyProblems().empty());

  // A mirrored shape's silhouette at azimuth a is the source's at -a (mirror x) or 180 - a (mirror y)
  // flipped left-right, or at a + 180 (both mirrors). The derived entries are exactly that; rendering
  // the mirrored positions gives the same silhouettes up to the rasteriser's tie rules.
  std::map<std::int64_t, SimulationRecord> rows;
  for (const auto& s : db.simulations()) rows[s.id] = s;
  std::string err;
  const auto tris = vision::trianglesFromTopology(
      ParticleTopology::fromGrid(ParticleGrid::rasterize(presetTextile("square"), 0.03, &err)));
  int compared = 0, identical_render = 0;
  double worst_render_iou = 1, worst_ortho_iou = 1;
  for (const auto& [id, s] : rows) {
    if (s.source == MirrorKind::kIdentity) continue;
    const SimulationRecord& src = rows.at(s.source_simulation_id);
    EXPECT_TRUE(b.symmetry().apply(s.source, src.hold).isApprox(s.hold, 1e-12));
    EXPECT_NEAR(s.hanging_depth_m, src.hanging_depth_m, 1e-12);
    const VecX xs = db.positions(src.id), xd = db.positions(id);
    EXPECT_NEAR(xs.segment<3>(3 * src.held_particle).z(), xd.segment<3>(3 * s.held_particle).z(), 1e-12);
    std::map<long, vision::BitMask> src_views;
    for (const auto& v : db.views(src.id)) src_views[std::lround(v.view_angle_deg)] = v.mask;
    for (const auto& v : db.views(id)) {
      const double a = v.view_angle_deg;
      bool flip = true;
      double from = a;
      if (s.source == MirrorKind::kMirrorX) from = -a;
      if (s.source == MirrorKind::kMirrorY) from = 180.0 - a;
      if (s.source == MirrorKind::kMirrorXY) {
        from = a + 180.0;
        flip = false;
      }
      const vision::BitMask& m = src_views.at(std::lround(azimuthMod(from)) % 360);
      EXPECT_EQ(v.mask, flip ? flipLeftRight(m) : m) << "simulation " << id << " view " << a;
      // Orthographic identity: the mirror-x shape at a looks like the source at 180 - a, unflipped.
      if (s.source == MirrorKind::kMirrorX)
        worst_ortho_iou = std::min(worst_ortho_iou, vision::iou(src_views.at(std::lround(azimuthMod(180.0 - a)) % 360), v.mask));
      const vision::BitMask rendered =
          vision::renderSilhouette(xd, tris, static_cast<Index>(s.held_particle), a, {}, smallSquare().frame);
      worst_render_iou = std::min(worst_render_iou, vision::iou(rendered, v.mask));
      identical_render += rendered == v.mask;
      ++compared;
    }
  }
  EXPECT_EQ(compared, 16 * 36);
  EXPECT_GE(worst_render_iou, 0.95);
  EXPECT_GE(worst_ortho_iou, 0.95);
  EXPECT_GE(identical_render, compared / 3);
  std::printf("mirrored views vs re-rendered mirrored shapes: %d of %d identical, worst IoU %.4f\n", identical_render,
              compared, worst_render_iou);

  // The matcher sees 25 hold points in 9 classes.
  const DrapeMatchIndex index = loadDrapeMatchIndex(db);
  EXPECT_EQ(index.matcher.size(), 25u * 36u);
  EXPECT_EQ(index.hold_points.size(), 25u);
  EXPECT_EQ(index.classes.size(), 9u);
  MatchIndexOptions only_simulated;
  only_simulated.include_derived = false;
  EXPECT_EQ(loadDrapeMatchIndex(db, only_simulated).matcher.size(), 9u * 36u);
  // A stored silhouette finds its own class first.
  const auto views = db.views(rows.begin()->first);
  const DrapeQueryResult q = queryDrape(index, views[3].mask);
  ASSERT_FALSE(q.matches.empty());
  EXPECT_EQ(q.matches.front().score, 1.0);
  EXPECT_EQ(q.matches.front().class_index, index.classOf("square", rows.begin()->second.hold).value());
  std::set<std::size_t> distinct;
  for (const auto& m : q.matches) distinct.insert(m.class_index);
  EXPECT_EQ(distinct.size(), q.matches.size());  // one entry per class
}

TEST(DrapeDatabaseBuilder, RebuildResumesAndSkipsDoneSimulations) {
  TestDatabase t("resume");
  HangingDrapeDatabase db(t.path());
  {
    DrapeDatabaseBuilder b(db, smallSquare());
    EXPECT_EQ(b.build().simulated_now, 9);
  }
  DrapeDatabaseBuilder again(db, smallSquare());
  const DrapeBuildReport r = again.build();
  EXPECT_EQ(r.already_done, 9);
  EXPECT_EQ(r.simulated_now, 0);
  EXPECT_EQ(r.derived_now, 0);
  EXPECT_EQ(db.counts().simulations, 25);
  // Other settings plan new rows instead of mixing results.
  DrapeBuildConfig other = smallSquare();
  other.settings.max_time = 19.0;
  DrapeDatabaseBuilder third(db, other);
  EXPECT_EQ(third.build().simulated_now, 9);
  EXPECT_EQ(db.counts().simulations, 50);
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(other), DrapeDatabaseBuilder::parametersText(smallSquare()));
}

TEST(DrapeDatabaseBuilder, ParameterTextCoversTheSolverSettingsThatChangeShapes) {
  // Rows are found again by their parameter text; a setting missing from it lets a rebuild with other
  // settings resume (and mix in) rows computed with the old ones.
  const DrapeBuildConfig base = smallSquare();
  const std::string t0 = DrapeDatabaseBuilder::parametersText(base);
  std::vector<std::pair<std::string, DrapeBuildConfig>> variants;
  DrapeBuildConfig c = base;
  c.settings.solver.warm_start = !base.settings.solver.warm_start;
  variants.emplace_back("warm start", c);
  c = base;
  c.settings.solver.preconditioner = base.settings.solver.preconditioner == PreconditionerKind::kTwoLevel
                                         ? PreconditionerKind::kBlockJacobi
                                         : PreconditionerKind::kTwoLevel;
  variants.emplace_back("preconditioner", c);
  c = base;
  c.settings.solver.accept_tolerance = base.settings.solver.accept_tolerance + 0.01;
  variants.emplace_back("accept tolerance", c);
  c = base;
  c.settings.solver.smoothing_steps = base.settings.solver.smoothing_steps + 1;
  variants.emplace_back("smoothing steps", c);
  c = base;
  c.settings.solver.relative_tolerance = base.settings.solver.relative_tolerance * 2;
  variants.emplace_back("CG tolerance", c);
  c = base;
  c.start_tilt_deg = 30;
  variants.emplace_back("start tilt", c);
  const std::string tilted = DrapeDatabaseBuilder::parametersText(c);
  c.start_tilt_axis_deg = 90;
  variants.emplace_back("start tilt axis", c);
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(c), tilted);
  for (const auto& [what, v] : variants) EXPECT_NE(DrapeDatabaseBuilder::parametersText(v), t0) << what;
  // A flat start (the default) adds nothing, so existing databases keep their rows.
  EXPECT_EQ(t0.find("start_tilt"), std::string::npos);
}

TEST(DrapeDatabaseBuilder, ParallelWorkersGiveTheSameShapes) {
  TestDatabase t1("w1"), t2("w2");
  HangingDrapeDatabase db1(t1.path()), db2(t2.path());
  DrapeBuildConfig c = smallSquare();
  c.workers = 1;
  DrapeDatabaseBuilder(db1, c).build();
  c.workers = 3;
  DrapeDatabaseBuilder(db2, c).build();
  const auto a = db1.simulations(), b = db2.simulations();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k) {
    ASSERT_TRUE(a[k].hold.isApprox(b[k].hold));
    EXPECT_EQ(db1.positions(a[k].id), db2.positions(b[k].id)) << "row " << a[k].id;
  }
}

TEST(DrapeDatabaseBuilder, FailedSimulationsAreStoredWithTheirReason) {
  TestDatabase t("fail");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();
  c.settings.max_time = 0.02;  // far too short to come to rest
  c.retry_with_smaller_steps = false;
  const DrapeBuildReport r = DrapeDatabaseBuilder(db, c).build();
  EXPECT_EQ(r.failed_now, 9);
  EXPECT_EQ(r.simulated_now, 0);
  EXPECT_EQ(r.failures.size(), 9u);
  const DatabaseCounts n = db.counts();
  EXPECT_EQ(n.failed, 25);  // mirrors fail with their source
  EXPECT_EQ(n.views, 0);
  for (const auto& s : db.simulations()) {
    EXPECT_EQ(s.status, SimulationStatus::kFailed);
    if (s.source == MirrorKind::kIdentity)
      EXPECT_NE(s.failure_reason.find("no rest within max_time"), std::string::npos) << s.failure_reason;
    else
      EXPECT_NE(s.failure_reason.find("source simulation"), std::string::npos) << s.failure_reason;
  }
  EXPECT_TRUE(db.consistencyProblems().empty());
  // Without retry_failed a rebuild leaves them; with it they run again.
  EXPECT_EQ(DrapeDatabaseBuilder(db, c).build().failed_now, 0);
  c.retry_failed = true;
  EXPECT_EQ(DrapeDatabaseBuilder(db, c).build().failed_now, 9);
  // Stored as done (rest_reached = false) when rest is not required.
  c.require_rest = false;
  c.retry_failed = false;
  const DrapeBuildReport ok = DrapeDatabaseBuilder(db, c).build();
  EXPECT_EQ(ok.simulated_now, 9);
  for (const auto& s : db.simulations(0, SimulationStatus::kDone)) EXPECT_FALSE(s.rest_reached);
}

TEST(DrapeDatabaseBuilder, InvalidConfigurationsWriteNothing) {
  TestDatabase t("invalid");
  HangingDrapeDatabase db(t.path());
  auto expectInvalid = [&](const DrapeBuildConfig& c, const std::string& what) {
    try {
      DrapeDatabaseBuilder b(db, c);
      b.build();
      ADD_FAILURE() << "accepted " << what;
    } catch (const InvalidInputError& e) {
      EXPECT_FALSE(std::string(e.what()).empty());
    }
  };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  DrapeBuildConfig c = smallSquare();
  c.spacing = nan;
  expectInvalid(c, "NaN spacing");
  c = smallSquare();
  c.settings.dt_max = nan;
  expectInvalid(c, "NaN dt_max");
  c = smallSquare();
  c.model.set("settle_damping_per_s", std::numeric_limits<double>::infinity());
  expectInvalid(c, "infinite damping");
  c = smallSquare();
  c.lattice_spacing = -1;
  expectInvalid(c, "negative lattice");
  c = smallSquare();
  c.hold_points = {Vec2(0.5, 0.5)};
  expectInvalid(c, "hold point off the textile");
  c = smallSquare();
  c.material.areal_density = nan;
  expectInvalid(c, "NaN density");
  c = smallSquare();
  c.textile.outline = {Vec2(0, 0), Vec2(1, 1), Vec2(1, 0), Vec2(0, 1)};
  expectInvalid(c, "self-intersecting outline");
  c = smallSquare();
  c.model = ClothModelSpec("choi_ko_missing");
  expectInvalid(c, "unknown model");
  c = smallSquare();
  c.frame.width_px = 0;
  expectInvalid(c, "empty frame");
  c = smallSquare();
  c.threads_per_simulation = -1;
  expectInvalid(c, "negative threads");
  EXPECT_EQ(db.counts().textiles, 0);
  EXPECT_EQ(db.counts().simulations, 0);
}

TEST(DrapeDatabaseBuilder, QuasiStaticRestShapesMatchTheDynamicBuild) {
  // The same two hold points built with both rest-shape methods into one file: different parameter
  // texts (no row is resumed across methods), rest shapes within 5 mm, threads chosen automatically.
  TestDatabase t("quasi_static");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();
  c.spacing = 0.015;
  c.hold_points = {Vec2(0, 0), Vec2(0.15, 0)};
  c.views.count = 4;
  c.views.step_deg = 90;
  c.workers = 1;
  c.threads_per_simulation = 0;
  std::map<std::string, std::map<std::pair<double, double>, VecX>> shapes;
  for (RestShapeMethod m : {RestShapeMethod::kDynamic, RestShapeMethod::kQuasiStatic}) {
    c.rest_shape.method = m;
    c.rest_shape.coarse_spacing = 0.03;
    DrapeBuildPass seen;
    c.on_pass_start = [&seen](const DrapeBuildPass& p) { seen = p; };
    DrapeDatabaseBuilder b(db, c);
    const DrapeBuildReport r = b.build();
    EXPECT_EQ(r.failed_now, 0);
    EXPECT_EQ(r.simulated_now, 2) << "rows of the other method were resumed";
    EXPECT_GE(seen.threads_per_simulation, 1);
    const std::string params = DrapeDatabaseBuilder::parametersText(c);
    EXPECT_EQ(params.find("rest_method: quasi_static") != std::string::npos, m == RestShapeMethod::kQuasiStatic);
    for (const SimulationRecord& rec : db.simulations(0, SimulationStatus::kDone))
      if (rec.parameters == params && rec.source == MirrorKind::kIdentity)
        shapes[toString(m)][{rec.hold.x(), rec.hold.y()}] = db.positions(rec.id);
  }
  ASSERT_EQ(shapes["dynamic"].size(), 2u);
  ASSERT_EQ(shapes["quasi_static"].size(), 2u);
  for (const auto& [hold, a] : shapes["dynamic"]) {
    const VecX& b = shapes["quasi_static"].at(hold);
    ASSERT_EQ(a.size(), b.size());
    Real worst = 0;
    for (Eigen::Index i = 0; i < a.size() / 3; ++i) worst = std::max(worst, (a.segment<3>(3 * i) - b.segment<3>(3 * i)).norm());
    EXPECT_LT(worst, 5e-3) << "hold (" << hold.first << ", " << hold.second << ")";
  }
}

TEST(DrapeDatabaseBuilder, AsymmetricGridSimulatesEveryHoldPoint) {
  TestDatabase t("asym");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c;
  c.textile = presetTextile("towel");
  c.spacing = 0.04;  // 0.46 m is not a multiple of 4 cm: the particle grid is not mirror-symmetric in y
  c.lattice_spacing = 0.3;
  c.views.count = 4;
  c.views.step_deg = 90;
  DrapeDatabaseBuilder b(db, c);
  EXPECT_FALSE(b.symmetricGrid());
  const DrapeBuildReport r = b.build();
  EXPECT_EQ(r.planned, 9);
  EXPECT_EQ(r.to_simulate, 9);
  EXPECT_EQ(r.derived_now, 0);
  EXPECT_EQ(db.counts().derived, 0);
  EXPECT_EQ(db.counts().done + db.counts().failed, 9);
  // Still folded into classes by the textile's symmetry: 4 classes (corner, two edge middles, centre).
  EXPECT_EQ(loadDrapeMatchIndex(db).classes.size(), 4u);
}

TEST(DrapeDatabaseBuilder, ReportsPassesProgressAndFailuresThroughCallbacks) {
  TestDatabase t("callbacks");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();
  c.settings.max_time = 0.02;  // every simulation fails quickly
  c.retry_with_smaller_steps = false;
  std::vector<std::string> events;
  std::vector<DrapeBuildFailure> failures;
  c.on_pass_start = [&](const DrapeBuildPass& p) {
    events.push_back("start " + p.textile + " " + std::to_string(p.planned) + " " + std::to_string(p.to_simulate) + " " +
                     std::to_string(p.already_done) + " " + std::to_string(p.to_run) + " " + p.symmetry);
    EXPECT_EQ(p.bracket_corner, -1);
    if (p.to_run > 0) {
      EXPECT_EQ(p.workers, 2);  // a pass with nothing to run has one (idle) worker
    }
    EXPECT_TRUE(p.symmetric_grid);
  };
  c.on_progress = [&](const DrapeBuildProgress& p) {
    events.push_back(std::to_string(p.done) + "/" + std::to_string(p.total));
    EXPECT_EQ(p.done_before, 0);
    EXPECT_GE(p.elapsed_s, 0.0);
    EXPECT_GE(p.eta_s, 0.0);  // a simulation has finished: there is an estimate
    if (p.done == p.total) {
      EXPECT_EQ(p.eta_s, 0.0);
    }
  };
  c.on_failure = [&](const DrapeBuildFailure& f) {
    events.push_back("failed");
    failures.push_back(f);
  };
  c.on_pass_end = [&](const DrapeBuildPass& p) { events.push_back("end " + std::to_string(p.to_run)); };
  const DrapeBuildReport r = DrapeDatabaseBuilder(db, c).build();
  ASSERT_EQ(r.failed_now, 9);
  std::vector<std::string> expected = {"start square 25 9 0 9 xy"};
  for (int k = 1; k <= 9; ++k) {
    expected.push_back("failed");
    expected.push_back(std::to_string(k) + "/9");
  }
  expected.push_back("end 9");
  EXPECT_EQ(events, expected);
  ASSERT_EQ(failures.size(), 9u);
  for (const DrapeBuildFailure& f : failures) {
    const SimulationRecord s = db.simulation(f.simulation_id);
    EXPECT_EQ(s.failure_reason, f.reason);
    EXPECT_LT((s.hold - f.hold).norm(), 1e-6);
    EXPECT_NE(f.reason.find("no rest within max_time"), std::string::npos) << f.reason;
  }
  // A rebuild has nothing to run: a pass with to_run 0 and no progress calls.
  events.clear();
  DrapeDatabaseBuilder(db, c).build();
  EXPECT_EQ(events, (std::vector<std::string>{"start square 25 9 0 0 xy", "end 0"}));
}

TEST(DrapeDatabaseBuilder, BracketHoldIsACornerOfTheGridCell) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), 0.04, &err);
  ASSERT_FALSE(g.empty()) << err;
  auto at = [&](const Vec2& p, int k) { return DrapeDatabaseBuilder::bracketHold(g, p, k); };
  const Vec2 p(0.05, 0.06);  // inside the cell [0.04, 0.08] x [0.04, 0.08]
  EXPECT_TRUE(at(p, 0)->isApprox(Vec2(0.04, 0.04)));
  EXPECT_TRUE(at(p, 1)->isApprox(Vec2(0.08, 0.04)));
  EXPECT_TRUE(at(p, 2)->isApprox(Vec2(0.04, 0.08)));
  EXPECT_TRUE(at(p, 3)->isApprox(Vec2(0.08, 0.08)));
  EXPECT_TRUE(at(p, -1)->isApprox(p));  // no bracket: the hold point itself
  const Vec2 on_col(0.08, 0.06);        // on a grid column: the upper-column corners are duplicates
  EXPECT_TRUE(at(on_col, 0)->isApprox(Vec2(0.08, 0.04)));
  EXPECT_FALSE(at(on_col, 1).has_value());
  EXPECT_TRUE(at(on_col, 2)->isApprox(Vec2(0.08, 0.08)));
  EXPECT_FALSE(at(on_col, 3).has_value());
  EXPECT_FALSE(at(Vec2(0.10, 0.45), 2).has_value());  // 46 cm is not a multiple of 4 cm: no row above
  EXPECT_FALSE(at(p, 4).has_value());
}

TEST(DrapeDatabaseBuilder, BracketedHoldPointsGetOneRowPerCornerParticle) {
  TestDatabase t("bracket");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();  // quadrant points x, y in {0, .10, .15}; d = 3 cm
  c.bracket_hold_points = true;
  DrapeDatabaseBuilder b(db, c);
  const DrapeBuildReport r = b.build();
  // 0 and 0.15 lie on grid lines (one particle), 0.10 between two: (1 + 2 + 1)^2 simulated rows.
  EXPECT_EQ(r.to_simulate, 16);
  EXPECT_EQ(r.failed_now, 0);
  const std::vector<std::string> texts = DrapeDatabaseBuilder::parameterTexts(c);
  ASSERT_EQ(texts.size(), 4u);
  EXPECT_EQ(std::set<std::string>(texts.begin(), texts.end()).size(), 4u);
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(c.textile, c.spacing, &err);
  int simulated = 0;
  for (const SimulationRecord& s : db.simulations(0, SimulationStatus::kDone)) {
    const auto it = std::find(texts.begin(), texts.end(), s.parameters);
    ASSERT_NE(it, texts.end());
    const int corner = static_cast<int>(it - texts.begin());
    if (s.source != MirrorKind::kIdentity) continue;
    ++simulated;
    // The pinned particle is that corner of the cell containing the (nominal) hold point.
    const auto want = DrapeDatabaseBuilder::bracketHold(g, s.hold, corner);
    ASSERT_TRUE(want.has_value());
    EXPECT_TRUE(g.activePosition(s.held_particle).isApprox(*want, 1e-9))
        << "hold (" << s.hold.x() << ", " << s.hold.y() << ") corner " << corner;
  }
  EXPECT_EQ(simulated, 16);
  // The index keeps one class per nominal hold point (up to symmetry) with all its corner rows, on the
  // lattice of the nominal points.
  MatchIndexOptions o;
  o.textile = "square";
  const DrapeMatchIndex index = loadDrapeMatchIndex(db, o);
  EXPECT_EQ(index.classes.size(), 9u);
  std::size_t members = 0;
  for (const auto& cl : index.classes) members += cl.members.size();
  EXPECT_EQ(members, index.hold_points.size());
  const auto c0 = index.classOf("square", Vec2(0.0, 0.0)), c1 = index.classOf("square", Vec2(0.10, 0.0)),
             c2 = index.classOf("square", Vec2(0.15, 0.0));
  ASSERT_TRUE(c0 && c1 && c2);
  EXPECT_TRUE(index.classesNeighbour(*c0, *c1, false));
  EXPECT_FALSE(index.classesNeighbour(*c0, *c2, false));
  // Only the bracket passes: a plain build of the same settings is another parameter set.
  DrapeBuildConfig plain = smallSquare();
  EXPECT_EQ(std::find(texts.begin(), texts.end(), DrapeDatabaseBuilder::parametersText(plain)), texts.end());
  // Resume: nothing left to do.
  DrapeDatabaseBuilder again(db, c);
  EXPECT_EQ(again.build().simulated_now, 0);
}

TEST(DrapeDatabaseBuilder, SelfCollisionKeepsStoredShapesFreeOfIntersections) {
  // The 30 x 30 cm square held at its centre folds onto itself (thesis 5.4.3): without collision
  // handling its rest shape passes through itself, with self_collision it does not. The setting is
  // part of the parameter text, so the two builds are separate rows of the same file.
  TestDatabase t("self_collision");
  HangingDrapeDatabase db(t.path());
  DrapeBuildConfig c = smallSquare();
  c.spacing = 0.025;
  c.hold_points = {Vec2(0.15, 0.15)};
  const std::string text_off = DrapeDatabaseBuilder::parametersText(c);
  const DrapeBuildReport off = DrapeDatabaseBuilder(db, c).build();
  c.self_collision = true;
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(c), text_off);
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(c).find("self_collision: v3"), std::string::npos);
  const DrapeBuildReport on = DrapeDatabaseBuilder(db, c).build();
  ASSERT_EQ(off.failed_now, 0);
  ASSERT_EQ(on.failed_now, 0);
  ASSERT_EQ(on.simulated_now, 1) << "the collision build must not resume the rows without collision";
  const DrapeScene scene = buildDrapeScene(DrapeDatabaseBuilder::sceneSpec(c, Vec2(0.15, 0.15)));
  const ClothTriangles tris = scene.triangles();
  std::map<std::string, long> pairs;
  for (const SimulationRecord& s : db.simulations()) {
    ASSERT_EQ(s.status, SimulationStatus::kDone);
    const bool with = s.parameters.find("self_collision: v3") != std::string::npos;
    pairs[with ? "on" : "off"] = countIntersectingTrianglePairs(tris, db.positions(s.id));
  }
  ASSERT_EQ(pairs.size(), 2u);
  EXPECT_GT(pairs["off"], 0) << "the scene no longer tests anything: the square does not pass through itself";
  EXPECT_EQ(pairs["on"], 0);
}
