// End-to-end recognition on synthetic camera images (no ROS): a tiny database (a 36 x 24 cm towel-shaped
// rectangle at d = 3 cm, hold points on a 6 cm lattice over one quadrant: 12 simulated, 35 with the
// mirrors, 36 views) and held-out shapes of the same textile simulated at ANOTHER resolution (d = 2 cm),
// their hold points mirrored into other quadrants, rendered by a tilted and rolled VGA camera at azimuths
// between the stored views. Checks the recognised hold point and every grasp pose against the ground
// truth (the named points of the rendered simulation, in the hold frame), and bad input.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include "recognition_test_support.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/recognition/point_cloud_segmentation.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;
using textile_handling::test_support::throwsCode;
using textile_handling::test_support::smallTowel;
using textile_handling::test_support::testCamera;
using textile_handling::test_support::vga;

namespace {

std::string tempPath(const std::string& name) { return test_support::freshTempPath("th_rec_", name); }

void removeDb(const std::string& p) {
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(p + s);
}

db::DrapeBuildConfig baseConfig() {
  db::DrapeBuildConfig c;
  c.textile = smallTowel();
  c.spacing = 0.03;
  c.lattice_spacing = 0.06;
  c.frame = vision::CanonicalFrame::fromMetric(0.6, 0.6, 64);
  c.workers = 2;
  return c;
}

// A held-out rest shape (simulated at d = 2 cm) with its grid, and the "oracle" error: how far the
// database's own shape for the true hold point (d = 3 cm) is from it, named point by named point, at the
// best rotation about the hold axis. No recogniser that returns stored shapes can do better.
struct Truth {
  Vec2 hold;
  VecX positions;
  std::vector<vision::Triangle> triangles;
  ParticleGrid grid;
  Index held = -1;
  double oracle_m = 0;
  Vec3 holdWorld() const { return positions.segment<3>(3 * held); }
};

// Renders the truth (its gripper turned by `turn` degrees about the hold axis) and builds the observation.
// The heading reference is the gripper's x axis, so the hold frame turns with the gripper.
CameraObservation observe(const Truth& t, double azimuth, double turn, bool depth, std::uint64_t seed) {
  const Vec3 hold = t.holdWorld();
  const Mat3 rz = rotationZ(turn);
  VecX x = t.positions;
  for (Eigen::Index k = 0; k < x.size() / 3; ++k) x.segment<3>(3 * k) = hold + rz * (x.segment<3>(3 * k) - hold);
  vision::ShadedRenderOptions ro;
  ro.intrinsics = vga();
  ro.camera = testCamera(hold, azimuth);
  ro.noise_sigma = 3.0;
  ro.seed = seed;
  const vision::ShadedImage img = vision::renderShaded(x, t.triangles, ro);
  CameraObservation ob;
  ob.image = img.bgr;
  ob.encoding = "bgr8";
  if (depth) ob.depth = img.depth;
  ob.intrinsics = ro.intrinsics;
  ob.hold_camera = ro.camera.toCamera(hold);
  ob.up_camera = ro.camera.rotation.transpose() * Vec3::UnitZ();
  ob.heading_camera = ro.camera.rotation.transpose() * (rz * Vec3::UnitX());
  return ob;
}

// Largest distance between the recognised grasp poses and the truth's named points in the hold frame
// (world axes at the hold point, gripper not turned). The names of the result refer to its hold point:
// g maps the true hold point onto the returned one, so the pose named n at textile point p is the true
// textile point g(p). For a hold point on a symmetry axis several g fit; the best is taken.
struct PoseErrors {
  double max_3d = 1e9;        // [m]
  double max_lateral = 1e9;   // in the plane perpendicular to the camera's viewing direction
  double max_depth = 1e9;     // along the viewing direction
};
PoseErrors poseErrors(const Truth& t, const RecognitionResult& r, const db::TextileSymmetry& sym,
                      const Vec3& view_dir_world) {
  PoseErrors best;
  std::vector<db::MirrorKind> group = {db::MirrorKind::kIdentity};
  for (auto m : sym.mirrors()) group.push_back(m);
  const Vec3 hold = t.holdWorld();
  for (db::MirrorKind g : group) {
    auto map = [&](const Vec2& p) { return g == db::MirrorKind::kIdentity ? p : sym.apply(g, p); };
    if ((map(t.hold) - r.hold_point).norm() > 1e-3) continue;
    PoseErrors e{0, 0, 0};
    for (const GraspPose& p : r.grasp_poses) {
      const Index k = t.grid.nearestActive(map(p.textile_position));
      const Vec3 truth = t.positions.segment<3>(3 * k) - hold;
      const Vec3 d = p.position - truth;
      const double along = d.dot(view_dir_world);
      e.max_3d = std::max(e.max_3d, d.norm());
      e.max_depth = std::max(e.max_depth, std::abs(along));
      e.max_lateral = std::max(e.max_lateral, (d - along * view_dir_world).norm());
    }
    if (e.max_3d < best.max_3d) best = e;
  }
  return best;
}

// The largest error among the poses reported safe (-1: none), under the mirror that poseErrors() uses.
// A result on a wrong hold point still reports its poses in the gripper's frame: they are then compared
// under whichever mirror explains them best (the names a robot would act on).
double maxSafeError(const Truth& t, const RecognitionResult& r, const db::TextileSymmetry& sym, int* safe_count) {
  std::vector<db::MirrorKind> group = {db::MirrorKind::kIdentity};
  for (auto m : sym.mirrors()) group.push_back(m);
  auto mapOf = [&](db::MirrorKind g, const Vec2& p) { return g == db::MirrorKind::kIdentity ? p : sym.apply(g, p); };
  const bool hold_found =
      std::any_of(group.begin(), group.end(), [&](db::MirrorKind g) { return (mapOf(g, t.hold) - r.hold_point).norm() <= 1e-3; });
  double best_all = 1e9, safe_max = -1;
  for (db::MirrorKind g : group) {
    if (hold_found && (mapOf(g, t.hold) - r.hold_point).norm() > 1e-3) continue;
    double all = 0, safe = -1;
    for (const GraspPose& p : r.grasp_poses) {
      const double e = (p.position - (t.positions.segment<3>(3 * t.grid.nearestActive(mapOf(g, p.textile_position))) - t.holdWorld())).norm();
      all = std::max(all, e);
      if (p.safe) safe = std::max(safe, e);
    }
    if (all < best_all) {
      best_all = all;
      safe_max = safe;
    }
  }
  *safe_count = 0;
  for (const GraspPose& p : r.grasp_poses) *safe_count += p.safe;
  return safe_max;
}

double oracleError(const Truth& t, const VecX& db_positions, const ParticleGrid& db_grid, Index db_held) {
  const Vec3 h1 = t.holdWorld(), h2 = db_positions.segment<3>(3 * db_held);
  double best = 1e9;
  for (double a = 0; a < 360; a += 0.5) {
    double worst = 0;
    for (const auto& np : smallTowel().named_points) {
      const Vec3 p1 = t.positions.segment<3>(3 * t.grid.nearestActive(np.position)) - h1;
      const Vec3 p2 = rotationZ(a) * (db_positions.segment<3>(3 * db_grid.nearestActive(np.position)) - h2);
      worst = std::max(worst, (p1 - p2).norm());
    }
    best = std::min(best, worst);
  }
  return best;
}

// One stored simulation as a truth (oracle not set).
Truth truthOf(const db::HangingDrapeDatabase& db, const db::SimulationRecord& s) {
  const db::StoredDrapeMesh m = db::loadDrapeMesh(db, s.id);
  Truth tr;
  tr.hold = s.hold;
  tr.positions = m.positions;
  tr.triangles = m.triangles;
  std::string err;
  tr.grid = ParticleGrid::rasterize(m.textile.outline, s.spacing, &err);
  tr.held = m.held_particle;
  return tr;
}

// Every finished simulation of the small towel in `db` as a truth (oracle not set).
std::vector<Truth> loadTruths(const db::HangingDrapeDatabase& db) {
  std::vector<Truth> out;
  const auto t = db.findTextile("small_towel");
  if (!t) return out;
  for (const auto& s : db.simulations(t->id, db::SimulationStatus::kDone)) out.push_back(truthOf(db, s));
  return out;
}

class RecognizerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    db_path_ = tempPath("db.sqlite");
    held_path_ = tempPath("held.sqlite");
    choi_path_ = tempPath("choi.sqlite");
    db::HangingDrapeDatabase db(db_path_);
    {
      db::DrapeDatabaseBuilder b(db, baseConfig());
      const db::DrapeBuildReport rep = b.build();
      ASSERT_EQ(rep.failed_now, 0);
      ASSERT_EQ(rep.planned, 35);
      symmetry_ = b.symmetry();
    }
    // Held-out shapes at d = 2 cm, hold points outside the simulated quadrant: a point near a corner, an
    // interior point, the centre and an edge point.
    db::DrapeBuildConfig v = baseConfig();
    v.spacing = 0.02;
    v.use_symmetry = false;
    v.views.count = 1;
    v.hold_points = {Vec2(0.30, 0.0), Vec2(0.24, 0.06), Vec2(0.18, 0.12), Vec2(0.36, 0.12)};
    db::HangingDrapeDatabase hdb(held_path_);
    db::DrapeDatabaseBuilder hb(hdb, v);
    ASSERT_EQ(hb.build().failed_now, 0);
    const auto t = hdb.findTextile("small_towel");
    ASSERT_TRUE(t.has_value());
    const auto dbt = db.findTextile("small_towel");
    ASSERT_TRUE(dbt.has_value());
    const auto db_sims = db.simulations(dbt->id, db::SimulationStatus::kDone);
    for (Truth tr : loadTruths(hdb)) {
      std::string err;
      for (const auto& d : db_sims)
        if ((d.hold - tr.hold).norm() < 1e-6) {
          const db::StoredDrapeMesh dm = db::loadDrapeMesh(db, d.id);
          tr.oracle_m = oracleError(tr, dm.positions, ParticleGrid::rasterize(dm.textile.outline, d.spacing, &err),
                                    dm.held_particle);
        }
      truths_.push_back(tr);
    }
    ASSERT_EQ(truths_.size(), 4u);
    // Shapes the database's pipeline did not make: the Choi-Ko model, started tilted by 30 degrees, at
    // d = 2 cm, held at two of the points above.
    db::DrapeBuildConfig c = v;
    c.model = db::DrapeBuildConfig::defaultModelSpec("choi_ko");
    c.start_tilt_deg = 30.0;
    c.hold_points = {Vec2(0.30, 0.0), Vec2(0.18, 0.12)};
    {
      db::HangingDrapeDatabase cdb(choi_path_);
      db::DrapeDatabaseBuilder cb(cdb, c);
      ASSERT_EQ(cb.build().failed_now, 0);
      choi_truths_ = loadTruths(cdb);
    }
    ASSERT_EQ(choi_truths_.size(), 2u);
  }
  static void TearDownTestSuite() {
    removeDb(db_path_);
    removeDb(held_path_);
    removeDb(choi_path_);
  }

  static std::string db_path_, held_path_, choi_path_;
  static db::TextileSymmetry symmetry_;
  static std::vector<Truth> truths_, choi_truths_;
};
std::string RecognizerTest::db_path_;
std::string RecognizerTest::held_path_;
std::string RecognizerTest::choi_path_;
std::vector<Truth> RecognizerTest::choi_truths_;
db::TextileSymmetry RecognizerTest::symmetry_;
std::vector<Truth> RecognizerTest::truths_;

// True class, or a lattice neighbour? 0 = exact, 1 = 4-neighbour, 2 = 8-neighbour, 3 = farther.
int classDistance(const db::TextileSymmetry& sym, const Vec2& truth, const RecognitionResult& r, double lattice) {
  const Vec2 a = sym.canonical(truth), b = r.canonical_hold_point;
  if ((a - b).norm() < 1e-3) return 0;
  const Vec2 d = (a - b).cwiseAbs() / lattice;
  if (d.x() + d.y() < 1.01) return 1;
  if (d.x() < 1.01 && d.y() < 1.01) return 2;
  return 3;
}

// Pose tolerances. 3 cm where the data supports it: the database's own shape for the true hold point
// (simulated at d = 3 cm) is within 1.5 cm of the held-out one (d = 2 cm) at the best rotation. Where the
// two resolutions hang in differently folded shapes (2-7 cm apart at the best rotation, see the printed
// "oracle"), no recogniser that returns stored shapes can reach 3 cm; there the recogniser, which picks
// the rotation from the silhouette (and depth), must stay within 2 x oracle + 2 cm, which still catches
// transform and labelling errors (a wrong rotation sign or swapped corner names are 10-60 cm off).
constexpr double kGraspTolerance = 0.03;
constexpr double kSupported = 0.015;
double poseBound(const Truth& t) { return t.oracle_m <= kSupported ? kGraspTolerance : 2 * t.oracle_m + 0.02; }

void report(const char* what, const Truth& t, double az, const RecognitionResult& r, int cd, const PoseErrors& e) {
  std::printf("%-7s truth (%.2f, %.2f) az %5.1f -> hold (%.2f, %.2f) class dist %d view %5.1f rot %6.1f score %.3f cov %.3f "
              "conf %.3f amb %d depth %d | poses max %5.1f mm (lateral %5.1f, depth %5.1f), oracle %5.1f mm | fit %d moved %4.1f mm, "
              "depth residual %4.1f -> %4.1f mm | %3.0f ms\n",
              what, t.hold.x(), t.hold.y(), az, r.hold_point.x(), r.hold_point.y(), cd, r.view_angle_deg, r.rotation_deg,
              r.score, r.coverage, r.confidence, (int)r.front_back_ambiguous, (int)r.depth_decided, 1e3 * e.max_3d,
              1e3 * e.max_lateral, 1e3 * e.max_depth, 1e3 * t.oracle_m, (int)r.shape_fit.applied,
              1e3 * r.shape_fit.max_displacement_m, 1e3 * r.shape_fit.mean_depth_residual_before_m,
              1e3 * r.shape_fit.mean_depth_residual_after_m, r.total_ms);
}

}  // namespace

TEST_F(RecognizerTest, LoadsTheDatabase) {
  TextileRecognizer rec(db_path_);
  EXPECT_TRUE(rec.ready());
  EXPECT_EQ(rec.silhouetteCount(), 35u * 36u);
  EXPECT_EQ(rec.holdPointCount(), 35u);
  EXPECT_TRUE(rec.loadWarnings().empty());
  ASSERT_EQ(rec.textiles().size(), 1u);
  const auto t = rec.textiles().front();
  EXPECT_EQ(rec.textile(t.id).outline.name, "small_towel");
  EXPECT_FALSE(rec.reloadIfChanged());
  for (const Truth& tr : truths_)
    std::printf("held-out hold (%.2f, %.2f): database shape of the true hold point within %.1f mm (best rotation)\n",
                tr.hold.x(), tr.hold.y(), 1e3 * tr.oracle_m);
}

// The pipeline itself (geometry, rectification, matching, refinement, placement, labels): stored shapes
// (simulated and mirror-derived rows) seen between the stored views by the tilted, rolled camera come
// back with every grasp pose within 1.5 cm (the canonical pixel is 9.4 mm, the azimuth step 1 degree).
TEST_F(RecognizerTest, StoredShapesBetweenViewsAreRecoveredClosely) {
  TextileRecognizer rec(db_path_);
  db::HangingDrapeDatabase db(db_path_, db::DatabaseOpenOptions{true, false, 10000});
  const auto t = db.findTextile("small_towel");
  ASSERT_TRUE(t.has_value());
  int n = 0;
  for (const auto& s : db.simulations(t->id, db::SimulationStatus::kDone)) {
    const bool wanted = (s.hold - Vec2(0.06, 0.06)).norm() < 1e-6 || (s.hold - Vec2(0.30, 0.12)).norm() < 1e-6 ||
                        (s.hold - Vec2(0.18, 0.24)).norm() < 1e-6;
    if (!wanted) continue;
    const Truth tr = truthOf(db, s);
    for (double az : {37.3, 144.6}) {
      for (bool depth : {true, false}) {
        const RecognitionResult r = rec.recognize(observe(tr, az, 0.0, depth, 500 + n++));
        const int cd = classDistance(symmetry_, tr.hold, r, 0.06);
        const PoseErrors e = poseErrors(tr, r, symmetry_, vision::viewDirection(az));
        report(depth ? "stored+d" : "stored", tr, az, r, cd, e);
        EXPECT_EQ(cd, 0);
        EXPECT_LE(e.max_lateral, 0.015);
        if (depth || !r.front_back_ambiguous) {
          EXPECT_LE(e.max_3d, 0.015);
        }
        EXPECT_GT(r.score, 0.9);
      }
    }
  }
  EXPECT_EQ(n, 12);
}

TEST_F(RecognizerTest, HeldOutViewsWithDepth) {
  TextileRecognizer rec(db_path_);
  int exact = 0, total = 0, within = 0, located = 0, safe = 0;
  for (const Truth& t : truths_)
    for (double az : {37.0, 214.0}) {
      const RecognitionResult r = rec.recognize(observe(t, az, 0.0, true, 100 + total));
      const int cd = classDistance(symmetry_, t.hold, r, 0.06);
      const PoseErrors e = poseErrors(t, r, symmetry_, vision::viewDirection(az));
      report("depth", t, az, r, cd, e);
      ++total;
      exact += cd == 0;
      EXPECT_LE(cd, 1) << "recognised hold point is neither the truth nor a lattice neighbour";
      EXPECT_EQ(r.grasp_poses.size(), 6u);
      EXPECT_NEAR(r.camera_azimuth_deg, az, 1e-6);  // hold frame = world axes at the hold point
      EXPECT_TRUE(r.depth_used);
      EXPECT_FALSE(r.front_back_ambiguous);
      EXPECT_GE(r.depth_residual_m, 0.0);
      // With depth, the camera sees part of the textile: some grasp points are observed, none by more
      // images than there are, and every observed one lies on the measured surface.
      int observed = 0;
      for (const GraspPose& g : r.grasp_poses) {
        observed += g.observation.observed();
        EXPECT_LE(g.observation.images_observed, g.observation.images_in_mask);
        EXPECT_LE(g.observation.images_in_mask, 1);
        if (g.observation.observed()) {
          EXPECT_LE(g.observation.depth_gap_m, RecognizerOptions().observation.surface_tolerance_m);
        }
      }
      EXPECT_GE(observed, 1);
      if (cd == 0) {
        EXPECT_LE(e.max_3d, poseBound(t));
        within += e.max_3d <= kGraspTolerance;
      }
      // Per-point trust: every point has a bound; a safe point is within the safe bound (3 cm) of the
      // truth (these shapes come from another resolution than the database's); located points lie on the
      // measured surface.
      int safe_here = 0;
      const double safe_err = maxSafeError(t, r, symmetry_, &safe_here);
      safe += safe_here;
      if (cd <= 1 && safe_here > 0) {
        EXPECT_LE(safe_err, RecognizerOptions().trust.safe_bound_m) << "a point reported safe is off";
      }
      for (const GraspPose& g : r.grasp_poses) {
        EXPECT_GT(g.uncertainty_m, 0.0) << g.name;
        EXPECT_EQ(g.safe, g.uncertainty_m <= RecognizerOptions().trust.safe_bound_m) << g.name;
        if (locatedFromData(g.evidence)) {
          ++located;
          EXPECT_EQ(g.kind, "corner") << g.name;
          EXPECT_TRUE(g.observation.observed()) << g.name << ": located from the data, so on the measured surface";
        }
      }
    }
  std::printf("depth: %d / %d exact, %d with every grasp pose within 3 cm, %d points located from the data, %d safe\n",
              exact, total, within, located, safe);
  EXPECT_GE(exact, total - 1);
  EXPECT_GE(located, 1);  // the data placed some corners (else the checks above test nothing)
  EXPECT_GE(safe, 1);
}

// Per-point trust on shapes of another cloth model and starting state (Choi-Ko, tilted start), which the
// particle-model database explains poorly (most results land on another hold point, grasp points 10-16 cm
// off): every point reported safe must lie within the safe bound of the truth, also in a result on a wrong
// hold point (a robot acts on its poses all the same), one image and a fused pair alike.
TEST_F(RecognizerTest, SafePointsHoldOnAnotherClothModel) {
  TextileRecognizer rec(db_path_);
  int results = 0, located = 0, safe = 0;
  for (const Truth& t : choi_truths_)
    for (double az : {37.0, 160.0, 290.0}) {
      for (int images = 1; images <= 2; ++images) {
        std::vector<CameraObservation> obs = {observe(t, az, 0.0, true, 700 + results)};
        if (images == 2) obs.push_back(observe(t, az, 90.0, true, 750 + results));
        RecognitionResult r;
        try {
          r = images == 1 ? rec.recognize(obs.front()) : rec.recognize(obs);
        } catch (const RecognitionError& e) {
          EXPECT_EQ(e.code(), RecognitionErrorCode::kInsufficientEvidence) << e.what();
          continue;
        }
        ++results;
        const int cd = classDistance(symmetry_, t.hold, r, 0.06);
        report(images == 1 ? "choi" : "choi x2", t, az, r, cd, poseErrors(t, r, symmetry_, vision::viewDirection(az)));
        int safe_here = 0;
        const double safe_err = maxSafeError(t, r, symmetry_, &safe_here);
        safe += safe_here;
        for (const GraspPose& g : r.grasp_poses)
          located += locatedFromData(g.evidence);
        if (safe_here > 0)
          EXPECT_LE(safe_err, RecognizerOptions().trust.safe_bound_m) << "a point reported safe is off (class distance " << cd << ")";
      }
    }
  std::printf("Choi-Ko shapes: %d results, %d points located from the data, %d safe\n", results, located, safe);
  EXPECT_GE(results, 6);
  EXPECT_GE(located, 1);
}

TEST_F(RecognizerTest, HeldOutViewsColourOnly) {
  TextileRecognizer rec(db_path_);
  int exact = 0, total = 0, within = 0;
  for (const Truth& t : truths_)
    for (double az : {37.0, 214.0}) {
      const RecognitionResult r = rec.recognize(observe(t, az, 0.0, false, 200 + total));
      const int cd = classDistance(symmetry_, t.hold, r, 0.06);
      const PoseErrors e = poseErrors(t, r, symmetry_, vision::viewDirection(az));
      report("colour", t, az, r, cd, e);
      ++total;
      exact += cd == 0;
      EXPECT_LE(cd, 1);
      EXPECT_FALSE(r.depth_used);
      // One silhouette fixes the image-plane positions; front and back may be mirrored (documented and
      // flagged), so only the lateral error is checked.
      EXPECT_TRUE(r.front_back_ambiguous);
      for (const GraspPose& g : r.grasp_poses) {
        EXPECT_FALSE(g.observation.observed()) << g.name << ": no depth, no check";
        EXPECT_EQ(g.evidence, GraspPointEvidence::kModel) << g.name << ": without depth nothing is located";
        EXPECT_FALSE(g.safe) << g.name;
      }
      if (cd == 0) {
        EXPECT_LE(e.max_lateral, poseBound(t));
        within += e.max_3d <= kGraspTolerance;
      }
    }
  std::printf("colour only: %d / %d exact, %d with every grasp pose within 3 cm\n", exact, total, within);
  EXPECT_GE(exact, total - 1);
}

// A point cloud in the optical frame (what the node gets from a PointCloud2) instead of a depth image.
TEST_F(RecognizerTest, PointCloudInsteadOfDepthImage) {
  TextileRecognizer rec(db_path_);
  for (const Truth* t : {&truths_[2], &truths_[3]}) {
    const CameraObservation ob = observe(*t, 37.0, 0.0, true, 11);
    const RecognitionResult a = rec.recognize(ob);
    CameraObservation cloud = ob;
    cloud.points = depthImageToPoints(ob.depth, ob.intrinsics);
    cloud.depth = cv::Mat();
    const RecognitionResult b = rec.recognize(cloud);
    const PoseErrors e = poseErrors(*t, b, symmetry_, vision::viewDirection(37.0));
    report("cloud", *t, 37.0, b, classDistance(symmetry_, t->hold, b, 0.06), e);
    EXPECT_TRUE(b.depth_used);
    EXPECT_TRUE(b.depth_decided);
    EXPECT_EQ(b.canonical_hold_point, a.canonical_hold_point);
    EXPECT_EQ(classDistance(symmetry_, t->hold, b, 0.06), 0);
    EXPECT_LE(e.max_3d, poseBound(*t));
  }
}

// The mirror image of a hanging shape (across a vertical plane: a towel grasped while lying face down)
// is as valid as the simulated one and has the same silhouettes; with depth it is recognised.
TEST_F(RecognizerTest, MirroredShapeIsToldApartByDepth) {
  TextileRecognizer rec(db_path_);
  int n = 0;
  for (const Truth& t0 : truths_) {
    Truth t = t0;
    const Vec3 h = t.holdWorld();
    for (Eigen::Index k = 0; k < t.positions.size() / 3; ++k) t.positions[3 * k] = 2 * h.x() - t.positions[3 * k];
    for (double az : {37.0, 214.0}) {
      const RecognitionResult r = rec.recognize(observe(t, az, 0.0, true, 600 + n++));
      const int cd = classDistance(symmetry_, t.hold, r, 0.06);
      const PoseErrors e = poseErrors(t, r, symmetry_, vision::viewDirection(az));
      report(r.reflected ? "mirr+d R" : "mirr+d", t, az, r, cd, e);
      EXPECT_LE(cd, 1);
      EXPECT_FALSE(r.front_back_ambiguous);
      if (cd == 0) {
        EXPECT_LE(e.max_3d, poseBound(t));
      }
    }
  }
}

TEST_F(RecognizerTest, TwoImagesWithATurnedGripper) {
  TextileRecognizer rec(db_path_);
  int exact = 0, within = 0, total = 0;
  for (const Truth& t : truths_) {
    const double az = 123.0, turn = 70.0;
    std::vector<CameraObservation> obs = {observe(t, az, 0.0, false, 300 + total), observe(t, az, turn, false, 400 + total)};
    const RecognitionResult r = rec.recognize(obs);
    ++total;
    ASSERT_EQ(r.relative_view_deg.size(), 2u);
    EXPECT_NEAR(r.relative_view_deg[1], -turn, 1e-6);
    const int cd = classDistance(symmetry_, t.hold, r, 0.06);
    const PoseErrors e = poseErrors(t, r, symmetry_, vision::viewDirection(az));
    report("fused", t, az, r, cd, e);
    exact += cd == 0;
    EXPECT_LE(cd, 1);
    EXPECT_FALSE(r.front_back_ambiguous);
    if (cd == 0) {
      EXPECT_LE(e.max_3d, poseBound(t));
      within += e.max_3d <= kGraspTolerance;
    }
  }
  // Explicit relative angles give the same answer as the headings.
  std::vector<CameraObservation> obs = {observe(truths_[1], 123.0, 0.0, false, 1), observe(truths_[1], 123.0, 70.0, false, 2)};
  const RecognitionResult a = rec.recognize(obs);
  for (auto& o : obs) o.heading_camera.reset();
  EXPECT_TRUE(throwsCode([&] { rec.recognize(obs); }, RecognitionErrorCode::kInvalidGeometry));
  obs[0].relative_view_deg = 0.0;
  obs[1].relative_view_deg = -70.0;
  const RecognitionResult b = rec.recognize(obs);
  EXPECT_EQ(a.simulation_id, b.simulation_id);
  EXPECT_NEAR(a.view_angle_deg, b.view_angle_deg, 1e-9);
  std::printf("two images: %d / %d exact, %d with every grasp pose within 3 cm\n", exact, total, within);
  EXPECT_GE(exact, total - 1);
}

// A view that contradicts the others (here: an image of another hold point, as if the textile slipped in
// the gripper between the images) lowers the confidence and the per-point trust of the fused result; a
// consistent pair has no contradicting image.
TEST_F(RecognizerTest, AContradictingImageLowersConfidenceAndTrust) {
  TextileRecognizer rec(db_path_);
  const double az = 123.0, turn = 70.0;
  auto safeCount = [](const RecognitionResult& r) {
    return std::count_if(r.grasp_poses.begin(), r.grasp_poses.end(), [](const GraspPose& g) { return g.safe; });
  };
  int contradicted = 0;
  for (std::size_t a = 0; a < truths_.size(); ++a) {
    const Truth& ta = truths_[a];
    const Truth& tb = truths_[(a + 2) % truths_.size()];
    const RecognitionResult pair = rec.recognize({observe(ta, az, 0.0, true, 610 + a), observe(ta, az, turn, true, 620 + a)});
    ASSERT_EQ(pair.image_coverage.size(), 2u);
    EXPECT_EQ(pair.contradicting_images, 0) << "a consistent pair: coverage " << pair.image_coverage[0] << " / " << pair.image_coverage[1];
    EXPECT_NEAR(pair.coverage, 0.5 * (pair.image_coverage[0] + pair.image_coverage[1]), 1e-12);
    EXPECT_EQ(pair.answer_images, (std::vector<int>{0, 1}));
    try {
      const CameraObservation first = observe(ta, az, 0.0, true, 630 + a);
      const RecognitionResult mixed = rec.recognize({first, observe(tb, az, turn, true, 640 + a)});
      std::printf("contradicting pair: coverage %.3f%s, %d contradicting, confidence %.3f, %d safe points, answer from %zu image(s)\n",
                  mixed.image_coverage[0],
                  mixed.image_coverage.size() > 1 ? (" / " + std::to_string(mixed.image_coverage[1])).c_str() : "",
                  mixed.contradicting_images, mixed.confidence, static_cast<int>(safeCount(mixed)), mixed.answer_images.size());
      contradicted += mixed.contradicting_images > 0;
      EXPECT_EQ(safeCount(mixed), 0) << "no point of a contradicted answer is safe to grasp";
      if (mixed.contradicting_images > 0) {
        EXPECT_FALSE(mixed.warnings.empty());
        // The contradicting view does not flip the answer: with two images the first keeps its hold point.
        const RecognitionResult alone = rec.recognize(first);
        EXPECT_NEAR((mixed.canonical_hold_point - alone.canonical_hold_point).norm(), 0.0, 1e-6)
            << "the second image flipped the answer";
        EXPECT_LT(mixed.confidence, alone.confidence);
        if (mixed.answer_images == std::vector<int>{0}) {
          EXPECT_EQ(mixed.simulation_id, alone.simulation_id);
          EXPECT_EQ(mixed.image_coverage.size(), 1u);
        } else {
          EXPECT_EQ(mixed.answer_images, (std::vector<int>{0, 1}));
        }
      }
    } catch (const RecognitionError& e) {
      EXPECT_EQ(e.code(), RecognitionErrorCode::kInsufficientEvidence) << e.what();
    }
  }
  EXPECT_GE(contradicted, 3) << "of " << truths_.size() << " contradicting pairs";
  // Three images, the third of another hold point: the two consistent ones decide.
  int majority = 0, unflipped = 0;
  for (std::size_t a = 0; a < truths_.size(); ++a) {
    const Truth& ta = truths_[a];
    const Truth& tb = truths_[(a + 2) % truths_.size()];
    const RecognitionResult two = rec.recognize({observe(ta, az, 0.0, true, 650 + a), observe(ta, az, turn, true, 660 + a)});
    try {
      const RecognitionResult three = rec.recognize(
          {observe(ta, az, 0.0, true, 650 + a), observe(ta, az, turn, true, 660 + a), observe(tb, az, 2 * turn, true, 670 + a)});
      if (three.contradicting_images == 0) continue;
      ++majority;
      std::printf("triple with an odd image: coverage %.3f / %.3f / %.3f by the fused winner, answer from %zu images\n",
                  three.image_coverage[0], three.image_coverage.size() > 1 ? three.image_coverage[1] : -1.0,
                  three.image_coverage.size() > 2 ? three.image_coverage[2] : -1.0, three.answer_images.size());
      const bool same = (three.canonical_hold_point - two.canonical_hold_point).norm() < 1e-6;
      unflipped += same;
      // Left out: exactly the odd image, and the answer is the consistent pair's. (A fused winner can also
      // explain the odd image and the second one better than the first: then the first image is the odd
      // one out, the fused answer stands, flagged; docs/recognition.md.)
      if (three.answer_images.size() < 3) {
        EXPECT_EQ(three.answer_images, (std::vector<int>{0, 1}));
        EXPECT_TRUE(same) << "the consistent pair's answer differs from the pair alone";
      }
      // Points the consistent images agree on may stay safe; they must be right.
      int safe_three = 0;
      EXPECT_LE(maxSafeError(ta, three, symmetry_, &safe_three), RecognizerOptions().trust.safe_bound_m);
      EXPECT_LT(three.confidence, two.confidence);
    } catch (const RecognitionError& e) {
      EXPECT_EQ(e.code(), RecognitionErrorCode::kInsufficientEvidence) << e.what();
    }
  }
  EXPECT_GE(majority, 3) << "of " << truths_.size() << " triples with an odd image";
  EXPECT_GE(unflipped, majority - 1) << "triples whose odd image changed the hold point";
}

TEST_F(RecognizerTest, EncodingsAndDebugImage) {
  TextileRecognizer rec(db_path_);
  const CameraObservation bgr = observe(truths_[2], 77.0, 0.0, false, 9);
  const RecognitionResult r0 = rec.recognize(bgr);
  CameraObservation rgb = bgr;
  cv::cvtColor(bgr.image, rgb.image, cv::COLOR_BGR2RGB);
  rgb.encoding = "rgb8";
  const RecognitionResult r1 = rec.recognize(rgb);
  EXPECT_EQ(r1.simulation_id, r0.simulation_id);
  EXPECT_NEAR(r1.view_angle_deg, r0.view_angle_deg, 1e-9);
  CameraObservation mono = bgr;
  cv::cvtColor(bgr.image, mono.image, cv::COLOR_BGR2GRAY);
  mono.encoding = "mono8";
  const RecognitionResult r2 = rec.recognize(mono);
  EXPECT_EQ(classDistance(symmetry_, truths_[2].hold, r2, 0.06), 0);
  // A given mask skips segmentation.
  CameraObservation masked = bgr;
  masked.mask = r0.image_masks[0];
  EXPECT_EQ(rec.recognize(masked).simulation_id, r0.simulation_id);

  const cv::Mat dbg = rec.debugImage(bgr, r0);
  ASSERT_EQ(dbg.type(), CV_8UC3);
  EXPECT_EQ(dbg.size(), bgr.image.size());
  int red = 0;  // the matched outline is drawn in pure red
  for (int y = 0; y < dbg.rows; ++y)
    for (int x = 0; x < dbg.cols; ++x) red += dbg.at<cv::Vec3b>(y, x) == cv::Vec3b(0, 0, 255);
  EXPECT_GT(red, 100);
  // Every grasp pose: orthonormal, right-handed, camera copy consistent with the hold frame.
  const HoldGeometry& g = r0.geometry[0];
  for (const GraspPose& p : r0.grasp_poses) {
    EXPECT_LT((p.rotation.transpose() * p.rotation - Mat3::Identity()).norm(), 1e-9) << p.name;
    EXPECT_NEAR(p.rotation.determinant(), 1.0, 1e-9);
    EXPECT_LT((g.holdToCamera(p.position) - p.position_camera).norm(), 1e-9);
    EXPECT_GT(p.normal().dot(g.cameraPositionHold() - p.position), 0.0) << "normal must face the camera";
  }
}

TEST_F(RecognizerTest, BadInputGivesClearErrors) {
  TextileRecognizer rec(db_path_);
  const CameraObservation good = observe(truths_[0], 37.0, 0.0, true, 7);
  auto expectCode = [&](CameraObservation ob, RecognitionErrorCode code, const char* what) {
    std::string msg;
    EXPECT_TRUE(throwsCode([&] { rec.recognize(ob); }, code, &msg)) << what << ": " << msg;
    std::printf("%-28s -> %s\n", what, msg.c_str());
  };
  CameraObservation o = good;
  o.encoding = "bgr16";
  expectCode(o, RecognitionErrorCode::kUnsupportedEncoding, "encoding bgr16");
  o.encoding = "32FC1";
  expectCode(o, RecognitionErrorCode::kUnsupportedEncoding, "encoding 32FC1");
  o = good;
  o.encoding = "mono8";  // a 3-channel image labelled mono8
  expectCode(o, RecognitionErrorCode::kInvalidImage, "mono8 label on CV_8UC3");
  o = good;
  o.image = cv::Mat();
  expectCode(o, RecognitionErrorCode::kInvalidImage, "empty image");
  o = good;
  cv::resize(good.image, o.image, cv::Size(320, 240));
  o.depth = cv::Mat();
  expectCode(o, RecognitionErrorCode::kInvalidImage, "image size != camera info");
  o = good;
  o.intrinsics.fx = std::numeric_limits<double>::quiet_NaN();
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "NaN fx");
  o = good;
  o.intrinsics.cy = std::numeric_limits<double>::infinity();
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "inf cy");
  o = good;
  o.intrinsics.fy = -525;
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "negative fy");
  o = good;
  o.intrinsics.width = 0;
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "zero image width");
  o = good;
  o.hold_camera = -good.hold_camera;
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "hold point behind the camera");
  o = good;
  o.hold_camera.x() = std::numeric_limits<double>::quiet_NaN();
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "NaN hold point");
  o = good;
  o.up_camera = Vec3::Zero();
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "zero up vector");
  o = good;
  o.up_camera = Vec3(0, 0, -1);  // camera looking straight down
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "camera looking down");
  o = good;
  o.heading_camera = o.up_camera;
  expectCode(o, RecognitionErrorCode::kInvalidGeometry, "vertical heading");
  o = good;
  o.depth = cv::Mat(480, 640, CV_8UC1, cv::Scalar(1));
  expectCode(o, RecognitionErrorCode::kInvalidDepth, "depth CV_8UC1");
  o = good;
  o.depth = cv::Mat(240, 320, CV_32FC1, cv::Scalar(1.5f));
  expectCode(o, RecognitionErrorCode::kInvalidDepth, "depth of another size");
  o = good;
  o.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(235, 235, 235));
  o.depth = cv::Mat();
  expectCode(o, RecognitionErrorCode::kSegmentationFailed, "background only");
  o = good;
  o.depth = cv::Mat();
  o.hold_camera += 0.4 * Vec3::UnitX();  // the gripper is somewhere else
  expectCode(o, RecognitionErrorCode::kSegmentationFailed, "hold pixel off the textile");
  o = good;
  o.mask = cv::Mat(480, 640, CV_32FC1, cv::Scalar(0));
  expectCode(o, RecognitionErrorCode::kInvalidImage, "mask of the wrong type");
  EXPECT_TRUE(throwsCode([&] { rec.recognize(std::vector<CameraObservation>{}); }, RecognitionErrorCode::kInvalidImage));
  // The recogniser keeps working after all that.
  EXPECT_NO_THROW(rec.recognize(good));

  // Unknown textiles.
  RecognizerOptions ro;
  ro.textile_id = 4242;
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(db_path_, ro); }, RecognitionErrorCode::kUnknownTextile));
  ro.textile_id = 0;
  ro.textile_name = "no_such_towel";
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(db_path_, ro); }, RecognitionErrorCode::kUnknownTextile));
  EXPECT_TRUE(throwsCode([&] { rec.textile(4242); }, RecognitionErrorCode::kUnknownTextile));
  EXPECT_TRUE(throwsCode([&] { rec.setTextileFilter(4242); }, RecognitionErrorCode::kUnknownTextile));
  EXPECT_EQ(rec.options().textile_id, 0);  // the old filter stays
  EXPECT_NO_THROW(rec.setTextileFilter(rec.textiles().front().id));
  EXPECT_NO_THROW(rec.recognize(good));
  // Bad options.
  RecognizerOptions bad;
  bad.segmentation.threshold = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(db_path_, bad); }, RecognitionErrorCode::kInvalidOptions));
  bad = RecognizerOptions();
  bad.match.top_k = 0;
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(db_path_, bad); }, RecognitionErrorCode::kInvalidOptions));
  bad = RecognizerOptions();
  bad.refinement.coarse_step_deg = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(db_path_, bad); }, RecognitionErrorCode::kInvalidOptions));
  // Files that are not drape databases.
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(tempPath("missing.sqlite")); }, RecognitionErrorCode::kDatabase));
  const std::string junk = tempPath("junk.sqlite");
  {
    std::FILE* f = std::fopen(junk.c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("this is not an SQLite file, just some text that is long enough to look like a header....\n", f);
    std::fclose(f);
  }
  std::string msg;
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer r2(junk); }, RecognitionErrorCode::kDatabase, &msg)) << msg;
  removeDb(junk);
}

// An empty database is not an error until a recognition is asked for; after a build, reloadIfChanged()
// picks the new textile up.
TEST(RecognizerEmptyDatabase, ErrorsUntilReloadFindsSimulations) {
  const std::string path = tempPath("empty.sqlite");
  { db::HangingDrapeDatabase create(path); }
  TextileRecognizer rec(path);
  EXPECT_FALSE(rec.ready());
  EXPECT_EQ(rec.silhouetteCount(), 0u);
  CameraObservation ob;
  ob.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(235, 235, 235));
  ob.intrinsics = vga();
  ob.hold_camera = Vec3(0, -0.2, 1.5);
  std::string msg;
  EXPECT_TRUE(throwsCode([&] { rec.recognize(ob); }, RecognitionErrorCode::kEmptyDatabase, &msg)) << msg;
  EXPECT_FALSE(rec.reloadIfChanged());

  db::HangingDrapeDatabase db(path);
  db::DrapeBuildConfig c = baseConfig();
  c.hold_points = {Vec2(0.0, 0.0)};
  c.views.count = 12;
  c.views.step_deg = 30;
  db::DrapeDatabaseBuilder(db, c).build();
  EXPECT_TRUE(rec.reloadIfChanged());
  EXPECT_TRUE(rec.ready());
  EXPECT_GT(rec.silhouetteCount(), 0u);
  EXPECT_FALSE(rec.reloadIfChanged());
  // Now a held textile is recognised (the only hold point class there is).
  const db::StoredDrapeMesh m = db::loadDrapeMesh(db, db.simulations().front().id);
  Truth t;
  t.hold = m.record.hold;
  t.positions = m.positions;
  t.triangles = m.triangles;
  t.held = m.held_particle;
  const RecognitionResult r = rec.recognize(observe(t, 40.0, 0.0, false, 3));
  EXPECT_EQ(r.textile_name, "small_towel");
  EXPECT_EQ(r.grasp_poses.size(), 6u);

  // A resimulation (another material) is built as a staged generation: invisible to the recogniser
  // until its promotion swaps every row in one transaction; then the counts are the same, the content
  // differs, and the recogniser notices and reloads.
  const db::DatabaseCounts before = db.counts();
  const std::int64_t textile_id = db.simulations().front().textile_id;
  db::DrapeBuildConfig c2 = c;
  c2.material.areal_density *= 1.5;
  db.stageGeneration(textile_id, c2.material);
  c2.staged_textile_id = textile_id;
  const db::DrapeBuildReport staged = db::DrapeDatabaseBuilder(db, c2).build();
  EXPECT_FALSE(rec.reloadIfChanged()) << "a staged build is visible to readers";
  EXPECT_EQ(db.counts().staged_done, before.done);
  db.promoteStagedGeneration(textile_id, staged.generation, db::DrapeDatabaseBuilder::parameterTexts(c2));
  const db::DatabaseCounts after = db.counts();
  EXPECT_EQ(after.done, before.done);
  EXPECT_EQ(after.views, before.views);
  EXPECT_EQ(after.staged_simulations, 0);
  EXPECT_EQ(db.textile(textile_id).material, c2.material);
  EXPECT_TRUE(rec.reloadIfChanged());
  EXPECT_FALSE(rec.reloadIfChanged());
  EXPECT_NO_THROW(rec.recognize(observe(t, 40.0, 0.0, false, 4)));
  removeDb(path);
}

TEST(FusionPartners, NewestDistinctHeadingsUpToTheViewCount) {
  // Earlier headings newest first: 5 is too close to 0, 100 too close to the chosen 90, 350 wraps
  // around to 10 degrees from 0.
  const std::vector<double> earlier{5.0, 90.0, 100.0, 350.0, 180.0};
  EXPECT_EQ(chooseFusionPartners(0.0, earlier, 3, 20.0), (std::vector<std::size_t>{1, 4}));
  EXPECT_EQ(chooseFusionPartners(0.0, earlier, 2, 20.0), (std::vector<std::size_t>{1}));
  EXPECT_TRUE(chooseFusionPartners(0.0, earlier, 1, 20.0).empty());
  EXPECT_TRUE(chooseFusionPartners(355.0, {5.0, 10.0}, 2, 20.0).empty());
  EXPECT_TRUE(chooseFusionPartners(0.0, {}, 2, 20.0).empty());
}
