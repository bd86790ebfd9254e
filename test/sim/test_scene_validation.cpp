// Strict scene and material YAML: unknown and missing keys, hold points on the textile, list and size
// limits, the memory budget, every shipped scene and material still valid, and a fuzz of the parser.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/memory_budget.h"
#include "textile_handling/sim/text_input.h"
#include "textile_handling/sim/woven_fabric.h"

namespace textile_handling {
namespace {

const std::string kSourceDir = TEXTILE_HANDLING_SOURCE_DIR;

// The four required keys, a square textile at a coarse spacing.
const std::string kMinimal = "textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [corner_ul]}\n";

// The message of the std::invalid_argument that f throws (fails the test on success or another type).
std::string rejection(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  } catch (const std::exception& e) {
    ADD_FAILURE() << "wrong exception type: " << e.what();
    return "";
  }
  ADD_FAILURE() << "accepted";
  return "";
}

std::string parseError(const std::string& text) {
  return rejection([&] { parseDrapeSceneYaml(text); });
}

std::string buildError(const std::string& text) {
  return rejection([&] { buildDrapeScene(parseDrapeSceneYaml(text)); });
}

bool contains(const std::string& text, const std::string& part) { return text.find(part) != std::string::npos; }

TEST(SceneKeys, MinimalSceneParsesAndBuilds) {
  const DrapeSceneSpec s = parseDrapeSceneYaml(kMinimal);
  EXPECT_EQ(s.textile.name, "square");
  ASSERT_EQ(s.hold.size(), 1u);
  EXPECT_EQ(buildDrapeScene(s).model->numNodes(), 7 * 7);
}

TEST(SceneKeys, UnknownKeysAreRejectedAtEveryLevelNamingTheKeyPath) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"colour: red\n", "'colour'"},
      {"simulation: {dt_mx: 0.1}\n", "'simulation.dt_mx'"},
      {"model: {gravty: false}\n", "'model.gravty'"},
      {"collision: {self: v3, selff: v3}\n", "'collision.selff'"},
      {"obstacles: {plane: []}\n", "'obstacles.plane'"},
      {"obstacles: {planes: [{point: [0, 0, 0], normal: [0, 0, 1], colour: red}]}\n", "'obstacles.planes[].colour'"},
      {"obstacles: {spheres: [{centre: [0, 0, 0], radius_m: 1, r: 2}]}\n", "'obstacles.spheres[].r'"},
      {"obstacles: {boxes: [{min: [0, 0, 0], max: [1, 1, 1], yaw_rad: 1}]}\n", "'obstacles.boxes[].yaw_rad'"},
  };
  for (const auto& c : cases) {
    const std::string message = parseError(kMinimal + c.first);
    EXPECT_TRUE(contains(message, "unknown key " + c.second)) << c.first << " -> " << message;
    EXPECT_TRUE(contains(message, "known:")) << message;
  }
  // Inside hold and a custom textile (the required keys given by these sections themselves).
  const std::string custom =
      "material: cotton\nspacing_m: 0.05\nhold: {points: [tip], speed: 1}\n"
      "textile: {name: napkin, outline: [[0, 0], [0.2, 0], [0.2, 0.2]], named_points: {tip: [0.2, 0.2]}}\n";
  EXPECT_TRUE(contains(parseError(custom), "unknown key 'hold.speed'"));
  EXPECT_TRUE(contains(parseError("material: cotton\nspacing_m: 0.05\nhold: {points: [tip]}\n"
                                  "textile: {outline: [[0, 0], [0.2, 0], [0.2, 0.2]], mirror: 0.1}\n"),
                       "unknown key 'textile.mirror'"));
  EXPECT_TRUE(contains(parseError("material: cotton\nspacing_m: 0.05\nhold: {points: [tip]}\n"
                                  "textile: {outline: [[0, 0], [0.2, 0], [0.2, 0.2]],"
                                  " named_points: {tip: {position: [0.2, 0], knd: corner}}}\n"),
                       "unknown key 'textile.named_points.tip.knd'"));
}

TEST(SceneKeys, RepeatedKeysAreRejected) {
  EXPECT_TRUE(contains(parseError(kMinimal + "simulation: {dt_s: 0.1, dt_s: 0.2}\n"), "'simulation.dt_s' appears twice"));
}

TEST(SceneKeys, MissingRequiredKeysAreNamed) {
  for (const std::string key : {"textile", "material", "spacing_m", "hold"}) {
    std::string text;
    for (const std::string line : {"textile: square", "material: cotton", "spacing_m: 0.05", "hold: {points: [corner_ul]}"})
      if (line.rfind(key + ":", 0) != 0) text += line + "\n";
    EXPECT_TRUE(contains(parseError(text), "missing required key '" + key + "'")) << key;
  }
  EXPECT_TRUE(contains(parseError("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {position: [0, 0, 1]}\n"),
                       "missing required key 'hold.points'"));
  EXPECT_TRUE(contains(parseError("textile: {name: x}\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [[0, 0]]}\n"),
                       "missing required key 'textile.outline'"));
  // A pinned region can replace the hold points (the table of the tablecloth validation).
  const DrapeSceneSpec s = parseDrapeSceneYaml(
      "textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {}\npinned_regions: [[0.1, 0.1, 0.2, 0.2]]\n");
  EXPECT_TRUE(s.hold.empty());
  EXPECT_EQ(s.pinned_regions.size(), 1u);
}

TEST(SceneHold, PointsOutsideTheTextileAreRejectedNamingThem) {
  std::string message = buildError("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [[5, 5]]}\n");
  EXPECT_TRUE(contains(message, "hold point 0")) << message;
  EXPECT_TRUE(contains(message, "5.000,5.000")) << message;
  EXPECT_TRUE(contains(message, "outside")) << message;
  message = buildError("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [corner_ul, [0.1, -0.01]]}\n");
  EXPECT_TRUE(contains(message, "hold point 1")) << message;
  // On the boundary and inside are fine.
  EXPECT_NO_THROW(buildDrapeScene(
      parseDrapeSceneYaml("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: [[0.3, 0.3], [0.1, 0.2]]}\n")));
  message = buildError("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {}\n"
                       "pinned_regions: [[0.1, 0.1, 0.2, 0.2], [2, 2, 3, 3]]\n");
  EXPECT_TRUE(contains(message, "pinned region 1")) << message;
}

TEST(SceneStart, ATiltedStartRotatesTheSheetAboutTheHeldPoint) {
  const DrapeScene flat = buildDrapeScene(parseDrapeSceneYaml(kMinimal));
  const DrapeScene tilted =
      buildDrapeScene(parseDrapeSceneYaml(kMinimal + "start: {tilt_deg: 90, tilt_axis_deg: 0}\n"));
  const Index h = tilted.hold_particle;
  ASSERT_EQ(h, flat.hold_particle);
  const Vec3 pivot = tilted.x0.segment<3>(3 * h);
  EXPECT_LT((pivot - flat.x0.segment<3>(3 * h)).norm(), 1e-12);  // the held particle stays
  EXPECT_LT((pivot - tilted.pins.anchors.front()).norm(), 1e-12);
  // 90 degrees about the textile's x axis (right-handed): textile +y goes to world +z. The held corner
  // (corner_ul, the top of the square) has every other particle at y below it: they all go down.
  for (Index p = 0; p < flat.model->numNodes(); ++p) {
    const Vec3 d0 = flat.x0.segment<3>(3 * p) - pivot, d1 = tilted.x0.segment<3>(3 * p) - pivot;
    EXPECT_NEAR(d1.norm(), d0.norm(), 1e-12);
    EXPECT_NEAR(d1.x(), d0.x(), 1e-12);
    EXPECT_NEAR(d1.z(), d0.y(), 1e-12);
    EXPECT_NEAR(d1.y(), 0.0, 1e-12);
  }
  EXPECT_TRUE(contains(buildError(kMinimal + "start: {tilt_deg: 91}\n"), "start: tilt_deg must be in [-90, 90]"));
  EXPECT_TRUE(contains(parseError(kMinimal + "start: {tilt_deg: .nan}\n"), "start.tilt_deg"));
  EXPECT_TRUE(contains(parseError(kMinimal + "start: {tilt: 10}\n"), "unknown key 'start.tilt'"));
  EXPECT_TRUE(contains(parseError(kMinimal + "start: 10\n"), "'start' must be a map"));
}

TEST(SceneLimits, ListsAreBoundedBeforeTheyAreCopied) {
  // (test_outline_limits.cpp refuses 100,000 vertices and named points at the geometry level.)
  std::string outline = "[";
  for (int i = 0; i < 5000; ++i) outline += (i ? ", " : "") + std::string("[0, 0]");
  std::string message = parseError("material: cotton\nspacing_m: 0.05\nhold: {points: [[0, 0]]}\ntextile: {outline: " +
                                   outline + "]}\n");
  EXPECT_TRUE(contains(message, "'textile.outline' has 5000 items, more than the limit of 4096")) << message;

  std::string points = "{";
  for (int i = 0; i < 300; ++i) points += (i ? ", " : "") + ("p" + std::to_string(i)) + ": [0, 0]";
  message = parseError("material: cotton\nspacing_m: 0.05\nhold: {points: [[0, 0]]}\n"
                       "textile: {outline: [[0, 0], [1, 0], [0, 1]], named_points: " + points + "}}\n");
  EXPECT_TRUE(contains(message, "limit of 256")) << message;

  std::string holds = "[";
  for (int i = 0; i < 300; ++i) holds += (i ? ", " : "") + std::string("corner_ul");
  message = parseError("textile: square\nmaterial: cotton\nspacing_m: 0.05\nhold: {points: " + holds + "]}\n");
  EXPECT_TRUE(contains(message, "'hold.points' has 300 items")) << message;
}

TEST(SceneLimits, NamedPointNamesFollowTheNameRule) {
  const std::string message = buildError(
      "material: cotton\nspacing_m: 0.05\nhold: {points: [[0, 0]]}\n"
      "textile: {name: napkin, outline: [[0, 0], [0.2, 0], [0.2, 0.2]],"
      " named_points: {\"x'); DROP TABLE grasp_points;--\": [0.2, 0.2]}}\n");
  EXPECT_TRUE(contains(message, "letters, digits")) << message;
}

TEST(SceneLimits, DocumentsOverTheByteLimitAreRefusedBeforeParsing) {
  const std::string padding = "# " + std::string(kMaxYamlDocumentBytes, 'x') + "\n";
  const std::string message = parseError(kMinimal + padding);
  EXPECT_TRUE(contains(message, "limit of " + std::to_string(kMaxYamlDocumentBytes))) << message;
  // The same from a file, and endless or special files are not read at all.
  const std::string path = ::testing::TempDir() + "/th_large_scene.yaml";
  { std::ofstream(path) << kMinimal << padding; }
  EXPECT_TRUE(contains(rejection([&] { loadDrapeSceneYaml(path); }), "limit of")) << path;
  std::filesystem::remove(path);
  EXPECT_TRUE(contains(rejection([] { loadDrapeSceneYaml("/dev/zero"); }), "not a regular file"));
  EXPECT_TRUE(contains(parseError("textile: square\nmaterial: /dev/zero\nspacing_m: 0.05\nhold: {points: [corner_ul]}\n"),
                       "not a regular file"));
}

TEST(MaterialLimits, DocumentsAndListsAreBounded) {
  const std::string base = materialToYaml(Material::cotton());
  EXPECT_NO_THROW(parseMaterialYaml(base));
  try {
    parseMaterialYaml(base + "# " + std::string(kMaxYamlDocumentBytes, 'x') + "\n");
    ADD_FAILURE() << "accepted";
  } catch (const MaterialError& e) {
    EXPECT_TRUE(contains(e.what(), "limit of " + std::to_string(kMaxYamlDocumentBytes))) << e.what();
  }
  std::string xs = "[", ys = "[";
  for (int i = 0; i < 2000; ++i) {
    xs += (i ? ", " : "") + std::to_string(0.001 * i);
    ys += (i ? ", " : "") + std::to_string(0.01 * i);
  }
  std::string text = base;
  const auto at = text.find("shear_warp:");
  const auto end = text.find('\n', at);
  text.replace(at, end - at, "shear_warp: {type: table, x: " + xs + "], y: " + ys + "]}");
  try {
    parseMaterialYaml(text);
    ADD_FAILURE() << "accepted";
  } catch (const MaterialError& e) {
    EXPECT_TRUE(contains(e.what(), "shear_warp.")) << e.what();  // .x or .y: both are too long
    EXPECT_TRUE(contains(e.what(), "limit of " + std::to_string(kMaxMaterialListLength))) << e.what();
  }
  EXPECT_THROW(loadMaterialYaml("/dev/zero"), MaterialError);
}

TEST(ShippedFiles, EverySceneAndMaterialIsValid) {
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kSourceDir + "/config/scenes")) {
    if (entry.path().extension() != ".yaml") continue;
    ++scenes;
    DrapeSceneSpec spec;
    ASSERT_NO_THROW(spec = loadDrapeSceneYaml(entry.path().string())) << entry.path();
    EXPECT_NO_THROW(buildDrapeScene(spec)) << entry.path();
  }
  EXPECT_GE(scenes, 3);
  for (const auto& entry : std::filesystem::directory_iterator(kSourceDir + "/data/materials")) {
    if (entry.path().extension() == ".yaml") {
      EXPECT_NO_THROW(loadMaterialYaml(entry.path().string())) << entry.path();
    }
  }
  int fabrics = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kSourceDir + "/data/fabrics")) {
    if (entry.path().extension() != ".yaml") continue;
    ++fabrics;
    EXPECT_NO_THROW(loadWovenFabricYaml(entry.path().string())) << entry.path();
  }
  EXPECT_GE(fabrics, 3);
}

// ---- memory budget ------------------------------------------------------------------------------

DrapeSceneSpec towelAt(Real spacing) {
  DrapeSceneSpec s = benchmarkTowelSpec(spacing, "corner_ul");
  useFastSolverSettings(s.settings);
  return s;
}

TEST(MemoryBudget, TheTowelAtTwoTenthsOfAMillimetreIsRefused) {
  // 7.4 M particles: the uncaught std::bad_alloc. Refused before the model allocates.
  DrapeSceneSpec s = towelAt(2e-4);
  s.settings.memory_budget_bytes = std::size_t{16} << 30;
  const std::string message = rejection([&] { buildDrapeScene(s); });
  EXPECT_TRUE(contains(message, "7365501 particles at spacing 0.000200 m")) << message;
  EXPECT_TRUE(contains(message, "memory budget of 16.0 GiB")) << message;
  EXPECT_TRUE(contains(message, "coarser particle spacing")) << message;
  EXPECT_THROW(buildDrapeScene(s), MemoryBudgetError);
  SimulationMemoryInput in;
  in.nodes = 7365501;
  EXPECT_GT(estimateSimulationBytes(in), std::size_t{16} << 30);
}

TEST(MemoryBudget, DemoScenesFitTheDefaultBudgetAndOneGibibyte) {
  for (const std::string name : {"towel_corner.yaml", "replay_a.yaml", "replay_b.yaml"}) {
    DrapeSceneSpec s = loadDrapeSceneYaml(kSourceDir + "/config/scenes/" + name);
    EXPECT_NO_THROW(buildDrapeScene(s)) << name;
    s.settings.memory_budget_bytes = std::size_t{1} << 30;
    EXPECT_NO_THROW(buildDrapeScene(s)) << name;
  }
}

TEST(MemoryBudget, EstimateGrowsWithNodesAndCollisionAndDirectSolver) {
  SimulationMemoryInput in;
  in.nodes = 10000;
  const std::size_t cg = estimateSimulationBytes(in);
  in.nodes = 20000;
  EXPECT_GT(estimateSimulationBytes(in), cg);
  in.nodes = 10000;
  in.self_collision = true;
  EXPECT_GT(estimateSimulationBytes(in), cg);
  in.self_collision = false;
  in.solver = LinearSolverKind::kDirect;
  EXPECT_GT(estimateSimulationBytes(in), cg);
  // Newton's PCR needs what CG needs; the direct-solver setting does not apply to it.
  in.integrator = IntegratorType::kBackwardEulerNewton;
  EXPECT_EQ(estimateSimulationBytes(in), cg);
  in.integrator = IntegratorType::kSemiImplicitEuler;
  in.nodes = std::numeric_limits<Index>::max();  // saturates, never wraps
  EXPECT_GT(estimateSimulationBytes(in), std::size_t{1} << 40);
  EXPECT_GT(defaultMemoryBudgetBytes(), 0u);
  EXPECT_EQ(effectiveMemoryBudget(0), defaultMemoryBudgetBytes());
  EXPECT_EQ(effectiveMemoryBudget(123), 123u);
}

TEST(MemoryBudget, SimultaneousSimulationsMultiplyTheNeed) {
  const std::size_t gib = std::size_t{1} << 30;
  EXPECT_NO_THROW(checkMemoryBudget(gib, 4 * gib, "one build"));
  EXPECT_NO_THROW(checkMemoryBudget(gib, 4 * gib, "a build", 4));
  try {
    checkMemoryBudget(gib, 4 * gib, "a build", 5);
    ADD_FAILURE() << "accepted";
  } catch (const MemoryBudgetError& e) {
    EXPECT_TRUE(contains(e.what(), "5 simultaneous simulations")) << e.what();
    EXPECT_TRUE(contains(e.what(), "4.0 GiB")) << e.what();
  }
  EXPECT_THROW(checkMemoryBudget(std::numeric_limits<std::size_t>::max(), 4 * gib, "overflow", 3), MemoryBudgetError);
}

// ---- fuzz ---------------------------------------------------------------------------------------

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::vector<std::string> splitLines(const std::string& text) {
  std::vector<std::string> lines;
  std::size_t start = 0;
  for (std::size_t end; (end = text.find('\n', start)) != std::string::npos; start = end + 1)
    lines.push_back(text.substr(start, end - start));
  return lines;
}

std::string mutate(const std::string& text, std::mt19937& rng) {
  static const std::vector<std::string> kValues = {
      ".nan", ".inf", "-.inf", "1e308", "-1e308", "-1", "0", "-0", "1e-300", "abc", "[1, 2]", "{a: 1}", "",
      "~", "[[[[", "'unterminated", "18446744073709551616", "true", "[]", "{}", "[.nan, .nan]", "\"\\u0000\"",
      "[[0, 0], [0, 0], [0, 0]]", "*alias", "&anchor 1", "!!binary AAAA", "v9"};
  std::vector<std::string> lines = splitLines(text);
  auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  if (lines.empty()) return text;
  const std::size_t line = pick(lines.size());
  std::string& l = lines[line];
  const std::string indent = l.substr(0, l.find_first_not_of(' ') == std::string::npos ? 0 : l.find_first_not_of(' '));
  switch (pick(6)) {
    case 0: lines.erase(lines.begin() + static_cast<long>(line)); break;  // delete a key
    case 1: lines.insert(lines.begin() + static_cast<long>(line), indent + "bogus_key: 1"); break;
    case 2: {  // replace one value of the line (block style, or one entry of a flow map)
      std::vector<std::size_t> colons;
      for (auto c = l.find(": "); c != std::string::npos; c = l.find(": ", c + 1)) colons.push_back(c + 2);
      if (colons.empty()) break;
      const std::size_t start = colons[pick(colons.size())];
      std::size_t end = l.find_first_of(",}", start);
      if (end == std::string::npos || l[start] == '[' || l[start] == '{') end = l.size();
      l = l.substr(0, start) + kValues[pick(kValues.size())] + l.substr(end);
      break;
    }
    case 3: {  // truncate the document
      std::string joined;
      for (const auto& x : lines) joined += x + "\n";
      return joined.substr(0, pick(joined.size() + 1));
    }
    case 4: lines.insert(lines.begin() + static_cast<long>(line), l); break;  // repeat a key
    default: std::swap(l, lines[pick(lines.size())]); break;                  // reorder (breaks nesting)
  }
  std::string joined;
  for (const auto& x : lines) joined += x + "\n";
  return joined;
}

TEST(SceneFuzz, MutatedScenesParseOrFailWithAMessage) {
  // A scene with every section; mutations work on its lines.
  const std::string base = readFile(kSourceDir + "/test/sim/scene_all_sections.yaml");
  ASSERT_NO_THROW(buildDrapeScene(parseDrapeSceneYaml(base)));
  std::mt19937 rng(20261202);
  int accepted = 0, rejected = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::string text = base;
    const int mutations = 1 + trial % 3;
    for (int m = 0; m < mutations; ++m) text = mutate(text, rng);
    try {
      const DrapeSceneSpec spec = parseDrapeSceneYaml(text);
      ++accepted;
      // Build the coarse ones too (scene-level checks); a fine spacing would only cost time here.
      if (spec.spacing >= 0.02) buildDrapeScene(spec);
    } catch (const std::invalid_argument& e) {
      ++rejected;
      EXPECT_GT(std::string(e.what()).size(), 0u) << text;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "trial " << trial << ": " << typeid(e).name() << ": " << e.what() << "\n" << text;
    } catch (...) {
      ADD_FAILURE() << "trial " << trial << ": a non-standard exception\n" << text;
    }
  }
  EXPECT_GT(accepted, 100);
  EXPECT_GT(rejected, 1000);
}

TEST(SceneFuzz, DeepNestingIsAnErrorNotACrash) {
  const std::string deep = "textile: " + std::string(100000, '[') + "\n";
  EXPECT_FALSE(parseError(kMinimal.substr(kMinimal.find('\n') + 1) + deep).empty());
}


TEST(SceneAutomaticModel, ModelAutoIsReadWithItsKeysAndMakesSpacingOptional) {
  const DrapeSceneSpec s = parseDrapeSceneYaml(
      "textile: square\nmaterial: cotton\nhold: {points: [corner_ul]}\n"
      "model: {name: auto, question: pull_out, spacings_m: [0.06, 0.04], named_point_tolerance_m: 0.02, "
      "min_mean_iou: 0.9}\n");
  EXPECT_TRUE(s.automatic.requested);
  EXPECT_EQ(s.automatic.question, "pull_out");
  ASSERT_EQ(s.automatic.spacings.size(), 2u);
  EXPECT_DOUBLE_EQ(s.automatic.spacings[1], 0.04);
  EXPECT_DOUBLE_EQ(s.automatic.named_point_tolerance_m, 0.02);
  EXPECT_DOUBLE_EQ(s.automatic.min_mean_iou, 0.9);
  // Not chosen yet: building it is refused, naming what to do.
  EXPECT_TRUE(contains(rejection([&] { buildDrapeScene(s); }), "model: auto is chosen before the scene is built"));
  // Without auto, the spacing stays required and no automatic choice is requested.
  EXPECT_FALSE(parseDrapeSceneYaml(kMinimal).automatic.requested);
}

TEST(SceneAutomaticModel, BadAutoKeysAreNamed) {
  const std::string head = "textile: square\nmaterial: cotton\nhold: {points: [corner_ul]}\n";
  EXPECT_TRUE(contains(parseError(head + "model: {name: auto, jacobian: exact}\n"), "model.jacobian"));
  EXPECT_TRUE(contains(parseError(head + "model: {name: auto, spacings_m: [0.02, -1]}\n"), "model.spacings_m"));
  EXPECT_TRUE(contains(parseError(head + "model: {name: auto, min_mean_iou: 1.5}\n"), "model.min_mean_iou"));
  EXPECT_TRUE(contains(parseError(head + "model: {name: auto, named_point_tolerance_m: 0}\n"), "named_point_tolerance_m"));
}
}  // namespace
}  // namespace textile_handling
