// The minimum-evidence rule (docs/recognition.md "Evidence") on a small database (the 36 x 24 cm towel,
// d = 3 cm, a 12 cm hold-point lattice over one quadrant with its mirrors, 12 views): stored shapes seen
// by the test camera succeed above the floors; hostile frames (all black, uniform grey, too large),
// implausible cameras (fx = 1, NaN intrinsics, far principal point) and damaged or lost database entries
// are typed errors with the reason, never a success. A short seeded fuzz of the image path ends in a
// success that meets the floors or a RecognitionError, nothing else.
#include <gtest/gtest.h>

#include <unistd.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "recognition_test_support.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;
using textile_handling::test_support::throwsCode;
using textile_handling::test_support::vga;

namespace {

std::string dbCopy(const std::string& from, const std::string& name) {
  const std::string to = from + "." + name;
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(to + s);
  std::filesystem::copy_file(from, to);
  return to;
}

class EvidenceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = test_support::freshTempDir("th_evidence");
    db_path_ = dir_ + "/db.sqlite";
    db::HangingDrapeDatabase db(db_path_);
    db::DrapeDatabaseBuilder b(db, test_support::smallTowelBuildConfig());
    ASSERT_EQ(b.build().failed_now, 0);
    sims_ = db.simulations(0, db::SimulationStatus::kDone);
    ASSERT_GE(sims_.size(), 4u);
    mesh_ = db::loadDrapeMesh(db, sims_.front().id);
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir_); }

  // The stored shape of the first simulation seen by the test camera at a stored azimuth (with its
  // rendered depth if `depth`).
  static CameraObservation observation(double azimuth = 60.0, bool depth = false) {
    return test_support::renderedObservation(mesh_, azimuth, depth);
  }

  static std::string dir_, db_path_;
  static std::vector<db::SimulationRecord> sims_;
  static db::StoredDrapeMesh mesh_;
};
std::string EvidenceTest::dir_, EvidenceTest::db_path_;
std::vector<db::SimulationRecord> EvidenceTest::sims_;
db::StoredDrapeMesh EvidenceTest::mesh_;

TEST_F(EvidenceTest, StoredShapesSucceedAboveTheFloors) {
  const TextileRecognizer rec(db_path_);
  const EvidenceOptions floors;
  for (double az : {0.0, 60.0, 150.0, 270.0}) {
    const RecognitionResult r = rec.recognize(observation(az));
    std::printf("azimuth %5.1f: score %.3f coverage %.3f colour fraction %.3f (floors %.2f, %.2f, ceiling %.2f)\n", az,
                r.score, r.coverage, r.colour_fraction, floors.min_score, floors.min_coverage, floors.max_colour_fraction);
    EXPECT_GE(r.score, floors.min_score + 0.1) << "no margin above the score floor at azimuth " << az;
    EXPECT_GE(r.coverage, floors.min_coverage + 0.1) << "no margin above the coverage floor at azimuth " << az;
    EXPECT_LE(r.colour_fraction, floors.max_colour_fraction - 0.2) << "no margin below the colour ceiling at azimuth " << az;
    EXPECT_EQ(r.skipped_views, 0u);
    EXPECT_TRUE(r.warnings.empty());
  }
}

// What the hostile frames score without the floors and plausibility limits (docs/recognition.md table).
TEST_F(EvidenceTest, HostileFramesScoreFarBelowTheFloorsWithoutThem) {
  RecognizerOptions open;
  open.evidence.min_score = open.evidence.min_coverage = 0;
  open.evidence.max_colour_fraction = 1;
  open.geometry.min_fov_deg = 0;
  open.geometry.max_fov_deg = 179.9;
  const TextileRecognizer rec(db_path_, open);
  const EvidenceOptions floors;
  auto measure = [&](const char* what, const CameraObservation& ob, bool hostile = true) {
    try {
      const RecognitionResult r = rec.recognize(ob);
      std::printf("%-22s score %.3f coverage %.3f colour fraction %.3f\n", what, r.score, r.coverage, r.colour_fraction);
      EXPECT_TRUE(!hostile || r.score < floors.min_score || r.coverage < floors.min_coverage ||
                  r.colour_fraction > floors.max_colour_fraction)
          << what;
    } catch (const RecognitionError& e) {
      std::printf("%-22s %s\n", what, e.what());
    }
  };
  CameraObservation ob = observation();
  ob.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));
  measure("all black", ob);
  ob.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(128, 128, 128));
  measure("uniform grey", ob);
  ob = observation(60.0, true);
  measure("stored shape, depth", ob, false);
  ob.image.setTo(cv::Scalar(0, 0, 0));
  measure("all black, depth", ob);
  ob = observation();
  ob.intrinsics.fx = ob.intrinsics.fy = 1.0;
  measure("fx = fy = 1", ob);
  ob = observation();
  ob.intrinsics.fx = 1.0;
  measure("fx = 1", ob);
}

TEST_F(EvidenceTest, HostileFramesAreInsufficientEvidence) {
  const TextileRecognizer rec(db_path_);
  CameraObservation ob = observation();
  std::string msg;
  ob.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(0, 0, 0));  // all black: everything differs from the background
  EXPECT_TRUE(throwsCode([&] { rec.recognize(ob); }, RecognitionErrorCode::kInsufficientEvidence, &msg)) << msg;
  EXPECT_NE(msg.find("% of the image"), std::string::npos) << msg;
  // Depth still outlines the textile, yet the colour frame carries no evidence.
  CameraObservation with_depth = observation(60.0, true);
  with_depth.image.setTo(cv::Scalar(0, 0, 0));
  EXPECT_TRUE(throwsCode([&] { rec.recognize(with_depth); }, RecognitionErrorCode::kInsufficientEvidence, &msg)) << msg;
  ob.image = cv::Mat(480, 640, CV_8UC3, cv::Scalar(128, 128, 128));  // uniform grey
  EXPECT_TRUE(throwsCode([&] { rec.recognize(ob); }, RecognitionErrorCode::kInsufficientEvidence, &msg)) << msg;
  // Without the colour ceiling the score and coverage floors still refuse it.
  RecognizerOptions no_ceiling;
  no_ceiling.evidence.max_colour_fraction = 1.0;
  EXPECT_TRUE(throwsCode([&] { TextileRecognizer(db_path_, no_ceiling).recognize(ob); },
                         RecognitionErrorCode::kInsufficientEvidence, &msg))
      << msg;
  EXPECT_NE(msg.find("floor"), std::string::npos) << msg;
  // A grey 8000 x 8000 frame (with matching intrinsics) is refused by its size before any conversion.
  CameraObservation big = ob;
  big.image = cv::Mat(8000, 8000, CV_8UC1, cv::Scalar(128));
  big.encoding = "mono8";
  big.intrinsics = vision::PinholeIntrinsics{6000, 6000, 3999.5, 3999.5, 8000, 8000};
  EXPECT_TRUE(throwsCode([&] { rec.recognize(big); }, RecognitionErrorCode::kImageTooLarge, &msg)) << msg;
  EXPECT_NE(msg.find("8000 x 8000"), std::string::npos) << msg;
}

TEST_F(EvidenceTest, ImplausibleCamerasAreRefused) {
  const TextileRecognizer rec(db_path_);
  std::string msg;
  auto refused = [&](const std::function<void(CameraObservation&)>& change, const char* needle) {
    CameraObservation ob = observation();
    change(ob);
    const bool ok = throwsCode([&] { rec.recognize(ob); }, RecognitionErrorCode::kInvalidGeometry, &msg);
    EXPECT_TRUE(ok) << needle << ": " << msg;
    EXPECT_NE(msg.find(needle), std::string::npos) << msg;
  };
  refused([](CameraObservation& o) { o.intrinsics.fx = o.intrinsics.fy = 1.0; }, "field of view");
  refused([](CameraObservation& o) { o.intrinsics.fx = 1.0; }, "field of view");
  refused([](CameraObservation& o) { o.intrinsics.fy = std::numeric_limits<double>::quiet_NaN(); }, "not finite");
  refused([](CameraObservation& o) { o.intrinsics.fx = 400, o.intrinsics.fy = 1200; }, "fy / fx");
  refused([](CameraObservation& o) { o.intrinsics.cx = 5000; }, "principal point");
  refused([](CameraObservation& o) { o.hold_camera *= 100.0; }, "farther than");
}

TEST_F(EvidenceTest, AFlippedMaskByteSkipsOneViewAndIsReported) {
  const std::string path = dbCopy(db_path_, "flipped");
  const auto ids = test_support::storedViewIds(path);
  ASSERT_EQ(test_support::flipStoredMaskBytes(path, {ids[5]}), 1);
  const TextileRecognizer intact(db_path_);
  const TextileRecognizer rec(path);
  EXPECT_EQ(rec.silhouetteCount(), intact.silhouetteCount() - 1);
  ASSERT_EQ(rec.skippedViews().size(), 1u);
  const db::SkippedView s = rec.skippedViews().front();
  EXPECT_EQ(s.view_id, ids[5]);
  EXPECT_GT(s.simulation_id, 0);
  EXPECT_EQ(s.textile, "small_towel");
  EXPECT_FALSE(s.reason.empty());
  const RecognitionResult r = rec.recognize(observation());
  EXPECT_EQ(r.textile_name, "small_towel");
  EXPECT_EQ(r.skipped_views, 1u);
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings.front().find("view " + std::to_string(ids[5])), std::string::npos) << r.warnings.front();
}

TEST_F(EvidenceTest, ManyDamagedOrLostViewsMakeTheDatabaseIncomplete) {
  const auto ids = test_support::storedViewIds(db_path_);
  std::string msg;
  {  // a quarter of the views damaged
    const std::string path = dbCopy(db_path_, "damaged");
    std::vector<std::int64_t> some;
    for (std::size_t k = 0; k < ids.size(); k += 4) some.push_back(ids[k]);
    test_support::flipStoredMaskBytes(path, some);
    const TextileRecognizer rec(path);
    EXPECT_TRUE(rec.ready());
    EXPECT_TRUE(throwsCode([&] { rec.recognize(observation()); }, RecognitionErrorCode::kIncompleteDatabase, &msg)) << msg;
    EXPECT_NE(msg.find("small_towel"), std::string::npos) << msg;
    RecognizerOptions lenient;
    lenient.evidence.max_lost_view_fraction = 1.0;
    EXPECT_NO_THROW(TextileRecognizer(path, lenient).recognize(observation()));
  }
  {  // every view of two finished simulations deleted: their hold points are lost
    const std::string path = dbCopy(db_path_, "lost");
    {
      db::HangingDrapeDatabase db(path);
      db.withConnection([&](db::SqlConnection& c) {
        db::SqlStatement d = c.prepare("DELETE FROM views WHERE simulation_id IN (?1, ?2)");
        d.bind(1, sims_[1].id).bind(2, sims_[2].id);
        d.step();
      });
    }
    const TextileRecognizer rec(path);
    EXPECT_TRUE(throwsCode([&] { rec.recognize(observation()); }, RecognitionErrorCode::kIncompleteDatabase, &msg)) << msg;
    EXPECT_NE(msg.find("finished simulations"), std::string::npos) << msg;
  }
  {  // every view damaged: the textile has no usable entries
    const std::string path = dbCopy(db_path_, "all_damaged");
    test_support::flipStoredMaskBytes(path, ids);
    const TextileRecognizer rec(path);
    EXPECT_FALSE(rec.ready());
    EXPECT_TRUE(throwsCode([&] { rec.recognize(observation()); }, RecognitionErrorCode::kEmptyDatabase, &msg)) << msg;
    EXPECT_NE(msg.find("damaged or missing"), std::string::npos) << msg;
  }
}

TEST_F(EvidenceTest, AnUnbuiltTextileFailsResultsUnlessIgnored) {
  const std::string path = dbCopy(db_path_, "unbuilt");
  {
    db::HangingDrapeDatabase db(path);
    TextileOutline other = test_support::smallTowel();
    other.name = "new_towel";
    Material cotton;
    cotton.name = "cotton";
    db.addTextile(other, cotton);
  }
  std::string msg;
  const TextileRecognizer strict(path);
  EXPECT_TRUE(throwsCode([&] { strict.recognize(observation()); }, RecognitionErrorCode::kIncompleteDatabase, &msg)) << msg;
  EXPECT_NE(msg.find("new_towel"), std::string::npos) << msg;
  RecognizerOptions o;
  o.evidence.ignore_unbuilt_textiles = true;
  const RecognitionResult r = TextileRecognizer(path, o).recognize(observation());
  EXPECT_EQ(r.textile_name, "small_towel");
  ASSERT_EQ(r.warnings.size(), 1u);
  EXPECT_NE(r.warnings.front().find("new_towel"), std::string::npos) << r.warnings.front();
  // Restricted to the built textile, the unbuilt one does not matter.
  RecognizerOptions only;
  only.textile_name = "small_towel";
  EXPECT_NO_THROW(TextileRecognizer(path, only).recognize(observation()));
}

// Random images through the core entry the node uses: sizes within the limits, encodings, channel
// counts, garbage pixels, random / NaN intrinsics and hold points, random depth.
TEST_F(EvidenceTest, FuzzedImagesEndInAFlooredSuccessOrATypedError) {
  RecognizerOptions o;
  o.max_image_pixels = 1'000'000;
  const TextileRecognizer rec(db_path_, o);
  std::mt19937_64 rng(20261202);
  auto uni = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  auto pick = [&](int n) { return static_cast<int>(rng() % static_cast<std::uint64_t>(n)); };
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::string> encodings{"bgr8", "rgb8", "mono8", "bgra8", "16UC1", "", "garbage"};
  const std::vector<int> types{CV_8UC3, CV_8UC1, CV_8UC4, CV_16UC1, CV_32FC1};
  int successes = 0, errors = 0;
  for (int it = 0; it < 60; ++it) {
    // Modes: 0 the rendered frame as it is, 1 with random patches painted over it, 2 with random camera
    // and hold point, 3 a garbage image of random size, type and encoding (each with random depth).
    const int mode = it % 4;
    CameraObservation ob = observation(uni(0, 360));
    if (mode == 1)
      for (int k = 0, n = 1 + pick(6); k < n; ++k)
        cv::rectangle(ob.image, cv::Rect(pick(640), pick(480), 1 + pick(300), 1 + pick(300)),
                      cv::Scalar(pick(256), pick(256), pick(256)), cv::FILLED);
    if (mode == 2) {
      const double f[] = {1.0, 525.0, uni(0.5, 5000), -300.0, nan};
      ob.intrinsics.fx = f[pick(5)];
      if (pick(2)) ob.intrinsics.cy = pick(2) ? nan : uni(-5000, 5000);
      ob.hold_camera = Vec3(uni(-2, 2), uni(-2, 2), pick(4) ? uni(-1, 5) : nan);
    }
    if (mode == 3) {
      const int w = 1 + pick(1200), h = 1 + pick(900);
      ob.image = cv::Mat(h, w, types[static_cast<std::size_t>(pick(static_cast<int>(types.size())))]);
      cv::randu(ob.image, 0, 255);
      ob.intrinsics.width = pick(4) ? w : 1 + pick(1200);
      ob.intrinsics.height = pick(4) ? h : 1 + pick(900);
      ob.encoding = encodings[static_cast<std::size_t>(pick(static_cast<int>(encodings.size())))];
    }
    if (pick(3) == 0) {
      const int dt = pick(2) ? CV_32FC1 : CV_16UC1;
      ob.depth = cv::Mat(pick(3) ? ob.intrinsics.height : 7, pick(3) ? ob.intrinsics.width : 9, dt);
      cv::randu(ob.depth, 0, dt == CV_32FC1 ? 3.0 : 3000.0);
    }
    try {
      const RecognitionResult r = rec.recognize(ob);
      ++successes;
      EXPECT_GE(r.score, o.evidence.min_score) << "iteration " << it;
      EXPECT_GE(r.coverage, o.evidence.min_coverage) << "iteration " << it;
    } catch (const RecognitionError& e) {
      ++errors;
      EXPECT_GT(std::string(e.what()).size(), std::string(toString(e.code())).size() + 2) << "iteration " << it;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "iteration " << it << ": untyped exception " << e.what();
    }
  }
  std::printf("fuzz: %d successes, %d typed errors\n", successes, errors);
  EXPECT_GT(errors, 0);
  EXPECT_GT(successes, 0);  // the floors were exercised
}

}  // namespace

// Which fused images contradict: a coverage far below the best image's, or a large regret (the image
// alone matches another shape much better) - never every image: the one with the least regret stays.
TEST(ContradictingImages, CoverageGapOrRegretButOneImageAlwaysStays) {
  EvidenceOptions o;  // gap 0.1, regret 0.2
  using V = std::vector<bool>;
  EXPECT_EQ(contradictingImages({0.8}, {0.5}, o), V({false}));             // one image: nothing to contradict
  EXPECT_EQ(contradictingImages({0.85, 0.80}, {0.02, 0.05}, o), V({false, false}));
  EXPECT_EQ(contradictingImages({0.85, 0.70}, {0.02, 0.05}, o), V({false, true}));  // covered 0.15 worse
  EXPECT_EQ(contradictingImages({0.80, 0.82}, {0.02, 0.25}, o), V({false, true}));  // alone it points elsewhere
  EXPECT_EQ(contradictingImages({0.80, 0.82}, {0.30, 0.25}, o), V({true, false}));  // both: the lesser regret stays
  EXPECT_EQ(contradictingImages({0.80, 0.82, 0.81}, {0.01, 0.25, 0.21}, o), V({false, true, true}));
  EXPECT_EQ(contradictingImages({0.80, 0.82}, {}, o), V({false, false}));   // no regrets measured
  o.contradiction_regret = 1.0;  // the regret test off
  EXPECT_EQ(contradictingImages({0.80, 0.82}, {0.02, 0.9}, o), V({false, false}));
  o.contradiction_regret = std::nan("");
  EXPECT_THROW(o.validate(), RecognitionError);
}
