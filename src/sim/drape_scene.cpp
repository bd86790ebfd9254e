#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/obstacle_penalty.h"

#include <yaml-cpp/yaml.h>

#include "textile_handling/sim/memory_budget.h"
#include "textile_handling/sim/text_input.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <set>
#include <sstream>
#include <stdexcept>

namespace textile_handling {

std::string HoldPoint::label() const {
  if (!name.empty()) return name;
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3f,%.3f", position.x(), position.y());
  return buf;
}

namespace {

// A hold position this close to the outline [m] counts as on it: far below any particle spacing,
// far above the rounding of coordinates written in decimal.
constexpr Real kHoldTolerance = 1e-6;

Vec2 resolveHold(const TextileOutline& t, const HoldPoint& h) {
  if (h.name.empty()) return h.position;
  for (const auto& np : t.named_points)
    if (np.name == h.name) return np.position;
  std::string known;
  for (const auto& np : t.named_points) known += (known.empty() ? "" : ", ") + np.name;
  throw SceneError("textile '" + t.name + "' has no named point '" + h.name + "' (known: " + known + ")");
}

// Hold positions given as coordinates must lie on the textile (named points are checked with the
// outline); a point beside it would silently pin the nearest particle instead.
void checkHoldPointsOnTextile(const DrapeSceneSpec& spec, const std::vector<Vec2>& outline) {
  for (std::size_t k = 0; k < spec.hold.size(); ++k) {
    const HoldPoint& h = spec.hold[k];
    if (!h.name.empty()) continue;
    if (!h.position.allFinite() || !pointInPolygon(outline, h.position, kHoldTolerance))
      throw SceneError("hold point " + std::to_string(k) + " (" + h.label() + ") lies outside the outline of textile '" +
                                  spec.textile.name + "'");
  }
}

// The scene's memory estimate against its budget, before the model and the solver allocate.
void checkSceneMemory(const DrapeSceneSpec& spec, Index nodes) {
  SimulationMemoryInput in = memoryInput(nodes, spec.settings, spec.self_collision);
  in.dofs_per_node = ClothModelRegistry::instance().find(spec.model.name).dofs_per_node;
  const std::string what = "the scene (textile '" + spec.textile.name + "', " + std::to_string(nodes) +
                           " particles at spacing " + std::to_string(spec.spacing) + " m)";
  checkMemoryBudget(estimateSimulationBytes(in), spec.settings.memory_budget_bytes, what);
}

}  // namespace

bool isClothModelName(const std::string& name) { return ClothModelRegistry::instance().contains(name); }

DrapeScene buildDrapeScene(const DrapeSceneSpec& spec) {
  if (spec.automatic.requested)
    throw SceneError("model: auto is chosen before the scene is built (chooseConfiguration(), db/automatic_configuration.h)");
  const ClothModelRegistry& models = ClothModelRegistry::instance();
  const std::any model_options = models.parseOptions(spec.model);  // throws ClothModelError naming the key
  if (spec.hold.empty() && spec.pinned_regions.empty())
    throw SceneError("scene holds nothing: give at least one hold point or pinned region");
  if (!spec.hold_position.allFinite()) throw SceneError("hold position is not finite");
  if (!(std::abs(spec.start_tilt_deg) <= 90) || !std::isfinite(spec.start_tilt_axis_deg))
    throw SceneError("start: tilt_deg must be in [-90, 90] and tilt_axis_deg finite, got " +
                     std::to_string(spec.start_tilt_deg) + " and " + std::to_string(spec.start_tilt_axis_deg));
  if (spec.start_heap.folds < 0 || spec.start_heap.folds > kMaxHeapFolds)
    throw SceneError("start: heap_folds must be in [0, " + std::to_string(kMaxHeapFolds) + "], got " +
                     std::to_string(spec.start_heap.folds));
  if (spec.start_heap.folds > 0 && spec.hold.empty())
    throw SceneError("start: a heap start needs a hold point (it is lifted by it)");
  if (spec.lift_times.size() != spec.lift_offsets.size())
    throw SceneError("lift: times and offsets differ in length");
  for (size_t k = 0; k < spec.lift_times.size(); ++k) {
    if (!std::isfinite(spec.lift_times[k]) || !spec.lift_offsets[k].allFinite())
      throw SceneError("lift: non-finite waypoint");
    if (k > 0 && !(spec.lift_times[k] > spec.lift_times[k - 1]))
      throw SceneError("lift: waypoint times must increase");
  }
  std::string error;
  if (!validateTextileOutline(spec.textile, &error)) throw SceneError("textile: " + error);
  if (!spec.material.validate(&error)) throw SceneError("material: " + error);

  DrapeScene scene;
  scene.spec = spec;
  scene.grid = ParticleGrid::rasterize(spec.textile, spec.spacing, &error);
  if (scene.grid.empty()) throw SceneError("rasterisation failed: " + error);
  checkHoldPointsOnTextile(spec, scene.grid.polygon());
  checkSceneMemory(spec, scene.grid.numActive());
  ParticleTopology topology = ParticleTopology::fromGrid(scene.grid);
  std::unique_ptr<ClothModel> model = models.find(spec.model.name).create(topology, spec.material, model_options);

  const Index n = scene.grid.numActive();
  // Shift so that the first held point (or the first region's centre) sits at hold_position.
  Vec2 ref;
  if (!spec.hold.empty()) {
    const Index p = scene.grid.nearestActive(resolveHold(spec.textile, spec.hold.front()));
    ref = scene.grid.activePosition(p);
  } else {
    const auto& r = spec.pinned_regions.front();
    ref = Vec2(0.5 * (r[0] + r[2]), 0.5 * (r[1] + r[3]));
  }
  scene.textile_to_world = spec.hold_position - Vec3(ref.x(), ref.y(), 0);
  // Positions into the position DOFs; a model's further DOFs (sliding coordinates) start at 0.
  VecX positions(3 * n);
  for (Index r = 0; r < n; ++r) {
    const Vec2 q = scene.grid.activePosition(r);
    positions.segment<3>(3 * r) = Vec3(q.x(), q.y(), 0) + scene.textile_to_world;
  }
  if (spec.start_heap.folds > 0) {
    const Index p = scene.grid.nearestActive(resolveHold(spec.textile, spec.hold.front()));
    try {
      positions = heapStartPositions(scene.grid, p, spec.start_heap, std::max<Real>(spec.spacing, 0.03));
    } catch (const std::invalid_argument& e) {
      throw SceneError(e.what());
    }
    for (Index r = 0; r < n; ++r) positions.segment<3>(3 * r) += scene.textile_to_world;
  }
  if (spec.start_tilt_deg != 0) {
    const Real a = spec.start_tilt_axis_deg * kPi / 180;
    const Eigen::AngleAxis<Real> tilt(spec.start_tilt_deg * kPi / 180, Vec3(std::cos(a), std::sin(a), 0));
    const Vec3 pivot = spec.hold_position;
    for (Index r = 0; r < n; ++r) positions.segment<3>(3 * r) = pivot + tilt * (positions.segment<3>(3 * r) - pivot);
  }
  scene.x0 = VecX::Zero(model->numDofs());
  model->setPositions(positions, scene.x0);
  scene.v0 = VecX::Zero(model->numDofs());

  std::vector<char> pinned(n, 0);
  auto pin = [&](Index p) {
    if (pinned[p]) return;
    pinned[p] = 1;
    scene.pins.nodes.push_back(p);
    scene.pins.anchors.push_back(positions.segment<3>(3 * p));
  };
  for (const auto& h : spec.hold) {
    const Index p = scene.grid.nearestActive(resolveHold(spec.textile, h));
    if (scene.hold_particle < 0) scene.hold_particle = p;
    pin(p);
  }
  for (std::size_t k = 0; k < spec.pinned_regions.size(); ++k) {
    const auto& r = spec.pinned_regions[k];
    const std::string name = "pinned region " + std::to_string(k);
    if (!r.allFinite() || !(r[2] >= r[0]) || !(r[3] >= r[1]))
      throw SceneError(name + " must be finite with x0 <= x1 and y0 <= y1");
    const Index before = static_cast<Index>(scene.pins.nodes.size());
    for (Index p = 0; p < n; ++p) {
      const Vec2 q = scene.grid.activePosition(p);
      const Real tol = 1e-9;
      if (q.x() >= r[0] - tol && q.x() <= r[2] + tol && q.y() >= r[1] - tol && q.y() <= r[3] + tol) pin(p);
    }
    if (static_cast<Index>(scene.pins.nodes.size()) == before)
      throw SceneError(name + " contains no particle (it lies outside the textile or between particles)");
  }
  if (scene.hold_particle < 0) scene.hold_particle = scene.pins.nodes.front();
  scene.pins.waypoint_times = spec.lift_times;
  scene.pins.waypoint_offsets = spec.lift_offsets;
  for (const auto& np : spec.textile.named_points)
    scene.named_particles.emplace_back(np.name, scene.grid.nearestActive(np.position));
  scene.model = std::move(model);

  // Collision handling (the pass constructors validate the obstacles and options).
  if (!spec.obstacles.empty() && spec.obstacles.method == ObstacleMethod::kPenalty) {
    ObstaclePenaltyOptions o;
    o.thickness = spec.obstacles.options.contact_distance;
    o.friction = spec.obstacles.options.friction;
    o.stiffness_factor = spec.obstacles.penalty_stiffness_factor;
    o.damping_ratio = spec.obstacles.penalty_damping_ratio;
    o.stick_speed = spec.obstacles.penalty_stick_speed;
    if (const std::string e = obstaclePenaltyErrors(o); !e.empty())
      throw SceneError("obstacles (method penalty): " + e + " (obstacles.contact_distance_m must be > 0)");
    scene.model = std::make_unique<ObstaclePenaltyModel>(std::move(scene.model), pinned, spec.obstacles.planes,
                                                         spec.obstacles.boxes, spec.obstacles.spheres, o);
  } else if (!spec.obstacles.empty()) {
    scene.obstacle_pass = std::make_unique<ObstaclePass>(n, scene.pins, spec.obstacles.options);
    for (const auto& p : spec.obstacles.planes) scene.obstacle_pass->addPlane(p);
    for (const auto& b : spec.obstacles.boxes) scene.obstacle_pass->addBox(b);
    for (const auto& sp : spec.obstacles.spheres) scene.obstacle_pass->addSphere(sp);
  }
  if (spec.self_collision) {
    if (!(spec.collision.max_passes >= 1) || !(spec.collision.d_min >= 0) || !(spec.collision.restitution >= 0) ||
        !(spec.collision.restitution <= 1) || !(spec.collision.tangential_damping >= 0) ||
        !(spec.collision.tangential_damping <= 1) || !(spec.collision.cell_size_factor > 0) ||
        !std::isfinite(spec.collision.cell_size_factor) || !(spec.collision.barycentric_tolerance >= 0))
      throw SceneError("collision: options out of range (see docs/collision.md)");
    scene.self_collision_pass = std::make_unique<SelfCollisionPass>(topology, scene.pins, spec.collision);
    // Persistent contact: the proximity stage's contact forces enter the next implicit solve, so a
    // textile resting on itself is a fixed point (docs/collision.md, "Persistent contact").
    scene.model = withContactForces(std::move(scene.model), *scene.self_collision_pass);
  }
  if (scene.obstacle_pass && scene.self_collision_pass)
    scene.pass_chain = std::make_unique<PostStepPassChain>(
        std::vector<PostStepPass*>{scene.obstacle_pass.get(), scene.self_collision_pass.get()});
  if (scene.model->dofsPerNode() != 3) {
    PostStepPass* passes = scene.pass_chain ? static_cast<PostStepPass*>(scene.pass_chain.get())
                           : scene.obstacle_pass ? static_cast<PostStepPass*>(scene.obstacle_pass.get())
                                                 : static_cast<PostStepPass*>(scene.self_collision_pass.get());
    if (passes) scene.position_view = std::make_unique<PositionViewPass>(*passes, *scene.model);
  }
  return scene;
}

PostStepPass* DrapeScene::postStepPass() const {
  if (position_view) return position_view.get();
  if (pass_chain) return pass_chain.get();
  if (obstacle_pass) return obstacle_pass.get();
  return self_collision_pass.get();
}

ClothTriangles DrapeScene::triangles() const {
  return ClothTriangles::fromTopology(ParticleTopology::fromGrid(grid));
}

Real hangingDepth(const DrapeScene& scene, const VecX& positions) {
  const Real top = positions[3 * scene.hold_particle + 2];
  Real lowest = top;
  for (Index r = 0; r < scene.model->numNodes(); ++r) lowest = std::min(lowest, positions[3 * r + 2]);
  return top - lowest;
}

// ---- YAML -------------------------------------------------------------------------------------

namespace {

// Longest list of a scene other than outlines and named points (whose limits are in
// textile_geometry.h): hold points, lift waypoints, pinned regions, obstacles of each kind.
constexpr std::size_t kMaxSceneListLength = 256;

[[noreturn]] void fail(const std::string& message) { throw SceneError("scene: " + message); }

// Keys and names from the file are quoted at most this long in messages (a key path holds a few
// names of at most kMaxTextileNameLength characters).
constexpr std::size_t kMaxQuotedLength = 200;

std::string quoted(const std::string& text) {
  return "'" + (text.size() > kMaxQuotedLength ? text.substr(0, kMaxQuotedLength) + "..." : text) + "'";
}

std::string joined(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }

using KeyList = std::initializer_list<const char*>;

// Every key of the map `n` (at `path`) must be a plain string from `known`, and none may repeat.
void checkKeys(const YAML::Node& n, const std::string& path, KeyList known) {
  if (!n.IsMap()) fail(quoted(path) + " must be a map");
  std::set<std::string> seen;
  for (const auto& kv : n) {
    if (!kv.first.IsScalar()) fail(quoted(path) + " has a key that is not a plain string");
    const std::string& key = kv.first.Scalar();
    if (std::none_of(known.begin(), known.end(), [&](const char* k) { return key == k; })) {
      std::string list;
      for (const char* k : known) list += (list.empty() ? "" : ", ") + std::string(k);
      fail("unknown key " + quoted(joined(path, key)) + " (known: " + list + ")");
    }
    if (!seen.insert(key).second) fail("key " + quoted(joined(path, key)) + " appears twice");
  }
}

void requireKey(const YAML::Node& n, const char* key, const std::string& path) {
  if (!n[key]) fail("missing required key " + quoted(joined(path, key)));
}

// A list with at most `limit` items, checked before any item is copied.
void checkList(const YAML::Node& n, const std::string& field, std::size_t limit) {
  if (!n.IsSequence()) fail(quoted(field) + " must be a list");
  if (n.size() > limit)
    fail(quoted(field) + " has " + std::to_string(n.size()) + " items, more than the limit of " + std::to_string(limit));
}

Real getReal(const YAML::Node& n, const std::string& field) {
  if (!n.IsScalar()) fail(quoted(field) + " must be a number");
  try {
    const Real v = n.as<Real>();
    if (!std::isfinite(v)) fail(quoted(field) + " is not finite");
    return v;
  } catch (const YAML::Exception&) {
    fail(quoted(field) + " must be a number");
  }
}

Real positive(const YAML::Node& parent, const char* key, Real fallback, const std::string& where) {
  if (!parent[key]) return fallback;
  const Real v = getReal(parent[key], where + key);
  if (!(v > 0)) fail("'" + where + key + "' must be positive");
  return v;
}

// Optional positive numbers of one section: each present key overwrites its field.
void readPositives(const YAML::Node& section, const std::string& where,
                   std::initializer_list<std::pair<const char*, Real*>> fields) {
  for (const auto& f : fields) *f.second = positive(section, f.first, *f.second, where);
}

// Scalars of other types, with an error naming the field instead of yaml-cpp's "bad conversion".
std::string getString(const YAML::Node& n, const std::string& field) {
  if (!n.IsScalar()) fail(quoted(field) + " must be a string");
  return n.Scalar();
}

int getInt(const YAML::Node& n, const std::string& field) {
  if (!n.IsScalar()) fail(quoted(field) + " must be an integer");
  try {
    return n.as<int>();
  } catch (const YAML::Exception&) {
    fail(quoted(field) + " must be an integer");
  }
}

bool getBool(const YAML::Node& parent, const char* key, bool fallback, const std::string& where) {
  if (!parent[key]) return fallback;
  try {
    if (!parent[key].IsScalar()) throw YAML::Exception(YAML::Mark::null_mark(), "not a scalar");
    return parent[key].as<bool>();
  } catch (const YAML::Exception&) {
    fail("'" + where + key + "' must be true or false");
  }
}

// Optional booleans of one section: each present key overwrites its field.
void readBools(const YAML::Node& section, const std::string& where,
               std::initializer_list<std::pair<const char*, bool*>> fields) {
  for (const auto& f : fields) *f.second = getBool(section, f.first, *f.second, where);
}

template <int N>
Eigen::Matrix<Real, N, 1> getVec(const YAML::Node& n, const std::string& field) {
  if (!n || !n.IsSequence() || n.size() != N)
    fail(quoted(field) + " must be a list of " + std::to_string(N) + " numbers");
  Eigen::Matrix<Real, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = getReal(n[i], field);
  return v;
}

// A value from a fixed set of names, converted by `parse` (which throws std::invalid_argument).
template <typename T, typename Parse>
T getEnum(const YAML::Node& n, const std::string& field, Parse parse) {
  const std::string name = getString(n, field);
  try {
    return parse(name);
  } catch (const std::invalid_argument& e) {
    fail(quoted(field) + ": " + e.what());
  }
}

HoldPoint parseHold(const YAML::Node& n) {
  HoldPoint h;
  if (n.IsScalar()) {
    h.name = n.Scalar();
  } else {
    h.position = getVec<2>(n, "hold.points[]");
  }
  return h;
}

NamedPoint parseNamedPoint(const YAML::Node& key, const YAML::Node& v) {
  NamedPoint p;
  p.name = getString(key, "textile.named_points");
  const std::string field = "textile.named_points." + p.name;
  p.kind = "grasp";
  if (v.IsMap()) {
    checkKeys(v, field, {"position", "kind"});
    requireKey(v, "position", field);
    p.position = getVec<2>(v["position"], field + ".position");
    if (v["kind"]) p.kind = getString(v["kind"], field + ".kind");
  } else {
    p.position = getVec<2>(v, field);
  }
  return p;
}

TextileOutline parseTextile(const YAML::Node& n) {
  if (n.IsScalar()) return presetTextile(n.Scalar());
  if (!n.IsMap()) fail("'textile' must be a preset name or a map with 'outline'");
  checkKeys(n, "textile", {"name", "outline", "mirror_x", "named_points"});
  requireKey(n, "outline", "textile");
  TextileOutline t;
  t.name = n["name"] ? getString(n["name"], "textile.name") : "custom";
  checkList(n["outline"], "textile.outline", kMaxOutlineVertices);
  for (const auto& v : n["outline"]) t.outline.push_back(getVec<2>(v, "textile.outline[]"));
  if (n["mirror_x"]) {
    t.mirrored = true;
    t.mirror_x = getReal(n["mirror_x"], "textile.mirror_x");
  }
  if (const YAML::Node points = n["named_points"]) {
    if (!points.IsMap()) fail("'textile.named_points' must be a map of name: [x, y]");
    if (points.size() > kMaxNamedPoints)
      fail("'textile.named_points' has " + std::to_string(points.size()) + " points, more than the limit of " +
           std::to_string(kMaxNamedPoints));
    for (const auto& it : points) t.named_points.push_back(parseNamedPoint(it.first, it.second));
  }
  return t;
}

Material parseMaterial(const YAML::Node& n, const std::string& base_dir) {
  const std::string m = getString(n, "material");
  if (m == "cotton") return Material::cotton();
  const std::string path = (!m.empty() && m[0] == '/') ? m : base_dir + "/" + m;
  return loadMaterialYaml(path);
}

void parseHoldSection(const YAML::Node& h, bool has_regions, DrapeSceneSpec& s) {
  checkKeys(h, "hold", {"points", "position", "lift"});
  if (!has_regions) requireKey(h, "points", "hold");
  if (const YAML::Node points = h["points"]) {
    checkList(points, "hold.points", kMaxSceneListLength);
    for (const auto& p : points) s.hold.push_back(parseHold(p));
    if (s.hold.empty() && !has_regions) fail("'hold.points' is empty and there are no pinned_regions: nothing holds the textile");
  }
  if (h["position"]) s.hold_position = getVec<3>(h["position"], "hold.position");
  if (const YAML::Node lift = h["lift"]) {
    checkList(lift, "hold.lift", kMaxSceneListLength);
    for (const auto& w : lift) {
      const auto v = getVec<4>(w, "hold.lift[]");
      s.lift_times.push_back(v[0]);
      s.lift_offsets.push_back(v.tail<3>());
    }
  }
}

// The model section: `name` plus the model's own option keys (ClothModelRegistry), validated here so
// that a bad key fails when the scene is read.
void parseAutomaticModel(const YAML::Node& m, DrapeSceneSpec& s) {
  s.automatic.requested = true;
  for (const auto& kv : m) {
    if (!kv.first.IsScalar()) fail("'model' has a key that is not a plain string");
    const std::string& key = kv.first.Scalar();
    if (key == "name") continue;
    if (key == "question") {
      s.automatic.question = getString(kv.second, "model.question");
    } else if (key == "spacings_m") {
      checkList(kv.second, "model.spacings_m", kMaxSceneListLength);
      for (const auto& v : kv.second) {
        const Real d = getReal(v, "model.spacings_m[]");
        if (!(d > 0)) fail("'model.spacings_m' values must be > 0");
        s.automatic.spacings.push_back(d);
      }
    } else if (key == "named_point_tolerance_m") {
      s.automatic.named_point_tolerance_m = positive(m, "named_point_tolerance_m", 0.03, "model.");
    } else if (key == "min_mean_iou") {
      s.automatic.min_mean_iou = getReal(kv.second, "model.min_mean_iou");
      if (!(s.automatic.min_mean_iou >= 0 && s.automatic.min_mean_iou <= 1)) fail("'model.min_mean_iou' must be in [0, 1]");
    } else {
      fail("unknown key " + quoted(joined("model", key)) +
           " for name: auto; known: question, spacings_m, named_point_tolerance_m, min_mean_iou");
    }
  }
}

void parseModel(const YAML::Node& m, DrapeSceneSpec& s) {
  if (!m.IsMap()) fail("'model' must be a map");
  if (m["name"] && m["name"].IsScalar() && m["name"].Scalar() == "auto") return parseAutomaticModel(m, s);
  std::set<std::string> seen;
  for (const auto& kv : m) {
    if (!kv.first.IsScalar()) fail("'model' has a key that is not a plain string");
    const std::string& key = kv.first.Scalar();
    if (!seen.insert(key).second) fail("key " + quoted(joined("model", key)) + " appears twice");
    if (key == "name") continue;
    s.model.options[key] = getString(kv.second, joined("model", key));
  }
  if (m["name"]) s.model.name = getString(m["name"], "model.name");
  try {
    ClothModelRegistry::instance().validate(s.model);
  } catch (const ClothModelError& e) {
    fail(e.what());
  }
}

void parseSolverKeys(const YAML::Node& m, SolverSettings& solver) {
  solver.relative_tolerance = positive(m, "cg_tolerance", solver.relative_tolerance, "simulation.");
  if (!(solver.relative_tolerance < 1)) fail("'simulation.cg_tolerance' must be < 1");
  if (m["cg_max_iterations"]) solver.max_iterations = getInt(m["cg_max_iterations"], "simulation.cg_max_iterations");
  if (solver.max_iterations < 1) fail("'simulation.cg_max_iterations' must be >= 1");
  if (m["linear_solver"])
    solver.kind = getEnum<LinearSolverKind>(m["linear_solver"], "simulation.linear_solver", linearSolverFromString);
  if (m["preconditioner"])
    solver.preconditioner =
        getEnum<PreconditionerKind>(m["preconditioner"], "simulation.preconditioner", preconditionerFromString);
  solver.warm_start = getBool(m, "cg_warm_start", solver.warm_start, "simulation.");
  if (m["cg_smoothing_steps"]) {
    solver.smoothing_steps = getInt(m["cg_smoothing_steps"], "simulation.cg_smoothing_steps");
    if (solver.smoothing_steps < 0) fail("'simulation.cg_smoothing_steps' must be >= 0");
  }
  if (m["cg_smoothing_weight"]) {
    solver.smoothing_weight = positive(m, "cg_smoothing_weight", solver.smoothing_weight, "simulation.");
    if (!(solver.smoothing_weight < 1.0)) fail("'simulation.cg_smoothing_weight' must be in (0, 1)");
  }
  if (m["cg_accept_tolerance"]) {
    solver.accept_tolerance = getReal(m["cg_accept_tolerance"], "simulation.cg_accept_tolerance");
    if (!(solver.accept_tolerance >= 0 && solver.accept_tolerance < 1))
      fail("'simulation.cg_accept_tolerance' must be in [0, 1)");
  }
  if (m["newton_max_iterations"]) {
    solver.newton_max_iterations = getInt(m["newton_max_iterations"], "simulation.newton_max_iterations");
    if (solver.newton_max_iterations < 1) fail("'simulation.newton_max_iterations' must be >= 1");
  }
  solver.newton_tolerance = positive(m, "newton_tolerance", solver.newton_tolerance, "simulation.");
}

void parseSimulation(const YAML::Node& m, SimulationSettings& t) {
  checkKeys(m, "simulation",
            {"integrator", "policy", "dt_s", "dt_min_s", "dt_max_s", "error_tolerance_m", "max_time_s",
             "max_wall_time_s", "rest_speed_m_s", "rest_mean_speed_m_s", "rest_duration_s", "max_edge_stretch",
             "cg_tolerance", "cg_max_iterations", "linear_solver", "preconditioner", "cg_warm_start",
             "cg_smoothing_steps", "cg_smoothing_weight", "cg_accept_tolerance", "newton_max_iterations",
             "newton_tolerance", "trajectory_every"});
  if (m["integrator"]) t.integrator = getEnum<IntegratorType>(m["integrator"], "simulation.integrator", integratorFromString);
  if (m["policy"]) t.policy = getEnum<StepPolicy>(m["policy"], "simulation.policy", stepPolicyFromString);
  readPositives(m, "simulation.",
                {{"dt_s", &t.dt}, {"dt_min_s", &t.dt_min}, {"dt_max_s", &t.dt_max},
                 {"error_tolerance_m", &t.error_tolerance}, {"max_time_s", &t.max_time},
                 {"max_wall_time_s", &t.max_wall_time}, {"rest_speed_m_s", &t.rest_speed},
                 {"rest_mean_speed_m_s", &t.rest_mean_speed}, {"rest_duration_s", &t.rest_duration},
                 {"max_edge_stretch", &t.max_edge_stretch}});
  parseSolverKeys(m, t.solver);
  if (m["trajectory_every"]) t.trajectory_every = getInt(m["trajectory_every"], "simulation.trajectory_every");
  if (t.trajectory_every < 0) fail("'simulation.trajectory_every' must be >= 0");
}

void parseCollision(const YAML::Node& c, DrapeSceneSpec& s) {
  checkKeys(c, "collision",
            {"self", "response", "max_passes", "d_min_m", "include_diagonals", "point_in_triangle_check",
             "fallback_rollback", "restitution", "tangential_damping", "cell_size_factor", "proximity",
             "proximity_propagate", "proximity_edges", "contact_forces", "thickness_factor",
             "proximity_search_factor", "proximity_friction", "proximity_separation", "proximity_iterations"});
  SelfCollisionOptions& o = s.collision;
  if (c["self"]) {
    const std::string v = getString(c["self"], "collision.self");
    s.self_collision = !(v == "off" || v == "false" || v == "none");
    if (s.self_collision) {
      try {
        o.version = selfCollisionVersionFromString(v);
      } catch (const std::invalid_argument& e) {
        fail(std::string("'collision.self': ") + e.what() + " (or off)");
      }
    }
  }
  if (c["response"]) {
    const std::string r = getString(c["response"], "collision.response");
    if (r == "stop") o.response = CollisionResponse::kStop;
    else if (r == "thesis") o.response = CollisionResponse::kThesis;
    else if (r == "relative") o.response = CollisionResponse::kRelative;
    else fail("'collision.response' must be stop, thesis or relative");
  }
  if (c["max_passes"]) {
    o.max_passes = getInt(c["max_passes"], "collision.max_passes");
    if (o.max_passes < 1) fail("'collision.max_passes' must be >= 1");
  }
  // Proximity stage keys (persistent contact) too; their ranges are checked by the pass constructor.
  readPositives(c, "collision.",
                {{"d_min_m", &o.d_min}, {"cell_size_factor", &o.cell_size_factor},
                 {"thickness_factor", &o.thickness_factor}, {"proximity_search_factor", &o.proximity_search_factor}});
  readBools(c, "collision.",
            {{"include_diagonals", &o.include_diagonals}, {"point_in_triangle_check", &o.point_in_triangle_check},
             {"fallback_rollback", &o.fallback_rollback}, {"proximity", &o.proximity},
             {"proximity_propagate", &o.proximity_propagate}, {"proximity_edges", &o.proximity_edges},
             {"contact_forces", &o.contact_forces}});
  for (const char* key : {"restitution", "tangential_damping"}) {
    if (!c[key]) continue;
    const Real v = getReal(c[key], std::string("collision.") + key);
    if (!(v >= 0 && v <= 1)) fail(std::string("'collision.") + key + "' must be in [0, 1]");
    (std::string(key) == "restitution" ? o.restitution : o.tangential_damping) = v;
  }
  if (c["proximity_friction"]) o.proximity_friction = getReal(c["proximity_friction"], "collision.proximity_friction");
  if (c["proximity_separation"])
    o.proximity_separation = getReal(c["proximity_separation"], "collision.proximity_separation");
  if (c["proximity_iterations"])
    o.proximity_iterations = getInt(c["proximity_iterations"], "collision.proximity_iterations");
}

BoxObstacle parseBox(const YAML::Node& b) {
  BoxObstacle q;
  if (b.IsMap() && (b["min"] || b["max"])) {
    checkKeys(b, "obstacles.boxes[]", {"min", "max"});
    const Vec3 lo = getVec<3>(b["min"], "obstacles.boxes[].min");
    const Vec3 hi = getVec<3>(b["max"], "obstacles.boxes[].max");
    if (!((hi - lo).array() > 0).all()) fail("'obstacles.boxes[]': max must exceed min on every axis");
    return BoxObstacle::axisAligned(lo, hi);
  }
  checkKeys(b, "obstacles.boxes[]", {"min", "max", "centre", "half_extents", "yaw_rad"});
  q.centre = getVec<3>(b["centre"], "obstacles.boxes[].centre");
  q.half_extents = getVec<3>(b["half_extents"], "obstacles.boxes[].half_extents");
  if (!(q.half_extents.array() > 0).all()) fail("'obstacles.boxes[].half_extents' must be positive");
  if (b["yaw_rad"]) {
    const Real yaw = getReal(b["yaw_rad"], "obstacles.boxes[].yaw_rad");
    q.rotation = Eigen::AngleAxis<Real>(yaw, Vec3::UnitZ()).toRotationMatrix();
  }
  return q;
}

void parseObstacles(const YAML::Node& ob, ObstacleSpec& o) {
  checkKeys(ob, "obstacles", {"method", "contact_distance_m", "friction", "penalty_stiffness_factor",
                              "penalty_damping_ratio", "penalty_stick_speed_m_per_s", "planes", "boxes", "spheres"});
  if (ob["method"]) {
    const std::string m = getString(ob["method"], "obstacles.method");
    if (m == "position") o.method = ObstacleMethod::kPosition;
    else if (m == "penalty") o.method = ObstacleMethod::kPenalty;
    else fail("'obstacles.method' must be position or penalty, not '" + m + "'");
  }
  if (ob["penalty_stiffness_factor"]) {
    o.penalty_stiffness_factor = getReal(ob["penalty_stiffness_factor"], "obstacles.penalty_stiffness_factor");
    if (!(o.penalty_stiffness_factor > 0)) fail("'obstacles.penalty_stiffness_factor' must be > 0");
  }
  if (ob["penalty_damping_ratio"]) {
    o.penalty_damping_ratio = getReal(ob["penalty_damping_ratio"], "obstacles.penalty_damping_ratio");
    if (!(o.penalty_damping_ratio >= 0)) fail("'obstacles.penalty_damping_ratio' must be >= 0");
  }
  if (ob["penalty_stick_speed_m_per_s"]) {
    o.penalty_stick_speed = getReal(ob["penalty_stick_speed_m_per_s"], "obstacles.penalty_stick_speed_m_per_s");
    if (!(o.penalty_stick_speed > 0)) fail("'obstacles.penalty_stick_speed_m_per_s' must be > 0");
  }
  if (ob["contact_distance_m"]) {
    o.options.contact_distance = getReal(ob["contact_distance_m"], "obstacles.contact_distance_m");
    if (!(o.options.contact_distance >= 0)) fail("'obstacles.contact_distance_m' must be >= 0");
  }
  if (ob["friction"]) {
    o.options.friction = getReal(ob["friction"], "obstacles.friction");
    if (!(o.options.friction >= 0)) fail("'obstacles.friction' must be >= 0");
  }
  auto list = [&](const char* key) {
    const YAML::Node l = ob[key];
    if (l) checkList(l, std::string("obstacles.") + key, kMaxSceneListLength);
    return l;
  };
  for (const auto& p : list("planes")) {
    checkKeys(p, "obstacles.planes[]", {"point", "normal"});
    PlaneObstacle q;
    q.point = getVec<3>(p["point"], "obstacles.planes[].point");
    q.normal = getVec<3>(p["normal"], "obstacles.planes[].normal");
    if (!(q.normal.norm() > 1e-12)) fail("'obstacles.planes[].normal' is zero");
    o.planes.push_back(q);
  }
  for (const auto& b : list("boxes")) o.boxes.push_back(parseBox(b));
  for (const auto& sp : list("spheres")) {
    checkKeys(sp, "obstacles.spheres[]", {"centre", "radius_m"});
    SphereObstacle q;
    q.centre = getVec<3>(sp["centre"], "obstacles.spheres[].centre");
    if (!sp["radius_m"]) fail("'obstacles.spheres[].radius_m' is missing");
    q.radius = positive(sp, "radius_m", 0, "obstacles.spheres[].");
    o.spheres.push_back(q);
  }
}

void parseSceneRoot(const YAML::Node& root, const std::string& base_dir, DrapeSceneSpec& s) {
  checkKeys(root, "", {"textile", "material", "spacing_m", "hold", "pinned_regions", "model", "simulation",
                       "collision", "obstacles", "start"});
  // spacing_m is the automatic choice's under model: {name: auto}.
  const YAML::Node model = root["model"];
  const bool automatic = model && model.IsMap() && model["name"] && model["name"].IsScalar() && model["name"].Scalar() == "auto";
  for (const char* key : {"textile", "material", "hold"}) requireKey(root, key, "");
  if (!automatic) requireKey(root, "spacing_m", "");
  s.textile = parseTextile(root["textile"]);
  s.material = parseMaterial(root["material"], base_dir);
  s.spacing = positive(root, "spacing_m", s.spacing, "");
  if (const YAML::Node regions = root["pinned_regions"]) {
    checkList(regions, "pinned_regions", kMaxSceneListLength);
    for (const auto& r : regions) s.pinned_regions.push_back(getVec<4>(r, "pinned_regions[]"));
  }
  parseHoldSection(root["hold"], !s.pinned_regions.empty(), s);
  if (const YAML::Node m = root["model"]) parseModel(m, s);
  if (const YAML::Node m = root["simulation"]) parseSimulation(m, s.settings);
  if (const YAML::Node c = root["collision"]) parseCollision(c, s);
  if (const YAML::Node ob = root["obstacles"]) parseObstacles(ob, s.obstacles);
  if (const YAML::Node st = root["start"]) {
    if (!st.IsMap()) fail("'start' must be a map");
    checkKeys(st, "start", {"tilt_deg", "tilt_axis_deg", "heap_folds", "heap_seed", "heap_lift_deg"});
    if (st["heap_folds"]) s.start_heap.folds = getInt(st["heap_folds"], "start.heap_folds");
    if (st["heap_seed"]) {
      const int seed = getInt(st["heap_seed"], "start.heap_seed");
      if (seed < 0) fail("start.heap_seed must be >= 0, got " + std::to_string(seed));
      s.start_heap.seed = static_cast<std::uint64_t>(seed);
    }
    if (st["heap_lift_deg"]) s.start_heap.lift_deg = getReal(st["heap_lift_deg"], "start.heap_lift_deg");
    if (st["tilt_deg"]) s.start_tilt_deg = getReal(st["tilt_deg"], "start.tilt_deg");
    if (st["tilt_axis_deg"]) s.start_tilt_axis_deg = getReal(st["tilt_axis_deg"], "start.tilt_axis_deg");
  }
}

}  // namespace

DrapeSceneSpec parseDrapeSceneYaml(const std::string& text, const std::string& base_dir) {
  const std::string too_large = textSizeError("scene text", text.size(), kMaxYamlDocumentBytes);
  if (!too_large.empty()) fail(too_large);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    fail(std::string("malformed YAML: ") + e.what());
  }
  if (!root.IsMap()) fail("top level must be a map");
  DrapeSceneSpec s;
  try {
    parseSceneRoot(root, base_dir, s);
  } catch (const YAML::Exception& e) {
    fail(std::string("wrong type: ") + e.what());
  } catch (const MaterialError& e) {
    fail(std::string("material: ") + e.what());
  }
  return s;
}

DrapeSceneSpec loadDrapeSceneYaml(const std::string& path) {
  std::string text, error;
  if (!readBoundedTextFile(path, kMaxYamlDocumentBytes, &text, &error)) fail(error);
  const auto slash = path.find_last_of('/');
  return parseDrapeSceneYaml(text, slash == std::string::npos ? "." : path.substr(0, slash));
}

DrapeSceneSpec benchmarkTowelSpec(Real spacing, const std::string& hold, const std::string& model) {
  DrapeSceneSpec s;
  s.textile = presetTextile("towel");
  s.material = Material::cotton();
  s.spacing = spacing;
  s.hold = {HoldPoint{hold, Vec2::Zero()}};
  s.hold_position = Vec3(0, 0, 1.0);
  // The same settling damping for every configuration (it shortens the swinging, not the rest shape)
  // and the definite Jacobian fix, which every implicit configuration needs.
  s.model = settlingModelSpec(model, 4.0);
  s.settings.max_time = 8.0;
  s.settings.dt = 1e-3;
  s.settings.dt_max = 0.02;
  s.settings.error_tolerance = 1e-3;
  return s;
}

void useFastSolverSettings(SimulationSettings& s) {
  s.dt_max = 0.0125;
  s.solver.relative_tolerance = 0.03;
  s.solver.warm_start = true;
}

}  // namespace textile_handling
