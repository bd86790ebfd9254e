#include "textile_handling/db/drape_build_job.h"

#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <vector>

#include "database_sql.h"
#include "textile_handling/db/database_errors.h"
#include "textile_handling/db/drape_build_members.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/text_input.h"

namespace textile_handling {
namespace db {

namespace {

constexpr const char* kFormat = "textile_handling_build_job 1";

// Every number of a DrapeBuildConfig that a build job carries, by key. Real-valued fields first, whole
// numbers second; the keys follow the parameter text where it has the same field.
struct RealField {
  const char* key;
  std::function<double&(DrapeBuildConfig&)> ref;
};
struct IntegerField {
  const char* key;
  std::function<std::int64_t(const DrapeBuildConfig&)> get;
  std::function<void(DrapeBuildConfig&, std::int64_t)> set;
  std::int64_t min, max;
};

const std::vector<RealField>& realFields() {
  static const std::vector<RealField> fields = {
      {"lattice_spacing_m", [](DrapeBuildConfig& c) -> double& { return c.lattice_spacing; }},
      {"spacing_m", [](DrapeBuildConfig& c) -> double& { return c.spacing; }},
      {"hold_height_m", [](DrapeBuildConfig& c) -> double& { return c.hold_height; }},
      {"start_tilt_deg", [](DrapeBuildConfig& c) -> double& { return c.start_tilt_deg; }},
      {"start_tilt_axis_deg", [](DrapeBuildConfig& c) -> double& { return c.start_tilt_axis_deg; }},
      {"start_heap.lift_deg", [](DrapeBuildConfig& c) -> double& { return c.start_heap.lift_deg; }},
      {"material_variation.bending", [](DrapeBuildConfig& c) -> double& { return c.material_variation.bending; }},
      {"material_variation.shear", [](DrapeBuildConfig& c) -> double& { return c.material_variation.shear; }},
      {"material_variation.density", [](DrapeBuildConfig& c) -> double& { return c.material_variation.density; }},
      {"simulation.dt_s", [](DrapeBuildConfig& c) -> double& { return c.settings.dt; }},
      {"simulation.dt_min_s", [](DrapeBuildConfig& c) -> double& { return c.settings.dt_min; }},
      {"simulation.dt_max_s", [](DrapeBuildConfig& c) -> double& { return c.settings.dt_max; }},
      {"simulation.error_tolerance_m", [](DrapeBuildConfig& c) -> double& { return c.settings.error_tolerance; }},
      {"simulation.max_time_s", [](DrapeBuildConfig& c) -> double& { return c.settings.max_time; }},
      {"simulation.rest_speed_m_s", [](DrapeBuildConfig& c) -> double& { return c.settings.rest_speed; }},
      {"simulation.rest_mean_speed_m_s", [](DrapeBuildConfig& c) -> double& { return c.settings.rest_mean_speed; }},
      {"simulation.rest_duration_s", [](DrapeBuildConfig& c) -> double& { return c.settings.rest_duration; }},
      {"simulation.rest_min_time_s", [](DrapeBuildConfig& c) -> double& { return c.settings.rest_min_time; }},
      {"simulation.max_edge_stretch", [](DrapeBuildConfig& c) -> double& { return c.settings.max_edge_stretch; }},
      {"simulation.max_speed_m_s", [](DrapeBuildConfig& c) -> double& { return c.settings.max_speed; }},
      {"simulation.max_wall_time_s", [](DrapeBuildConfig& c) -> double& { return c.settings.max_wall_time; }},
      {"simulation.cg_tolerance", [](DrapeBuildConfig& c) -> double& { return c.settings.solver.relative_tolerance; }},
      {"simulation.cg_accept_tolerance", [](DrapeBuildConfig& c) -> double& { return c.settings.solver.accept_tolerance; }},
      {"simulation.cg_smoothing_weight", [](DrapeBuildConfig& c) -> double& { return c.settings.solver.smoothing_weight; }},
      {"simulation.newton_tolerance", [](DrapeBuildConfig& c) -> double& { return c.settings.solver.newton_tolerance; }},
      {"rest_shape.coarse_spacing_m", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.coarse_spacing; }},
      {"rest_shape.settle_speed_m_s", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.settle_speed; }},
      {"rest_shape.settle_mean_speed_m_s", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.settle_mean_speed; }},
      {"rest_shape.settle_duration_s", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.settle_duration; }},
      {"rest_shape.settle_error_tolerance_m",
       [](DrapeBuildConfig& c) -> double& { return c.rest_shape.settle_error_tolerance; }},
      {"rest_shape.finish.force_tolerance", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.finish.force_tolerance; }},
      {"rest_shape.finish.initial_time_scale_s",
       [](DrapeBuildConfig& c) -> double& { return c.rest_shape.finish.initial_time_scale; }},
      {"rest_shape.finish.max_time_scale_s", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.finish.max_time_scale; }},
      {"rest_shape.finish.min_time_scale_s", [](DrapeBuildConfig& c) -> double& { return c.rest_shape.finish.min_time_scale; }},
      {"rest_shape.finish.max_extrapolation",
       [](DrapeBuildConfig& c) -> double& { return c.rest_shape.finish.max_extrapolation; }},
      {"views.start_deg", [](DrapeBuildConfig& c) -> double& { return c.views.start_deg; }},
      {"views.step_deg", [](DrapeBuildConfig& c) -> double& { return c.views.step_deg; }},
      {"frame.metres_per_pixel", [](DrapeBuildConfig& c) -> double& { return c.frame.metres_per_pixel; }},
      {"frame.top_margin_px", [](DrapeBuildConfig& c) -> double& { return c.frame.top_margin_px; }},
      {"frame.coverage_threshold", [](DrapeBuildConfig& c) -> double& { return c.frame.coverage_threshold; }},
      {"projection.camera_distance_m", [](DrapeBuildConfig& c) -> double& { return c.projection.camera_distance; }},
      {"projection.camera_height_m", [](DrapeBuildConfig& c) -> double& { return c.projection.camera_height; }},
      {"projection.fx", [](DrapeBuildConfig& c) -> double& { return c.projection.intrinsics.fx; }},
      {"projection.fy", [](DrapeBuildConfig& c) -> double& { return c.projection.intrinsics.fy; }},
      {"projection.cx", [](DrapeBuildConfig& c) -> double& { return c.projection.intrinsics.cx; }},
      {"projection.cy", [](DrapeBuildConfig& c) -> double& { return c.projection.intrinsics.cy; }},
      {"claim_lease_s", [](DrapeBuildConfig& c) -> double& { return c.claim_lease_s; }},
  };
  return fields;
}

#define TH_INT_FIELD(KEY, EXPR, MIN, MAX)                                                          \
  IntegerField {                                                                                   \
    KEY, [](const DrapeBuildConfig& c) { return static_cast<std::int64_t>(c.EXPR); },             \
        [](DrapeBuildConfig& c, std::int64_t v) { c.EXPR = static_cast<decltype(c.EXPR)>(v); }, MIN, MAX \
  }

const std::vector<IntegerField>& integerFields() {
  constexpr std::int64_t kIntMax = 2147483647;
  static const std::vector<IntegerField> fields = {
      TH_INT_FIELD("simulation.trajectory_every", settings.trajectory_every, 0, kIntMax),
      TH_INT_FIELD("simulation.cg_max_iterations", settings.solver.max_iterations, 1, kIntMax),
      TH_INT_FIELD("simulation.cg_smoothing_steps", settings.solver.smoothing_steps, 0, kIntMax),
      TH_INT_FIELD("simulation.newton_max_iterations", settings.solver.newton_max_iterations, 1, kIntMax),
      TH_INT_FIELD("simulation.memory_budget_bytes", settings.memory_budget_bytes, 0, std::int64_t{1} << 60),
      TH_INT_FIELD("rest_shape.finish.max_iterations", rest_shape.finish.max_iterations, 1, kIntMax),
      TH_INT_FIELD("rest_shape.finish.max_backtracks", rest_shape.finish.max_backtracks, 0, kIntMax),
      TH_INT_FIELD("start_heap.folds", start_heap.folds, 0, kIntMax),
      TH_INT_FIELD("views.count", views.count, 1, kIntMax),
      TH_INT_FIELD("frame.width_px", frame.width_px, 1, kIntMax),
      TH_INT_FIELD("frame.height_px", frame.height_px, 1, kIntMax),
      TH_INT_FIELD("frame.supersample", frame.supersample, 1, kIntMax),
      TH_INT_FIELD("projection.width_px", projection.intrinsics.width, 0, kIntMax),
      TH_INT_FIELD("projection.height_px", projection.intrinsics.height, 0, kIntMax),
      TH_INT_FIELD("staged_textile_id", staged_textile_id, 0, std::numeric_limits<std::int64_t>::max()),
      TH_INT_FIELD("workers", workers, 0, 4096),
      TH_INT_FIELD("threads_per_simulation", threads_per_simulation, 0, 4096),
  };
  return fields;
}
#undef TH_INT_FIELD

// Booleans and words (enumerations, names, texts): written and read as text.
struct TextField {
  const char* key;
  std::function<std::string(const DrapeBuildConfig&)> get;
  std::function<void(DrapeBuildConfig&, const std::string&)> set;  ///< throws std::exception on a bad value
};

bool boolFromText(const std::string& s) {
  if (s == "true") return true;
  if (s == "false") return false;
  throw std::invalid_argument("expected true or false, got '" + s + "'");
}

std::string boolText(bool b) { return b ? "true" : "false"; }

#define TH_BOOL_FIELD(KEY, EXPR) \
  TextField { KEY, [](const DrapeBuildConfig& c) { return boolText(c.EXPR); }, [](DrapeBuildConfig& c, const std::string& s) { c.EXPR = boolFromText(s); } }

const std::vector<TextField>& textFields() {
  static const std::vector<TextField> fields = {
      TH_BOOL_FIELD("use_symmetry", use_symmetry),
      TH_BOOL_FIELD("bracket_hold_points", bracket_hold_points),
      TH_BOOL_FIELD("self_collision", self_collision),
      TH_BOOL_FIELD("require_rest", require_rest),
      TH_BOOL_FIELD("retry_with_smaller_steps", retry_with_smaller_steps),
      TH_BOOL_FIELD("retry_failed", retry_failed),
      TH_BOOL_FIELD("simulation.cg_warm_start", settings.solver.warm_start),
      {"model", [](const DrapeBuildConfig& c) { return c.model.text(); },
       [](DrapeBuildConfig& c, const std::string& s) { c.model = parseClothModelSpecText(s); }},
      {"simulation.integrator", [](const DrapeBuildConfig& c) { return toString(c.settings.integrator); },
       [](DrapeBuildConfig& c, const std::string& s) { c.settings.integrator = integratorFromString(s); }},
      {"simulation.policy", [](const DrapeBuildConfig& c) { return toString(c.settings.policy); },
       [](DrapeBuildConfig& c, const std::string& s) { c.settings.policy = stepPolicyFromString(s); }},
      {"simulation.linear_solver", [](const DrapeBuildConfig& c) { return toString(c.settings.solver.kind); },
       [](DrapeBuildConfig& c, const std::string& s) { c.settings.solver.kind = linearSolverFromString(s); }},
      {"simulation.preconditioner", [](const DrapeBuildConfig& c) { return toString(c.settings.solver.preconditioner); },
       [](DrapeBuildConfig& c, const std::string& s) { c.settings.solver.preconditioner = preconditionerFromString(s); }},
      {"rest_shape.method", [](const DrapeBuildConfig& c) { return toString(c.rest_shape.method); },
       [](DrapeBuildConfig& c, const std::string& s) { c.rest_shape.method = restShapeMethodFromString(s); }},
      {"rest_shape.fine_finish",
       [](const DrapeBuildConfig& c) {
         return std::string(c.rest_shape.fine_finish == FineFinish::kNewton ? "newton" : "dynamic");
       },
       [](DrapeBuildConfig& c, const std::string& s) {
         if (s != "newton" && s != "dynamic") throw std::invalid_argument("expected newton or dynamic, got '" + s + "'");
         c.rest_shape.fine_finish = s == "newton" ? FineFinish::kNewton : FineFinish::kDynamic;
       }},
      {"projection.type",
       [](const DrapeBuildConfig& c) {
         return std::string(c.projection.type == vision::ProjectionType::kPinhole ? "pinhole" : "orthographic");
       },
       [](DrapeBuildConfig& c, const std::string& s) {
         if (s != "pinhole" && s != "orthographic")
           throw std::invalid_argument("expected orthographic or pinhole, got '" + s + "'");
         c.projection.type = s == "pinhole" ? vision::ProjectionType::kPinhole : vision::ProjectionType::kOrthographic;
       }},
      // The heap seed is a full 64-bit word: text, not a double.
      {"start_heap.seed", [](const DrapeBuildConfig& c) { return std::to_string(c.start_heap.seed); },
       [](DrapeBuildConfig& c, const std::string& s) {
         if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos)
           throw std::invalid_argument("expected a whole number >= 0, got '" + s + "'");
         errno = 0;
         const unsigned long long v = std::strtoull(s.c_str(), nullptr, 10);
         if (errno == ERANGE) throw std::invalid_argument("out of range: '" + s + "'");
         c.start_heap.seed = v;
       }},
      {"member", [](const DrapeBuildConfig& c) { return c.member; },
       [](DrapeBuildConfig& c, const std::string& s) { c.member = s; }},
      {"automatic_choice", [](const DrapeBuildConfig& c) { return c.automatic_choice; },
       [](DrapeBuildConfig& c, const std::string& s) { c.automatic_choice = s; }},
  };
  return fields;
}
#undef TH_BOOL_FIELD

// A number in the file: decimal text that converts completely and is finite.
double finiteNumber(const YAML::Node& node, const std::string& key) {
  if (!node.IsScalar()) throw InvalidInputError("build job: '" + key + "' must be a number");
  const std::string s = node.Scalar();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE || !std::isfinite(v))
    throw InvalidInputError("build job: '" + key + "' must be a finite number, got '" + s + "'");
  return v;
}

std::int64_t wholeNumber(const YAML::Node& node, const std::string& key, std::int64_t min, std::int64_t max) {
  const std::string s = node.IsScalar() ? node.Scalar() : std::string();
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE || v < min || v > max)
    throw InvalidInputError("build job: '" + key + "' must be a whole number in [" + std::to_string(min) + ", " +
                            std::to_string(max) + "], got '" + s + "'");
  return v;
}

Vec2 point(const YAML::Node& node, const std::string& key) {
  if (!node.IsSequence() || node.size() != 2) throw InvalidInputError("build job: '" + key + "' must be [x, y]");
  return Vec2(finiteNumber(node[0], key), finiteNumber(node[1], key));
}

void emitPoint(YAML::Emitter& out, const Vec2& p) {
  out << YAML::Flow << YAML::BeginSeq << internal::fmt17(p.x()) << internal::fmt17(p.y()) << YAML::EndSeq;
}

std::string writeJobText(const DrapeBuildJob& job) {
  DrapeBuildConfig c = job.config;  // the field tables take references
  YAML::Emitter out;
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "members" << YAML::Value << job.members;
  out << YAML::Key << "textile" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << c.textile.name;
  out << YAML::Key << "mirrored" << YAML::Value << boolText(c.textile.mirrored);
  out << YAML::Key << "mirror_x_m" << YAML::Value << internal::fmt17(c.textile.mirror_x);
  out << YAML::Key << "outline_m" << YAML::Value << YAML::BeginSeq;
  for (const Vec2& p : c.textile.outline) emitPoint(out, p);
  out << YAML::EndSeq;
  out << YAML::Key << "named_points" << YAML::Value << YAML::BeginSeq;
  for (const NamedPoint& p : c.textile.named_points) {
    out << YAML::BeginMap << YAML::Key << "name" << YAML::Value << YAML::DoubleQuoted << p.name;
    out << YAML::Key << "kind" << YAML::Value << YAML::DoubleQuoted << p.kind;
    out << YAML::Key << "position_m" << YAML::Value;
    emitPoint(out, p.position);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq << YAML::EndMap;
  out << YAML::Key << "material" << YAML::Value << YAML::Literal << materialToYaml(c.material);
  out << YAML::Key << "hold_points_m" << YAML::Value << YAML::BeginSeq;
  for (const Vec2& p : c.hold_points) emitPoint(out, p);
  out << YAML::EndSeq;
  for (const TextField& f : textFields()) out << YAML::Key << f.key << YAML::Value << YAML::DoubleQuoted << f.get(c);
  for (const RealField& f : realFields()) out << YAML::Key << f.key << YAML::Value << internal::fmt17(f.ref(c));
  for (const IntegerField& f : integerFields()) out << YAML::Key << f.key << YAML::Value << std::to_string(f.get(c));
  out << YAML::EndMap;
  if (!out.good()) throw InvalidInputError(std::string("build job: cannot write: ") + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

void readTextile(const YAML::Node& node, TextileOutline* t) {
  if (!node.IsMap()) throw InvalidInputError("build job: 'textile' must be a map");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (key != "name" && key != "mirrored" && key != "mirror_x_m" && key != "outline_m" && key != "named_points")
      throw InvalidInputError("build job: unknown key 'textile." + key + "'");
  }
  if (!node["name"] || !node["outline_m"]) throw InvalidInputError("build job: 'textile' needs name and outline_m");
  t->name = node["name"].as<std::string>();
  t->mirrored = node["mirrored"] ? boolFromText(node["mirrored"].as<std::string>()) : false;
  t->mirror_x = node["mirror_x_m"] ? finiteNumber(node["mirror_x_m"], "textile.mirror_x_m") : 0.0;
  const YAML::Node outline = node["outline_m"];
  if (!outline.IsSequence()) throw InvalidInputError("build job: 'textile.outline_m' must be a list of [x, y]");
  t->outline.clear();
  for (const auto& p : outline) t->outline.push_back(point(p, "textile.outline_m"));
  t->named_points.clear();
  if (const YAML::Node named = node["named_points"]) {
    if (!named.IsSequence()) throw InvalidInputError("build job: 'textile.named_points' must be a list");
    for (const auto& n : named) {
      if (!n.IsMap() || !n["name"] || !n["position_m"])
        throw InvalidInputError("build job: every 'textile.named_points' entry needs name and position_m");
      NamedPoint p;
      p.name = n["name"].as<std::string>();
      p.kind = n["kind"] ? n["kind"].as<std::string>() : std::string();
      p.position = point(n["position_m"], "textile.named_points.position_m");
      t->named_points.push_back(p);
    }
  }
  std::string error;
  if (!validateTextileOutline(*t, &error)) throw InvalidInputError("build job: 'textile': " + error);
}

DrapeBuildJob readJob(const YAML::Node& root) {
  if (!root.IsMap()) throw InvalidInputError("build job: the file is not a YAML map");
  if (!root["format"] || !root["format"].IsScalar() || root["format"].Scalar() != kFormat)
    throw InvalidInputError(std::string("build job: 'format' must be '") + kFormat + "'");
  std::set<std::string> known = {"format", "members", "textile", "material", "hold_points_m"};
  for (const auto& f : textFields()) known.insert(f.key);
  for (const auto& f : realFields()) known.insert(f.key);
  for (const auto& f : integerFields()) known.insert(f.key);
  std::set<std::string> seen;  // yaml-cpp keeps the first of repeated keys silently
  for (const auto& kv : root) {
    if (!kv.first.IsScalar() || !known.count(kv.first.Scalar()))
      throw InvalidInputError("build job: unknown key '" + (kv.first.IsScalar() ? kv.first.Scalar() : "?") + "'");
    if (!seen.insert(kv.first.Scalar()).second)
      throw InvalidInputError("build job: '" + kv.first.Scalar() + "' appears twice");
  }
  DrapeBuildJob job;
  DrapeBuildConfig& c = job.config;
  if (root["members"]) {
    job.members = root["members"].as<std::string>();
    drapeMembersByName(job.members);  // InvalidInputError naming the member
  }
  if (!root["textile"]) throw InvalidInputError("build job: 'textile' is missing");
  readTextile(root["textile"], &c.textile);
  if (!root["material"]) throw InvalidInputError("build job: 'material' is missing");
  try {
    c.material = parseMaterialYaml(root["material"].as<std::string>());
  } catch (const std::exception& e) {
    throw InvalidInputError(std::string("build job: 'material': ") + e.what());
  }
  std::string error;
  if (!c.material.validate(&error)) throw InvalidInputError("build job: 'material': " + error);
  if (const YAML::Node holds = root["hold_points_m"]) {
    if (!holds.IsSequence()) throw InvalidInputError("build job: 'hold_points_m' must be a list of [x, y]");
    for (const auto& p : holds) c.hold_points.push_back(point(p, "hold_points_m"));
  }
  for (const TextField& f : textFields())
    if (const YAML::Node n = root[f.key]) {
      if (!n.IsScalar()) throw InvalidInputError(std::string("build job: '") + f.key + "' must be text");
      try {
        f.set(c, n.Scalar());
      } catch (const std::exception& e) {
        throw InvalidInputError(std::string("build job: '") + f.key + "': " + e.what());
      }
    }
  for (const RealField& f : realFields())
    if (const YAML::Node n = root[f.key]) f.ref(c) = finiteNumber(n, f.key);
  for (const IntegerField& f : integerFields())
    if (const YAML::Node n = root[f.key]) f.set(c, wholeNumber(n, f.key, f.min, f.max));
  try {
    ClothModelRegistry::instance().validate(c.model);
  } catch (const ClothModelError& e) {
    throw InvalidInputError(std::string("build job: 'model': ") + e.what());
  }
  if (!(c.spacing > 0) || !(c.lattice_spacing > 0))
    throw InvalidInputError("build job: 'spacing_m' and 'lattice_spacing_m' must be positive");
  if (!(c.claim_lease_s >= 3 && c.claim_lease_s <= 1e6))
    throw InvalidInputError("build job: 'claim_lease_s' must be in [3, 1e6]");
  return job;
}

}  // namespace

DrapeBuildJob parseDrapeBuildJob(const std::string& text) {
  if (text.size() > kMaxBuildJobBytes)
    throw InvalidInputError(textSizeError("build job", text.size(), kMaxBuildJobBytes));
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InvalidInputError(std::string("build job: malformed YAML: ") + e.what());
  }
  try {
    return readJob(root);
  } catch (const YAML::Exception& e) {  // a value of the wrong shape deeper down
    throw InvalidInputError(std::string("build job: ") + e.what());
  }
}

std::string drapeBuildJobText(const DrapeBuildJob& job) {
  drapeMembersByName(job.members);
  const std::string text = writeJobText(job);
  // The file must give back this very build: every parameter text (what the rows are keyed by) and
  // every other setting (the second writing of what was read equals the first).
  const DrapeBuildJob back = parseDrapeBuildJob(text);
  const auto mine = DrapeDatabaseBuilder::parameterTexts(job.config);
  const auto read = DrapeDatabaseBuilder::parameterTexts(back.config);
  if (mine != read)
    throw InvalidInputError("build job: the written settings do not give back the build's parameter text:\n" +
                            mine.front() + "--- read back as ---\n" + read.front());
  if (writeJobText(back) != text) throw InvalidInputError("build job: a setting does not survive writing and reading");
  return text;
}

DrapeBuildJob loadDrapeBuildJob(const std::string& path) {
  std::string text, error;
  if (!readBoundedTextFile(path, kMaxBuildJobBytes, &text, &error))
    throw InvalidInputError("build job '" + path + "': " + error);
  try {
    return parseDrapeBuildJob(text);
  } catch (const InvalidInputError& e) {
    throw InvalidInputError("'" + path + "': " + e.what());
  }
}

void saveDrapeBuildJob(const DrapeBuildJob& job, const std::string& path) {
  const std::string text = drapeBuildJobText(job);
  writeFileAtomically(path, [&](std::ostream& out) { out << text; });
}

}  // namespace db
}  // namespace textile_handling
