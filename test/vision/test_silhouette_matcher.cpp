// Tests for the silhouette matcher: exact pruned search vs brute force, aggregation per
// (textile, hold point), margins, fusion, and error handling.
#include "textile_handling/vision/silhouette_matcher.h"

#include <gtest/gtest.h>

#include <cmath>
#include <algorithm>
#include <random>
#include <set>
#include <stdexcept>
#include <string>

#include "textile_handling/bench/match_benchmark.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace vision {
namespace {

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

BitMask rect(int w, int h, int x0, int y0, int x1, int y1) {
  BitMask m(w, h);
  for (int y = y0; y < y1; ++y) m.setSpan(y, x0, x1);
  return m;
}

// Union of random ellipses hanging below the top centre (a silhouette-like blob).
BitMask blob(int w, int h, std::mt19937& rng, double scale = 1.0) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  BitMask m(w, h);
  const int k = 1 + static_cast<int>(U(rng) * 3);
  for (int e = 0; e < k; ++e) {
    const double cx = 0.5 * w + (U(rng) - 0.5) * 0.3 * w;
    const double cy = 2 + (0.1 + 0.5 * U(rng)) * h;
    const double rx = (0.05 + 0.2 * U(rng)) * w * scale, ry = (0.08 + 0.3 * U(rng)) * h * scale;
    for (int y = 0; y < h; ++y) {
      const double t = (y + 0.5 - cy) / ry;
      if (std::abs(t) >= 1) continue;
      const double hw = rx * std::sqrt(1 - t * t);
      m.setSpan(y, static_cast<int>(std::ceil(cx - hw - 0.5)), static_cast<int>(std::floor(cx + hw - 0.5)) + 1);
    }
  }
  return m;
}

SilhouetteMatcher randomDatabase(int w, int h, int groups, int views, std::mt19937& rng, bool duplicates = false) {
  SilhouetteMatcher db;
  for (int g = 0; g < groups; ++g)
    for (int v = 0; v < views; ++v) {
      SilhouetteEntry e;
      e.textile_id = g % 2 ? "towel" : "shirt";
      e.hold_point_id = "h" + std::to_string(g / 2);
      e.view_angle_deg = 360.0 * v / views;
      e.mask = blob(w, h, rng);
      db.add(e);
      if (duplicates && v == 0) {  // exact tie with a later entry of another group
        e.hold_point_id += "_dup";
        db.add(e);
      }
    }
  return db;
}

void expectSameResults(const QueryResult& a, const QueryResult& b, const std::string& what) {
  ASSERT_EQ(a.matches.size(), b.matches.size()) << what;
  for (std::size_t i = 0; i < a.matches.size(); ++i) {
    const MatchResult &x = a.matches[i], &y = b.matches[i];
    EXPECT_EQ(x.textile_id, y.textile_id) << what << " rank " << i;
    EXPECT_EQ(x.hold_point_id, y.hold_point_id) << what << " rank " << i;
    EXPECT_EQ(x.entry, y.entry) << what << " rank " << i;
    EXPECT_EQ(x.view_angle_deg, y.view_angle_deg) << what << " rank " << i;
    EXPECT_EQ(x.dx, y.dx) << what << " rank " << i;
    EXPECT_EQ(x.dy, y.dy) << what << " rank " << i;
    EXPECT_EQ(x.score, y.score) << what << " rank " << i;  // exact: same integers, same division
    EXPECT_EQ(x.margin, y.margin) << what << " rank " << i;
  }
  EXPECT_EQ(a.margin, b.margin) << what;
}

TEST(SilhouetteMatcher, FindsAStoredSilhouetteWithItsShift) {
  std::mt19937 rng(1);
  SilhouetteMatcher db = randomDatabase(64, 64, 10, 6, rng);
  const SilhouetteEntry target = db.entry(23);
  const BitMask q = target.mask.shifted(4, -2);  // query drawn 4 px right and 2 px up
  const QueryResult r = db.query(q);
  ASSERT_FALSE(r.matches.empty());
  const MatchResult& best = r.matches[0];
  EXPECT_EQ(best.entry, 23u);
  EXPECT_EQ(best.textile_id, target.textile_id);
  EXPECT_EQ(best.hold_point_id, target.hold_point_id);
  EXPECT_DOUBLE_EQ(best.view_angle_deg, target.view_angle_deg);
  EXPECT_EQ(best.dx, 4);
  EXPECT_EQ(best.dy, -2);
  EXPECT_DOUBLE_EQ(best.score, iou(q, target.mask, 4, -2));
  ASSERT_GE(r.matches.size(), 2u);
  EXPECT_DOUBLE_EQ(r.margin, best.score - r.matches[1].score);
  EXPECT_DOUBLE_EQ(best.margin, r.margin);
  EXPECT_DOUBLE_EQ(r.matches[1].margin, r.matches[1].score - best.score);
  // Results are distinct (textile, hold point) pairs, sorted by score.
  for (std::size_t i = 1; i < r.matches.size(); ++i) {
    EXPECT_GE(r.matches[i - 1].score, r.matches[i].score);
    for (std::size_t j = 0; j < i; ++j)
      EXPECT_FALSE(r.matches[i].textile_id == r.matches[j].textile_id &&
                   r.matches[i].hold_point_id == r.matches[j].hold_point_id);
  }
  // Without the shift search the same entry scores lower.
  MatchOptions no_shift;
  no_shift.max_dx = 0;
  no_shift.max_dy = 0;
  const QueryResult r0 = db.query(q, no_shift);
  ASSERT_FALSE(r0.matches.empty());
  EXPECT_LT(r0.matches[0].score, 1.0);
}

TEST(SilhouetteMatcher, BestViewPerTextileAndHoldPoint) {
  SilhouetteMatcher db;
  const BitMask wide = rect(64, 64, 20, 2, 44, 40), narrow = rect(64, 64, 29, 2, 35, 40), mid = rect(64, 64, 24, 2, 40, 40);
  db.add({"towel", "corner", 0.0, wide});
  db.add({"towel", "corner", 90.0, narrow});
  db.add({"towel", "middle", 0.0, mid});
  const QueryResult r = db.query(narrow);
  ASSERT_EQ(r.matches.size(), 2u);
  EXPECT_EQ(r.matches[0].hold_point_id, "corner");
  EXPECT_DOUBLE_EQ(r.matches[0].view_angle_deg, 90.0);
  EXPECT_DOUBLE_EQ(r.matches[0].score, 1.0);
  EXPECT_EQ(r.matches[1].hold_point_id, "middle");
  EXPECT_DOUBLE_EQ(r.matches[1].score, 6.0 / 16.0);
  EXPECT_DOUBLE_EQ(r.margin, 1.0 - 6.0 / 16.0);
  MatchOptions top1;
  top1.top_k = 1;
  const QueryResult r1 = db.query(narrow, top1);
  ASSERT_EQ(r1.matches.size(), 1u);
  EXPECT_DOUBLE_EQ(r1.margin, r.margin);  // the margin still looks at the runner-up
  EXPECT_EQ(db.numGroups(), 2u);
}

TEST(SilhouetteMatcher, PrunedSearchEqualsBruteForceOnRandomDatabases) {
  std::mt19937 rng(2024);
  struct Case {
    int w, h, groups, views;
  };
  for (const Case c : {Case{64, 64, 12, 8}, Case{40, 48, 9, 5}, Case{100, 70, 6, 4}, Case{64, 64, 20, 3},
                       Case{24, 20, 8, 4}, Case{20, 260, 4, 3} /* > 255 rows: 16-bit column counts */}) {
    SilhouetteMatcher db = randomDatabase(c.w, c.h, c.groups, c.views, rng, /*duplicates=*/true);
    for (int q = 0; q < 6; ++q) {
      BitMask query = q % 3 == 0 ? db.entry(static_cast<std::size_t>(rng() % db.size())).mask.shifted(q - 3, 1)
                                 : blob(c.w, c.h, rng, q % 3 == 1 ? 1.0 : 0.6);
      if (query.count() == 0) query.set(c.w / 2, 3);
      for (const int k : {1, 3, 50}) {
        // Ranges beyond the window (shifts that empty the overlap) only on the small masks.
        const std::pair<int, int> wide = c.w <= 24 ? std::pair<int, int>{40, 30} : std::pair<int, int>{3, 1};
        for (const auto& range : {std::pair<int, int>{30, 5}, {0, 0}, {7, 9}, wide}) {
          MatchOptions o;
          o.top_k = k;
          o.max_dx = range.first;
          o.max_dy = range.second;
          const QueryResult pruned = db.query(query, o);
          o.exhaustive = true;
          const QueryResult brute = db.query(query, o);
          const std::string what = std::to_string(c.w) + "x" + std::to_string(c.h) + " q" + std::to_string(q) +
                                   " k" + std::to_string(k) + " range " + std::to_string(range.first) + "/" +
                                   std::to_string(range.second);
          expectSameResults(pruned, brute, what);
          EXPECT_LE(pruned.stats.shifts_evaluated, brute.stats.shifts_evaluated) << what;
          EXPECT_EQ(pruned.stats.pruned_area + pruned.stats.pruned_projection + pruned.stats.evaluated, db.size())
              << what;
        }
      }
    }
  }
}

TEST(SilhouetteMatcher, PrunedSearchEqualsBruteForceOnRenderedViews) {
  // Views of procedural hanging textiles: many similar silhouettes, the realistic case.
  SilhouetteMatcher db;
  std::mt19937 rng(9);
  for (int g = 0; g < 8; ++g) {
    HangingShapeParams p;
    p.hold_u = 0.64 * (g % 4) / 3.0;
    p.hold_v = g < 4 ? 0.46 : 0.23;
    p.fold_phase = g;
    p.spacing = 0.03;
    const SyntheticMesh mesh = syntheticHangingMesh(p);
    for (const auto& v : renderViews(mesh.positions, mesh.triangles, mesh.hold, ViewSet{12, 0.0, 30.0}))
      db.add({"towel", "h" + std::to_string(g), v.view_angle_deg, v.mask});
  }
  for (int q = 0; q < 5; ++q) {
    HangingShapeParams p;
    p.hold_u = 0.64 * (q % 4) / 3.0;
    p.fold_phase = q + 0.2;
    p.spacing = 0.03;
    const SyntheticMesh mesh = syntheticHangingMesh(p);
    const BitMask query = renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, 17.0 + 40 * q).shifted(2, 1);
    MatchOptions o;
    const QueryResult pruned = db.query(query, o);
    o.exhaustive = true;
    expectSameResults(pruned, db.query(query, o), "rendered q" + std::to_string(q));
    EXPECT_LT(pruned.stats.evaluated, db.size());  // pruning does prune here
  }
}

TEST(SilhouetteMatcher, FusionResolvesASingleViewAmbiguity) {
  // Two hold points of one textile. From the front (0 deg) the wrong one fits the photo better; from
  // the side (+90 deg) only the right one fits. The fused (mean) score picks the right one.
  SilhouetteMatcher db;
  db.add({"towel", "right", 0.0, rect(64, 64, 22, 2, 42, 42)});  // 20 px wide
  db.add({"towel", "right", 90.0, rect(64, 64, 28, 2, 36, 42)});  // 8 px
  db.add({"towel", "wrong", 0.0, rect(64, 64, 21, 2, 43, 42)});  // 22 px
  db.add({"towel", "wrong", 90.0, rect(64, 64, 24, 2, 40, 42)});  // 16 px
  const BitMask photo1 = rect(64, 64, 21, 2, 43, 42);  // 22 px: ambiguous, favours "wrong"
  const BitMask photo2 = rect(64, 64, 28, 2, 36, 42);  // 8 px, taken from +90 deg
  const QueryResult single = db.query(photo1);
  ASSERT_FALSE(single.matches.empty());
  EXPECT_EQ(single.matches[0].hold_point_id, "wrong");

  const std::vector<FusionImage> images = {{photo1, 0.0}, {photo2, 90.0}};
  const FusedQueryResult fused = db.queryFused(images);
  ASSERT_EQ(fused.matches.size(), 2u);
  const FusedMatch& best = fused.matches[0];
  EXPECT_EQ(best.hold_point_id, "right");
  EXPECT_DOUBLE_EQ(best.base_view_deg, 0.0);
  ASSERT_EQ(best.images.size(), 2u);
  EXPECT_DOUBLE_EQ(best.images[0].view_angle_deg, 0.0);
  EXPECT_DOUBLE_EQ(best.images[1].view_angle_deg, 90.0);
  EXPECT_DOUBLE_EQ(best.images[0].score, 20.0 / 22.0);
  EXPECT_DOUBLE_EQ(best.images[1].score, 1.0);
  EXPECT_DOUBLE_EQ(best.score, 0.5 * (20.0 / 22.0 + 1.0));
  // "wrong": base 0 -> (1 + 8/16) / 2 = 0.75; base 90 -> image 2 goes to the nearest view of 180 deg.
  EXPECT_EQ(fused.matches[1].hold_point_id, "wrong");
  EXPECT_DOUBLE_EQ(fused.matches[1].score, 0.75);
  EXPECT_DOUBLE_EQ(fused.margin, best.score - 0.75);
  EXPECT_GT(best.margin, 0);
  // Exhaustive fusion agrees.
  MatchOptions ex;
  ex.exhaustive = true;
  const FusedQueryResult fe = db.queryFused(images, ex);
  ASSERT_EQ(fe.matches.size(), 2u);
  EXPECT_EQ(fe.matches[0].hold_point_id, "right");
  EXPECT_EQ(fe.matches[0].score, best.score);
  EXPECT_EQ(fe.margin, fused.margin);
}

TEST(SilhouetteMatcher, FusionOfOneImageEqualsTheSingleQuery) {
  std::mt19937 rng(77);
  SilhouetteMatcher db = randomDatabase(64, 64, 8, 6, rng);
  const BitMask q = blob(64, 64, rng);
  const QueryResult r = db.query(q);
  const FusedQueryResult f = db.queryFused({{q, 0.0}});
  ASSERT_EQ(r.matches.size(), f.matches.size());
  for (std::size_t i = 0; i < r.matches.size(); ++i) {
    EXPECT_EQ(r.matches[i].hold_point_id, f.matches[i].hold_point_id);
    EXPECT_EQ(r.matches[i].textile_id, f.matches[i].textile_id);
    EXPECT_EQ(r.matches[i].score, f.matches[i].score);
    EXPECT_EQ(r.matches[i].entry, f.matches[i].images[0].entry);
    EXPECT_EQ(r.matches[i].dx, f.matches[i].images[0].dx);
  }
}

TEST(SilhouetteMatcher, CoarserGroupsAggregateTheBestEntryOfTheirMembers) {
  // group_of_entry merges (textile, hold point) pairs into coarser groups (e.g. the hold points a
  // symmetry makes indistinguishable): one result per group, its best entry, exact as brute force.
  std::mt19937 rng(5150);
  for (const int w : {64, 100}) {  // one and two words per row
    SilhouetteMatcher db = randomDatabase(w, 64, 14, 5, rng, /*duplicates=*/true);
    std::vector<std::uint32_t> groups(db.size());
    for (std::size_t e = 0; e < db.size(); ++e) groups[e] = static_cast<std::uint32_t>(db.groupOf(e) % 4);
    for (int q = 0; q < 4; ++q) {
      const BitMask query = q == 0 ? db.entry(7).mask.shifted(2, -1) : blob(w, 64, rng);
      for (const int k : {1, 2, 4}) {
        MatchOptions o;
        o.top_k = k;
        o.max_dx = 6;
        o.max_dy = 3;
        o.group_of_entry = &groups;
        const QueryResult pruned = db.query(query, o);
        o.exhaustive = true;
        const QueryResult brute = db.query(query, o);
        expectSameResults(pruned, brute, "w" + std::to_string(w) + " q" + std::to_string(q) + " k" + std::to_string(k));
        // Reference: best IoU per coarse group over all its entries, by plain bestShiftIou.
        std::vector<double> ref(4, 0.0);
        for (std::size_t e = 0; e < db.size(); ++e)
          ref[groups[e]] = std::max(ref[groups[e]], bestShiftIou(query, db.entry(e).mask, 6, 3).score);
        std::vector<double> sorted = ref;
        std::sort(sorted.rbegin(), sorted.rend());
        ASSERT_EQ(pruned.matches.size(), static_cast<std::size_t>(k));
        for (int i = 0; i < k; ++i) {
          EXPECT_EQ(pruned.matches[static_cast<std::size_t>(i)].score, sorted[static_cast<std::size_t>(i)]);
          EXPECT_EQ(groups[pruned.matches[static_cast<std::size_t>(i)].entry] < 4, true);
        }
        std::set<std::uint32_t> seen;
        for (const auto& m : pruned.matches) EXPECT_TRUE(seen.insert(groups[m.entry]).second);  // one per group
      }
    }
    std::vector<std::uint32_t> wrong(db.size() - 1, 0);
    MatchOptions bad;
    bad.group_of_entry = &wrong;
    EXPECT_THROW(db.query(db.entry(0).mask, bad), std::invalid_argument);
  }
}

TEST(SilhouetteMatcher, FusionRanksCoarseGroupsByTheirBestMember) {
  std::mt19937 rng(909);
  SilhouetteMatcher db = randomDatabase(64, 64, 12, 6, rng);
  std::vector<std::uint32_t> groups(db.size());
  for (std::size_t e = 0; e < db.size(); ++e) groups[e] = static_cast<std::uint32_t>(db.groupOf(e) / 3);  // 4 groups
  for (int q = 0; q < 3; ++q) {
    std::vector<FusionImage> imgs = {{blob(64, 64, rng), 0.0}, {blob(64, 64, rng), 120.0}};
    if (q == 0) imgs = {{db.entry(3).mask, 0.0}, {db.entry(5).mask, 120.0}};
    // Reference: every member group fused on its own (exhaustive), then the best member per coarse group.
    MatchOptions all;
    all.top_k = static_cast<int>(db.numGroups());
    all.max_dx = 5;
    all.max_dy = 2;
    all.exhaustive = true;
    const FusedQueryResult members = db.queryFused(imgs, all);
    std::vector<double> ref(4, -1.0);
    for (const FusedMatch& fm : members.matches) {
      const std::uint32_t c = groups[fm.images[0].entry];
      ref[c] = std::max(ref[c], fm.score);
    }
    std::vector<double> sorted;
    for (double v : ref)
      if (v > 0) sorted.push_back(v);
    std::sort(sorted.rbegin(), sorted.rend());
    for (const bool exhaustive : {false, true}) {
      MatchOptions o;
      o.top_k = 3;
      o.max_dx = 5;
      o.max_dy = 2;
      o.exhaustive = exhaustive;
      o.group_of_entry = &groups;
      const FusedQueryResult r = db.queryFused(imgs, o);
      ASSERT_EQ(r.matches.size(), std::min<std::size_t>(3, sorted.size()));
      std::set<std::uint32_t> seen;
      for (std::size_t i = 0; i < r.matches.size(); ++i) {
        EXPECT_EQ(r.matches[i].score, sorted[i]) << "q" << q << " rank " << i << " exhaustive " << exhaustive;
        const std::uint32_t c = groups[r.matches[i].images[0].entry];
        EXPECT_TRUE(seen.insert(c).second);
        for (const auto& im : r.matches[i].images) EXPECT_EQ(groups[im.entry], c);  // one member's views
      }
    }
  }
  std::vector<std::uint32_t> split = groups;
  split[0] = 3;
  split[1] = 0;  // entries 0 and 1 share a (textile, hold point) but not a group
  MatchOptions bad;
  bad.group_of_entry = &split;
  EXPECT_THROW(db.queryFused({{db.entry(0).mask, 0.0}}, bad), std::invalid_argument);
}

TEST(SilhouetteMatcher, PrunedFusionEqualsExhaustiveFusion) {
  std::mt19937 rng(31);
  for (int trial = 0; trial < 3; ++trial) {
    SilhouetteMatcher db = randomDatabase(64, 64, 10, 8, rng);
    std::vector<FusionImage> images = {{blob(64, 64, rng), 0.0}, {blob(64, 64, rng), 90.0}};
    if (trial == 2) images.push_back({db.entry(5).mask, -45.0});
    for (int k : {1, 4}) {
      MatchOptions o;
      o.top_k = k;
      const FusedQueryResult p = db.queryFused(images, o);
      o.exhaustive = true;
      const FusedQueryResult e = db.queryFused(images, o);
      ASSERT_EQ(p.matches.size(), e.matches.size());
      for (std::size_t i = 0; i < p.matches.size(); ++i) {
        EXPECT_EQ(p.matches[i].hold_point_id, e.matches[i].hold_point_id);
        EXPECT_EQ(p.matches[i].textile_id, e.matches[i].textile_id);
        EXPECT_EQ(p.matches[i].score, e.matches[i].score);
        EXPECT_EQ(p.matches[i].base_view_deg, e.matches[i].base_view_deg);
        for (std::size_t j = 0; j < images.size(); ++j) {
          EXPECT_EQ(p.matches[i].images[j].entry, e.matches[i].images[j].entry);
          EXPECT_EQ(p.matches[i].images[j].dx, e.matches[i].images[j].dx);
          EXPECT_EQ(p.matches[i].images[j].dy, e.matches[i].images[j].dy);
        }
      }
      EXPECT_EQ(p.margin, e.margin);
    }
  }
}

TEST(SilhouetteMatcher, BadInputGivesClearErrors) {
  auto expectThrow = [](auto&& fn, const std::string& part) {
    try {
      fn();
      ADD_FAILURE() << "expected std::invalid_argument containing '" << part << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_TRUE(contains(e.what(), part)) << e.what();
    }
  };
  SilhouetteMatcher db;
  const BitMask m = rect(64, 64, 20, 2, 40, 30);
  expectThrow([&] { db.query(m); }, "database is empty");
  expectThrow([&] { db.add({"t", "h", 0.0, BitMask()}); }, "empty");
  expectThrow([&] { db.add({"t", "h", std::nan(""), m}); }, "not finite");
  db.add({"t", "h", 0.0, m});
  db.add({"t", "h2", 0.0, BitMask(64, 64)});  // all-zero entries are allowed and never match
  expectThrow([&] { db.add({"t", "h", 10.0, rect(32, 64, 0, 0, 5, 5)}); }, "32x64");
  expectThrow([&] { db.query(rect(64, 32, 0, 0, 5, 5)); }, "64x32");
  expectThrow([&] { db.query(BitMask(64, 64)); }, "no foreground");
  expectThrow([&] { db.query(BitMask()); }, "empty");
  MatchOptions bad;
  bad.max_dx = -1;
  expectThrow([&] { db.query(m, bad); }, "max_dx");
  bad = MatchOptions();
  bad.top_k = 0;
  expectThrow([&] { db.query(m, bad); }, "top_k");
  expectThrow([&] { db.queryFused({}); }, "no images");
  expectThrow([&] { db.queryFused({{m, std::nan("")}}); }, "relative view angle");
  expectThrow([&] { db.queryFused({{m, 0.0}, {BitMask(64, 64), 90.0}}); }, "image 1");
  EXPECT_THROW(db.entry(5), std::out_of_range);
  const QueryResult r = db.query(m);
  ASSERT_EQ(r.matches.size(), 1u);  // the all-zero entry's group never appears
  EXPECT_DOUBLE_EQ(r.margin, 1.0);  // no runner-up: margin against 0
}

TEST(MatchBenchmark, SmallRunIsExactAndRecognisesShapes) {
  MatchBenchmarkConfig c;
  c.entries = 36 * 24;
  c.queries = 20;
  c.verify_queries = 3;
  const MatchBenchmarkReport r = runMatchBenchmark(c);
  EXPECT_EQ(r.entries, static_cast<std::size_t>(c.entries));
  EXPECT_EQ(r.groups, 24u);
  EXPECT_EQ(r.verified, 3);
  EXPECT_EQ(r.verify_mismatches, 0);
  EXPECT_GE(r.top1_correct, 10);  // procedural shapes are distinct enough
  EXPECT_GT(r.mean_ms, 0);
  EXPECT_FALSE(formatReport(r).empty());
  c.database = BenchmarkDatabase::kRandomBlobs;
  const MatchBenchmarkReport b = runMatchBenchmark(c);
  EXPECT_EQ(b.verify_mismatches, 0);
  EXPECT_EQ(b.top1_correct, -1);
}

}  // namespace
}  // namespace vision
}  // namespace textile_handling
