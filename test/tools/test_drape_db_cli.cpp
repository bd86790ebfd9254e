// drape_db as a process against hostile command lines and inputs: each must exit with the usage / bad
// input status (2) and a message naming the argument at fault, instead of growing without bound. The
// child's address space is capped at 4 GiB (setrlimit) and its run time at 120 s, so a regression fails
// here instead of exhausting the machine.
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "../recognition/recognition_test_support.h"
#include "tool_process.h"
#include "textile_handling/db/drape_build_job.h"
#include "textile_handling/db/drape_build_members.h"
#include "textile_handling/db/drape_database_builder.h"

using namespace textile_handling;

namespace {

using tool_process::ToolRun;

ToolRun runDrapeDb(const std::vector<std::string>& args) {
  const ToolRun r = tool_process::runTool(DRAPE_DB_EXE, args);
  EXPECT_FALSE(r.timed_out) << "drape_db did not finish within 120 s";
  return r;
}

// `drape_db build --auto` of the square held at its corner into `db` (4 views, one thread, no mirror), with
// the search's candidate spacings, named-point tolerance and IoU bound, plus `extra` arguments.
ToolRun autoBuildOfSquareCorner(const std::string& db, const std::string& spacings, const std::string& tolerance,
                                const std::string& min_iou, const std::vector<std::string>& extra = {}) {
  std::vector<std::string> args = {"build", "--db", db, "--textile", "square", "--hold", "0,0", "--views", "4", "--threads", "1",
                                   "--no-symmetry", "--auto", "--auto-spacings", spacings, "--auto-tolerance", tolerance,
                                   "--auto-min-iou", min_iou, "--auto-samples", "1", "--quiet"};
  args.insert(args.end(), extra.begin(), extra.end());
  return runDrapeDb(args);
}

class DrapeDbCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = test_support::freshTempDir("th_drape_db_cli");
    db_ = dir_ + "/good.sqlite";
    db::HangingDrapeDatabase database(db_);
    db::DrapeBuildConfig c;
    c.textile = test_support::smallTowel();
    c.spacing = 0.04;
    c.hold_points = {Vec2(0.0, 0.0), Vec2(0.18, 0.0)};
    c.use_symmetry = false;
    c.views.count = 4;
    c.views.step_deg = 90;
    c.workers = 1;
    db::DrapeDatabaseBuilder b(database, c);
    ASSERT_EQ(b.build().failed_now, 0);
    // A 64 x 64 mask: a 20 x 40 px rectangle hanging from (32, 4).
    cv::Mat m(64, 64, CV_8UC1, cv::Scalar(0));
    m(cv::Rect(22, 4, 20, 40)).setTo(255);
    mask_ = dir_ + "/ok64.png";
    cv::imwrite(mask_, m);
  }
  static void TearDownTestSuite() { std::filesystem::remove_all(dir_); }

  static ToolRun query(std::vector<std::string> extra) {
    std::vector<std::string> args{"query", "--db", db_};
    args.insert(args.end(), extra.begin(), extra.end());
    return runDrapeDb(args);
  }
  /// The simulation rows of the 'square' textile in the database at `path`, opened read-only.
  static std::vector<db::SimulationRecord> squareRows(const std::string& path) {
    db::DatabaseOpenOptions o;
    o.read_only = true;
    o.create = false;
    db::HangingDrapeDatabase database(path, o);
    const auto t = database.findTextile("square");
    EXPECT_TRUE(t) << path;
    return t ? database.simulations(t->id) : std::vector<db::SimulationRecord>{};
  }
  static void expectRefused(const ToolRun& r, const std::string& names) {
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_NE(r.err.find(names), std::string::npos) << "the message does not name " << names << ": " << r.err;
  }

  static std::string dir_, db_, mask_;
};
std::string DrapeDbCli::dir_, DrapeDbCli::db_, DrapeDbCli::mask_;

TEST_F(DrapeDbCli, AnIntactQuerySucceeds) {
  const ToolRun r = query({"--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("rank"), std::string::npos) << r.out;
}

TEST_F(DrapeDbCli, HostileScalesHoldPixelsShiftsAndCountsAreRefused) {
  expectRefused(query({"--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "1e-300"}), "--metres-per-pixel");
  expectRefused(query({"--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "nan"}), "--metres-per-pixel");
  expectRefused(query({"--mask", mask_, "--hold-pixel", "1e300,-1e300", "--metres-per-pixel", "0.01"}), "--hold-pixel");
  expectRefused(query({"--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01", "--shift", "1e9,1e9"}),
                "--shift");
  expectRefused(query({"--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01", "--top", "1000000000"}),
                "--top");
  expectRefused(query({"--image", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01", "--threshold", "1e308"}),
                "--threshold");
}

TEST_F(DrapeDbCli, HugeImagesAreRefusedFromTheirHeader) {
  // A PNG whose header claims 20000 x 20000 px (the decoded image would take 1.2 GB): only the header is
  // written, the tool must refuse it before decoding.
  const std::string png = dir_ + "/huge.png";
  {
    const unsigned char head[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                  0, 0, 0x4E, 0x20, 0, 0, 0x4E, 0x20, 8, 2, 0, 0, 0, 0, 0, 0, 0};
    std::ofstream f(png, std::ios::binary);
    f.write(reinterpret_cast<const char*>(head), sizeof head);
  }
  for (const char* option : {"--image", "--mask"}) {
    const ToolRun r = query({option, png, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01"});
    expectRefused(r, option);
    EXPECT_NE(r.err.find("20000 x 20000"), std::string::npos) << "not refused for its size: " << r.err;
  }
  const std::string text = dir_ + "/not_an_image.png";
  std::ofstream(text) << "hello";
  expectRefused(query({"--mask", text, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01"}), "--mask");
}

TEST_F(DrapeDbCli, HugeYamlIsRefusedBeforeParsing) {
  const std::string yaml = dir_ + "/huge.yaml";
  {
    std::ofstream f(yaml);
    f << "values:\n";
    for (int k = 0; k < 1'500'000; ++k) f << "  - " << k << "\n";  // about 12 MB of list
  }
  const ToolRun r = runDrapeDb({"build", "--db", dir_ + "/never.sqlite", "--textile", "towel", "--material", yaml});
  expectRefused(r, "--material");
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/never.sqlite"));
}

TEST_F(DrapeDbCli, UnknownMembersAreRefusedBeforeTheDatabaseIsOpened) {
  for (const char* list : {"base,crumpled", "heap,heap", ""}) {
    const ToolRun r = runDrapeDb({"build", "--db", dir_ + "/never.sqlite", "--textile", "towel", "--members", list});
    expectRefused(r, "--members");
  }
  EXPECT_FALSE(std::filesystem::exists(dir_ + "/never.sqlite"));
}

TEST_F(DrapeDbCli, AJobFileBuildsItsSettingsAndPrintsRecords) {
  db::DrapeBuildJob job;
  job.config.textile = test_support::smallTowel();
  job.config.textile.name = "job_towel";
  job.config.spacing = 0.04;
  job.config.hold_points = {Vec2(0.0, 0.0), Vec2(0.18, 0.0)};
  job.config.use_symmetry = false;
  job.config.views.count = 4;
  job.config.views.step_deg = 90;
  job.config.workers = 1;
  const std::string file = dir_ + "/job.yaml", target = dir_ + "/job.sqlite";
  db::saveDrapeBuildJob(job, file);
  // Settings come from the file only; a broken file is refused before the database is created.
  expectRefused(runDrapeDb({"build", "--db", target, "--job", file, "--textile", "towel"}), "--textile");
  expectRefused(runDrapeDb({"build", "--db", target, "--job", file, "--spacing", "0.02"}), "--spacing");
  {
    std::ofstream bad(dir_ + "/bad_job.yaml");
    bad << tool_process::readAll(file) << "surprise: 1\n";
  }
  expectRefused(runDrapeDb({"build", "--db", target, "--job", dir_ + "/bad_job.yaml"}), "surprise");
  expectRefused(runDrapeDb({"build", "--db", target, "--job", dir_ + "/missing.yaml"}), "missing.yaml");
  EXPECT_FALSE(std::filesystem::exists(target));

  const ToolRun r = runDrapeDb({"build", "--db", target, "--job", file, "--progress-records"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("th-build-progress done=2 total=2"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("th-build-report generation=0 planned=2 to_simulate=2 already_done=0 simulated=2 failed=0"),
            std::string::npos)
      << r.err;
  db::HangingDrapeDatabase database(target);
  const auto rows = database.simulations(0, db::SimulationStatus::kDone);
  ASSERT_EQ(rows.size(), 2u);
  for (const db::SimulationRecord& s : rows)
    EXPECT_EQ(s.parameters, db::DrapeDatabaseBuilder::parametersText(job.config));
}

TEST_F(DrapeDbCli, ADamagedStoredViewIsSkippedAndReported) {
  const std::string copy = dir_ + "/damaged.sqlite";
  std::filesystem::copy_file(db_, copy, std::filesystem::copy_options::overwrite_existing);
  const auto ids = test_support::storedViewIds(copy);
  ASSERT_FALSE(ids.empty());
  ASSERT_EQ(test_support::flipStoredMaskBytes(copy, {ids.front()}), 1);
  const ToolRun r = runDrapeDb({"query", "--db", copy, "--mask", mask_, "--hold-pixel", "32,4", "--metres-per-pixel", "0.01"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("damaged view " + std::to_string(ids.front())), std::string::npos) << r.err;
  EXPECT_NE(r.out.find(std::to_string(ids.size() - 1) + " silhouettes"), std::string::npos) << r.out;
}

}  // namespace

TEST_F(DrapeDbCli, AutoRefusesTheSettingsItChoosesAndItsOptionsNeedIt) {
  const std::string never = dir_ + "/never_auto.sqlite";
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--spacing", "0.02"}), "--spacing");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--model", "choi_ko"}), "--model");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto-tolerance", "0.01"}), "needs --auto");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--question", "unravel"}), "unravel");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--auto-spacings", "0.02"}),
                "spacings");
  // 5.8 and 5.5 cm both become 5 cm, the next finer spacing with a mirror-symmetric grid on the 30 cm square.
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--auto-spacings", "0.058,0.055"}),
                "mirror-symmetric");
  EXPECT_FALSE(std::filesystem::exists(never));
}

TEST_F(DrapeDbCli, ACoarseToFineBuildStoresItsRestShapeSettings) {
  const std::string path = dir_ + "/coarse_to_fine.sqlite";
  const ToolRun r = runDrapeDb({"build", "--db", path, "--textile", "square", "--hold", "0,0", "--spacing", "0.03",
                                "--views", "4", "--threads", "1", "--no-symmetry", "--rest-method", "quasi_static", "--coarse-spacing",
                                "0.0625", "--no-coarse-finish", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto sims = squareRows(path);
  ASSERT_EQ(sims.size(), 1u);
  EXPECT_EQ(sims[0].status, db::SimulationStatus::kDone);
  EXPECT_NE(sims[0].parameters.find("rest_method: quasi_static coarse_spacing: 0.0625 "), std::string::npos) << sims[0].parameters;
  EXPECT_NE(sims[0].parameters.find("prolonged_edge_ratios: 0.9"), std::string::npos) << sims[0].parameters;
  EXPECT_NE(sims[0].parameters.find("coarse_static_finish: 0"), std::string::npos) << sims[0].parameters;
  expectRefused(runDrapeDb({"build", "--db", dir_ + "/never.sqlite", "--textile", "square", "--coarse-spacing", "2"}),
                "--coarse-spacing");
}

TEST_F(DrapeDbCli, AnAutoBuildOfASymmetricTextileSearchesMirrorSymmetricGrids) {
  const std::string path = dir_ + "/auto_symmetric.sqlite";
  const ToolRun r = runDrapeDb({"build", "--db", path, "--textile", "square", "--hold", "0,0", "--views", "4", "--threads",
                                "1", "--auto", "--auto-spacings", "0.07,0.05", "--auto-tolerance", "10", "--auto-min-iou",
                                "0", "--auto-samples", "1", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  // 7 cm gives no symmetric grid on the 30 cm square (0.30 / 0.07 = 4.3 steps); 6 cm does (5 steps).
  EXPECT_NE(r.out.find("candidate spacings on mirror-symmetric grids: 0.06, 0.05 m"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("spacing 0.06 m"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("grid not symmetric"), std::string::npos) << r.out;
}

TEST_F(DrapeDbCli, AnAutoBuildWithoutConvergenceBuildsACoarserGridWithMembers) {
  // Named points never agree (1e-9 m), silhouettes loosely: the members rule takes 6 cm plus soft_light when
  // their work on the sample is below the 3 cm run's, and the build makes both members.
  const std::string path = dir_ + "/auto_members.sqlite";
  const ToolRun r = autoBuildOfSquareCorner(path, "0.06,0.03", "1e-9", "0.3");
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("a coarser one with members was taken"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("members base, soft_light: d 0.06 silhouettes agree with d 0.03"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("member soft_light:"), std::string::npos) << r.out;
  const auto sims = squareRows(path);
  ASSERT_EQ(sims.size(), 2u);
  std::set<std::string> members;
  for (const auto& s : sims) {
    EXPECT_EQ(s.status, db::SimulationStatus::kDone);
    EXPECT_DOUBLE_EQ(s.spacing, 0.06);
    EXPECT_NE(s.parameters.find("automatic: members base, soft_light"), std::string::npos) << s.parameters;
    members.insert(db::memberOfParameters(s.parameters));
  }
  EXPECT_EQ(members, (std::set<std::string>{"base", "soft_light"}));
  // --auto-members none keeps the finest; an unknown member or the base is refused before the file is made.
  const ToolRun none =
      autoBuildOfSquareCorner(dir_ + "/auto_no_members.sqlite", "0.06,0.03", "1e-9", "0.3", {"--auto-members", "none"});
  ASSERT_EQ(none.exit_code, 0) << none.out << none.err;
  EXPECT_NE(none.out.find("spacing 0.03 m"), std::string::npos) << none.out;
  EXPECT_EQ(none.out.find("member soft_light"), std::string::npos) << none.out;
  const std::string never = dir_ + "/never_members.sqlite";
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--auto-members", "velvet"}), "velvet");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto", "--auto-members", "base"}), "base member");
  expectRefused(runDrapeDb({"build", "--db", never, "--textile", "square", "--auto-members", "soft_light"}), "needs --auto");
  EXPECT_FALSE(std::filesystem::exists(never));
}

TEST_F(DrapeDbCli, AnAutoBuildStoresItsChoiceAndEvidenceWithTheRows) {
  const std::string path = dir_ + "/auto.sqlite";
  const ToolRun r = runDrapeDb({"build", "--db", path, "--textile", "square", "--hold", "0,0", "--hold", "0.15,0.15",
                                "--views", "4", "--threads", "1", "--no-symmetry", "--auto", "--auto-spacings", "0.06,0.05",
                                "--auto-tolerance", "10", "--auto-min-iou", "0", "--auto-samples", "2",
                                "--auto-step-factors", "3", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("automatic choice"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("model particle_kes (hanging scene), spacing 0.06 m"), std::string::npos) << r.out;
  const auto sims = squareRows(path);
  ASSERT_EQ(sims.size(), 2u);
  for (const auto& s : sims) {
    EXPECT_EQ(s.status, db::SimulationStatus::kDone);
    EXPECT_DOUBLE_EQ(s.spacing, 0.06);
    EXPECT_NE(s.parameters.find("automatic: model particle_kes (hanging scene), spacing 0.06 m"), std::string::npos)
        << s.parameters;
    EXPECT_NE(s.parameters.find("automatic: evidence particle_kes hold"), std::string::npos) << s.parameters;
    // The step tolerance search (3 times the builder's 0.1 mm) agreed under these loose criteria.
    EXPECT_NE(s.parameters.find("(step error tolerance 0.0003 m)"), std::string::npos) << s.parameters;
    EXPECT_NE(s.parameters.find("d 0.06 step tolerance 0.0003 vs 0.0001:"), std::string::npos) << s.parameters;
  }
  // Without --auto-step-factors (or with none) the builder's step tolerance is kept and no other is tried.
  const std::string kept = dir_ + "/auto_kept.sqlite";
  const ToolRun r2 = autoBuildOfSquareCorner(kept, "0.06,0.05", "10", "0");
  ASSERT_EQ(r2.exit_code, 0) << r2.out << r2.err;
  EXPECT_NE(r2.out.find("(step error tolerance 0.0001 m)"), std::string::npos) << r2.out;
  EXPECT_EQ(r2.out.find("step tolerance 0."), std::string::npos) << r2.out;
  const ToolRun r3 = runDrapeDb({"build", "--db", dir_ + "/auto_bad.sqlite", "--textile", "square", "--auto",
                                 "--auto-step-factors", "0.5"});
  EXPECT_EQ(r3.exit_code, 2) << r3.out << r3.err;
  EXPECT_NE(r3.err.find("error_tolerance_factors"), std::string::npos) << r3.err;
}
