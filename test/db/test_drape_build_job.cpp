// Build-job files (db/drape_build_job.h): a build written to a file and read back is the same build
// (every parameter text, every execution setting), for the defaults and for a build that changes every
// setting; a file that is malformed, oversized or names an unknown key is refused with an error naming
// the key, and what is read is what is built.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <string>

#include "../test_support.h"
#include "textile_handling/db/database_errors.h"
#include "textile_handling/db/drape_build_job.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

// Every setting away from its default (the values need not make a sensible build, only a valid one).
DrapeBuildJob everySettingChanged() {
  DrapeBuildJob job;
  DrapeBuildConfig& c = job.config;
  job.members = "base,tilted";
  c.textile = presetTextile("tshirt");
  c.textile.name = "tshirt.XL-2024_b";
  c.material = Material::cotton();
  c.material.name = "heavy";
  c.material.areal_density *= 1.7;
  c.lattice_spacing = 0.0731;
  c.hold_points = {Vec2(0.1, 0.2), Vec2(1.0 / 3.0, 0.05)};
  c.use_symmetry = false;
  c.bracket_hold_points = true;
  c.spacing = 0.0123456789;
  c.hold_height = 1.37;
  c.model = DrapeBuildConfig::defaultModelSpec("choi_ko");
  c.settings.integrator = IntegratorType::kBackwardEulerNewton;
  c.settings.policy = StepPolicy::kFixed;
  c.settings.solver.kind = LinearSolverKind::kDirect;
  c.settings.solver.preconditioner = PreconditionerKind::kBlockJacobi;
  c.settings.solver.warm_start = true;
  c.settings.solver.max_iterations = 333;
  c.settings.solver.relative_tolerance = 3e-5;
  c.settings.solver.accept_tolerance = 1e-3;
  c.settings.solver.smoothing_steps = 3;
  c.settings.solver.smoothing_weight = 0.55;
  c.settings.solver.newton_max_iterations = 7;
  c.settings.solver.newton_tolerance = 2e-3;
  c.settings.dt = 2e-3;
  c.settings.dt_min = 1e-8;
  c.settings.dt_max = 0.031;
  c.settings.error_tolerance = 7e-5;
  c.settings.max_time = 17;
  c.settings.rest_speed = 4e-3;
  c.settings.rest_mean_speed = 9e-4;
  c.settings.rest_duration = 0.3;
  c.settings.rest_min_time = 0.5;
  c.settings.max_edge_stretch = 2.5;
  c.settings.max_speed = 40;
  c.settings.max_wall_time = 120;
  c.settings.memory_budget_bytes = std::size_t{3} << 30;
  c.start_tilt_deg = 30;
  c.start_tilt_axis_deg = 45;
  c.self_collision = true;
  c.start_heap.folds = 3;
  c.start_heap.seed = std::numeric_limits<std::uint64_t>::max() - 12345;  // beyond a double's integers
  c.start_heap.lift_deg = 60;
  c.material_variation.bending = 1.5;
  c.material_variation.shear = 0.8;
  c.material_variation.density = 1.1;
  c.member = "custom";
  c.automatic_choice = "model: particle_kes\nspacing: 0.02 m (from 3 candidates)\n";
  c.rest_shape.method = RestShapeMethod::kQuasiStatic;
  c.rest_shape.coarse_spacing = 0.04;
  c.rest_shape.fine_finish = FineFinish::kNewton;
  c.rest_shape.finish.max_iterations = 44;
  c.require_rest = false;
  c.retry_with_smaller_steps = false;
  c.views.count = 12;
  c.views.start_deg = 5;
  c.views.step_deg = 30;
  c.frame = vision::CanonicalFrame::fromMetric(0.8, 1.2, 48);
  c.frame.supersample = 2;
  c.projection = vision::SilhouetteProjection::pinhole(vision::PinholeIntrinsics{600, 610, 320, 240, 640, 480}, 1.8, 0.1);
  c.staged_textile_id = 42;
  c.workers = 3;
  c.threads_per_simulation = 2;
  c.retry_failed = true;
  c.claim_lease_s = 90;
  return job;
}

void expectSameBuild(const DrapeBuildJob& a, const DrapeBuildJob& b) {
  EXPECT_EQ(DrapeDatabaseBuilder::parameterTexts(a.config), DrapeDatabaseBuilder::parameterTexts(b.config));
  EXPECT_EQ(a.members, b.members);
  const DrapeBuildConfig &x = a.config, &y = b.config;
  EXPECT_EQ(x.textile.name, y.textile.name);
  ASSERT_EQ(x.textile.outline.size(), y.textile.outline.size());
  for (std::size_t k = 0; k < x.textile.outline.size(); ++k) EXPECT_EQ(x.textile.outline[k], y.textile.outline[k]);
  EXPECT_EQ(x.textile.mirrored, y.textile.mirrored);
  EXPECT_EQ(x.textile.mirror_x, y.textile.mirror_x);
  ASSERT_EQ(x.textile.named_points.size(), y.textile.named_points.size());
  for (std::size_t k = 0; k < x.textile.named_points.size(); ++k) {
    EXPECT_EQ(x.textile.named_points[k].name, y.textile.named_points[k].name);
    EXPECT_EQ(x.textile.named_points[k].kind, y.textile.named_points[k].kind);
    EXPECT_EQ(x.textile.named_points[k].position, y.textile.named_points[k].position);
  }
  EXPECT_EQ(materialToYaml(x.material), materialToYaml(y.material));
  EXPECT_EQ(x.lattice_spacing, y.lattice_spacing);
  ASSERT_EQ(x.hold_points.size(), y.hold_points.size());
  for (std::size_t k = 0; k < x.hold_points.size(); ++k) EXPECT_EQ(x.hold_points[k], y.hold_points[k]);
  EXPECT_EQ(x.use_symmetry, y.use_symmetry);
  EXPECT_EQ(x.bracket_hold_points, y.bracket_hold_points);
  EXPECT_EQ(x.start_heap.seed, y.start_heap.seed);
  EXPECT_EQ(x.settings.memory_budget_bytes, y.settings.memory_budget_bytes);
  EXPECT_EQ(x.settings.max_wall_time, y.settings.max_wall_time);
  EXPECT_EQ(x.rest_shape.fine_finish, y.rest_shape.fine_finish);
  EXPECT_EQ(x.staged_textile_id, y.staged_textile_id);
  EXPECT_EQ(x.workers, y.workers);
  EXPECT_EQ(x.threads_per_simulation, y.threads_per_simulation);
  EXPECT_EQ(x.retry_failed, y.retry_failed);
  EXPECT_EQ(x.claim_lease_s, y.claim_lease_s);
}

// The InvalidInputError message of parsing `text` ("" if accepted).
std::string refusal(const std::string& text) {
  try {
    parseDrapeBuildJob(text);
  } catch (const InvalidInputError& e) {
    return e.what();
  }
  return "";
}

// The text of the default job with key `key` (its line and the indented lines of its value) replaced by
// `line`, or with `line` appended if the key is absent.
std::string withLine(const std::string& key, const std::string& line) {
  const std::string text = "\n" + drapeBuildJobText(DrapeBuildJob{});
  const auto at = text.find("\n" + key + ":");
  if (at == std::string::npos) return text.substr(1) + line + "\n";
  auto end = text.find('\n', at + 1);
  while (end != std::string::npos && end + 1 < text.size() && (text[end + 1] == ' ' || text[end + 1] == '-'))
    end = text.find('\n', end + 1);
  return (text.substr(0, at + 1) + line + (end == std::string::npos ? "\n" : text.substr(end))).substr(1);
}

TEST(DrapeBuildJob, TheDefaultBuildComesBackUnchanged) {
  const DrapeBuildJob job;
  const std::string text = drapeBuildJobText(job);
  EXPECT_EQ(text.rfind("format: textile_handling_build_job 1", 0), 0u) << text.substr(0, 80);
  expectSameBuild(job, parseDrapeBuildJob(text));
}

TEST(DrapeBuildJob, ABuildWithEverySettingChangedComesBackUnchanged) {
  const DrapeBuildJob job = everySettingChanged();
  // The changed build differs from the default one in its parameter texts (the comparison can fail).
  ASSERT_NE(DrapeDatabaseBuilder::parameterTexts(job.config), DrapeDatabaseBuilder::parameterTexts(DrapeBuildConfig{}));
  const std::string text = drapeBuildJobText(job);
  const DrapeBuildJob back = parseDrapeBuildJob(text);
  expectSameBuild(job, back);
  EXPECT_EQ(drapeBuildJobText(back), text);
}

TEST(DrapeBuildJob, SavedFilesLoadAndAChangedValueChangesTheBuild) {
  const std::string dir = test_support::freshTempDir("th_build_job");
  const std::string path = dir + "/job.yaml";
  saveDrapeBuildJob(DrapeBuildJob{}, path);
  expectSameBuild(DrapeBuildJob{}, loadDrapeBuildJob(path));
  // What is read is what is built: a changed value reaches the configuration and its parameter text.
  const DrapeBuildJob changed = parseDrapeBuildJob(withLine("simulation.dt_max_s", "simulation.dt_max_s: 0.005"));
  EXPECT_EQ(changed.config.settings.dt_max, 0.005);
  EXPECT_NE(DrapeDatabaseBuilder::parametersText(changed.config), DrapeDatabaseBuilder::parametersText(DrapeBuildConfig{}));
}

TEST(DrapeBuildJob, ABuildThatCannotBeWrittenIsRefusedByTheWriter) {
  DrapeBuildJob job;
  job.config.spacing = std::nan("");
  try {
    drapeBuildJobText(job);
    ADD_FAILURE() << "a NaN spacing was written";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("spacing_m"), std::string::npos) << e.what();
  }
  job = DrapeBuildJob{};
  job.members = "base,no_such_member";
  EXPECT_THROW(drapeBuildJobText(job), InvalidInputError);
}

TEST(DrapeBuildJob, HostileFilesAreRefusedWithTheKeyAtFault) {
  struct Case {
    std::string text, needle;
  };
  const Case cases[] = {
      {"{ this is not yaml", "malformed YAML"},
      {"- a list\n- not a map\n", "not a YAML map"},
      {"format: textile_handling_build_job 2\n", "'format'"},
      {withLine("format", "format: something_else"), "'format'"},
      {withLine("no_such_key", "no_such_key: 1"), "unknown key 'no_such_key'"},
      {withLine("spacing_m", "spacing_m: 0.02\nspacing_m: 0.03"), "'spacing_m' appears twice"},
      {withLine("spacing_m", "spacing_m: nan"), "'spacing_m' must be a finite number"},
      {withLine("spacing_m", "spacing_m: 1e999"), "'spacing_m' must be a finite number"},
      {withLine("spacing_m", "spacing_m: 0"), "'spacing_m' and 'lattice_spacing_m' must be positive"},
      {withLine("spacing_m", "spacing_m: [1, 2]"), "'spacing_m' must be a number"},
      {withLine("views.count", "views.count: 2.5"), "'views.count' must be a whole number"},
      {withLine("views.count", "views.count: 0"), "'views.count' must be a whole number in [1,"},
      {withLine("workers", "workers: 99999999999999999999"), "'workers' must be a whole number"},
      {withLine("start_heap.seed", "start_heap.seed: \"-1\""), "'start_heap.seed'"},
      {withLine("use_symmetry", "use_symmetry: \"yes\""), "'use_symmetry': expected true or false"},
      {withLine("simulation.integrator", "simulation.integrator: \"warp_drive\""), "'simulation.integrator'"},
      {withLine("model", "model: \"no_such_model\""), "'model'"},
      {withLine("members", "members: \"base,base\""), "base"},
      {withLine("material", "material: \"not: [a material\""), "'material'"},
      {withLine("claim_lease_s", "claim_lease_s: 1"), "'claim_lease_s'"},
      {withLine("hold_points_m", "hold_points_m: [[0.1]]"), "'hold_points_m' must be [x, y]"},
  };
  for (const Case& c : cases) {
    const std::string why = refusal(c.text);
    EXPECT_NE(why.find(c.needle), std::string::npos) << "expected '" << c.needle << "', got '" << why << "'";
  }
  // A self-intersecting outline and a missing textile.
  std::string text = drapeBuildJobText(DrapeBuildJob{});
  const auto outline = text.find("  outline_m:");
  ASSERT_NE(outline, std::string::npos);
  const auto next = text.find("  named_points:", outline);
  const std::string bowtie = "  outline_m:\n    - [0, 0]\n    - [1, 1]\n    - [1, 0]\n    - [0, 1]\n";
  EXPECT_NE(refusal(text.substr(0, outline) + bowtie + text.substr(next)).find("'textile'"), std::string::npos);
  EXPECT_NE(refusal("format: textile_handling_build_job 1\n").find("'textile' is missing"), std::string::npos);
  // Too large: refused before it is parsed; a device is refused before it is read.
  EXPECT_NE(refusal(std::string(kMaxBuildJobBytes + 1, ' ')).find("limit"), std::string::npos);
  try {
    loadDrapeBuildJob("/dev/zero");
    ADD_FAILURE() << "/dev/zero was read";
  } catch (const InvalidInputError& e) {
    EXPECT_NE(std::string(e.what()).find("/dev/zero"), std::string::npos) << e.what();
  }
  EXPECT_THROW(loadDrapeBuildJob("/nonexistent/job.yaml"), InvalidInputError);
}

}  // namespace
