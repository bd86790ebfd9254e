#include "textile_handling/sim/drape_scene.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
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

Vec2 resolveHold(const TextileOutline& t, const HoldPoint& h) {
  if (h.name.empty()) return h.position;
  for (const auto& np : t.named_points)
    if (np.name == h.name) return np.position;
  std::string known;
  for (const auto& np : t.named_points) known += (known.empty() ? "" : ", ") + np.name;
  throw std::invalid_argument("textile '" + t.name + "' has no named point '" + h.name + "' (known: " + known + ")");
}

}  // namespace

DrapeScene buildDrapeScene(const DrapeSceneSpec& spec) {
  if (spec.model != "particle_kes")
    throw std::invalid_argument("unknown cloth model '" + spec.model + "' (available: particle_kes)");
  if (spec.hold.empty() && spec.pinned_regions.empty())
    throw std::invalid_argument("scene holds nothing: give at least one hold point or pinned region");
  if (!spec.hold_position.allFinite()) throw std::invalid_argument("hold position is not finite");
  if (spec.lift_times.size() != spec.lift_offsets.size())
    throw std::invalid_argument("lift: times and offsets differ in length");
  for (size_t k = 0; k < spec.lift_times.size(); ++k) {
    if (!std::isfinite(spec.lift_times[k]) || !spec.lift_offsets[k].allFinite())
      throw std::invalid_argument("lift: non-finite waypoint");
    if (k > 0 && !(spec.lift_times[k] > spec.lift_times[k - 1]))
      throw std::invalid_argument("lift: waypoint times must increase");
  }
  std::string error;
  if (!validateTextileOutline(spec.textile, &error)) throw std::invalid_argument("textile: " + error);
  if (!spec.material.validate(&error)) throw std::invalid_argument("material: " + error);

  DrapeScene scene;
  scene.spec = spec;
  scene.grid = ParticleGrid::rasterize(spec.textile, spec.spacing, &error);
  if (scene.grid.empty()) throw std::invalid_argument("rasterisation failed: " + error);
  auto model = std::make_unique<ParticleClothModel>(ParticleTopology::fromGrid(scene.grid), spec.material,
                                                    spec.model_options);

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
  scene.x0.resize(3 * n);
  for (Index r = 0; r < n; ++r) {
    const Vec2 q = scene.grid.activePosition(r);
    scene.x0.segment<3>(3 * r) = Vec3(q.x(), q.y(), 0) + scene.textile_to_world;
  }
  scene.v0 = VecX::Zero(3 * n);

  std::vector<char> pinned(n, 0);
  auto pin = [&](Index p) {
    if (pinned[p]) return;
    pinned[p] = 1;
    scene.pins.nodes.push_back(p);
    scene.pins.anchors.push_back(scene.x0.segment<3>(3 * p));
  };
  for (const auto& h : spec.hold) {
    const Index p = scene.grid.nearestActive(resolveHold(spec.textile, h));
    if (scene.hold_particle < 0) scene.hold_particle = p;
    pin(p);
  }
  for (const auto& r : spec.pinned_regions) {
    if (!r.allFinite() || !(r[2] >= r[0]) || !(r[3] >= r[1]))
      throw std::invalid_argument("pinned region must be finite with x0 <= x1 and y0 <= y1");
    const Index before = static_cast<Index>(scene.pins.nodes.size());
    for (Index p = 0; p < n; ++p) {
      const Vec2 q = scene.grid.activePosition(p);
      const Real tol = 1e-9;
      if (q.x() >= r[0] - tol && q.x() <= r[2] + tol && q.y() >= r[1] - tol && q.y() <= r[3] + tol) pin(p);
    }
    if (static_cast<Index>(scene.pins.nodes.size()) == before)
      throw std::invalid_argument("pinned region contains no particle");
  }
  if (scene.hold_particle < 0) scene.hold_particle = scene.pins.nodes.front();
  scene.pins.waypoint_times = spec.lift_times;
  scene.pins.waypoint_offsets = spec.lift_offsets;
  for (const auto& np : spec.textile.named_points)
    scene.named_particles.emplace_back(np.name, scene.grid.nearestActive(np.position));
  scene.model = std::move(model);
  return scene;
}

Real hangingDepth(const DrapeScene& scene, const VecX& x) {
  const Real top = x[3 * scene.hold_particle + 2];
  Real lowest = top;
  for (Index r = 0; r < scene.model->numNodes(); ++r) lowest = std::min(lowest, x[3 * r + 2]);
  return top - lowest;
}

// ---- YAML -------------------------------------------------------------------------------------

namespace {

Real getReal(const YAML::Node& n, const std::string& field) {
  try {
    const Real v = n.as<Real>();
    if (!std::isfinite(v)) throw std::invalid_argument("scene: '" + field + "' is not finite");
    return v;
  } catch (const YAML::Exception&) {
    throw std::invalid_argument("scene: '" + field + "' must be a number");
  }
}

Real positive(const YAML::Node& parent, const char* key, Real fallback, const std::string& where) {
  if (!parent[key]) return fallback;
  const Real v = getReal(parent[key], where + key);
  if (!(v > 0)) throw std::invalid_argument("scene: '" + where + key + "' must be positive");
  return v;
}

// Scalars of other types, with an error naming the field instead of yaml-cpp's "bad conversion".
std::string getString(const YAML::Node& n, const std::string& field) {
  if (!n.IsScalar()) throw std::invalid_argument("scene: '" + field + "' must be a string");
  return n.as<std::string>();
}

int getInt(const YAML::Node& n, const std::string& field) {
  try {
    return n.as<int>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument("scene: '" + field + "' must be an integer");
  }
}

bool getBool(const YAML::Node& parent, const char* key, bool fallback, const std::string& where) {
  if (!parent[key]) return fallback;
  try {
    return parent[key].as<bool>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument("scene: '" + where + key + "' must be true or false");
  }
}

template <int N>
Eigen::Matrix<Real, N, 1> getVec(const YAML::Node& n, const std::string& field) {
  if (!n.IsSequence() || n.size() != N)
    throw std::invalid_argument("scene: '" + field + "' must be a list of " + std::to_string(N) + " numbers");
  Eigen::Matrix<Real, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = getReal(n[i], field);
  return v;
}

HoldPoint parseHold(const YAML::Node& n) {
  HoldPoint h;
  if (n.IsScalar()) {
    h.name = n.as<std::string>();
  } else {
    h.position = getVec<2>(n, "hold.points[]");
  }
  return h;
}

TextileOutline parseTextile(const YAML::Node& n) {
  if (n.IsScalar()) return presetTextile(n.as<std::string>());
  if (!n.IsMap() || !n["outline"]) throw std::invalid_argument("scene: 'textile' must be a preset name or a map with 'outline'");
  TextileOutline t;
  t.name = n["name"] ? getString(n["name"], "textile.name") : "custom";
  for (const auto& v : n["outline"]) t.outline.push_back(getVec<2>(v, "textile.outline[]"));
  if (n["mirror_x"]) {
    t.mirrored = true;
    t.mirror_x = getReal(n["mirror_x"], "textile.mirror_x");
  }
  if (n["named_points"]) {
    for (const auto& it : n["named_points"]) {
      NamedPoint p;
      p.name = getString(it.first, "textile.named_points");
      const YAML::Node& v = it.second;
      if (v.IsMap()) {
        p.position = getVec<2>(v["position"], "textile.named_points." + p.name);
        p.kind = v["kind"] ? getString(v["kind"], "textile.named_points." + p.name + ".kind") : "grasp";
      } else {
        p.position = getVec<2>(v, "textile.named_points." + p.name);
        p.kind = "grasp";
      }
      t.named_points.push_back(p);
    }
  }
  return t;
}

}  // namespace

DrapeSceneSpec parseDrapeSceneYaml(const std::string& text, const std::string& base_dir) {
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(std::string("scene: malformed YAML: ") + e.what());
  }
  if (!root.IsMap()) throw std::invalid_argument("scene: top level must be a map");
  DrapeSceneSpec s;
  try {
    if (root["textile"]) s.textile = parseTextile(root["textile"]);
    if (root["material"]) {
      const std::string m = getString(root["material"], "material");
      if (m == "cotton") {
        s.material = Material::cotton();
      } else {
        const std::string path = (!m.empty() && m[0] == '/') ? m : base_dir + "/" + m;
        s.material = loadMaterialYaml(path);
      }
    }
    s.spacing = positive(root, "spacing_m", s.spacing, "");
    if (const YAML::Node h = root["hold"]) {
      if (h["points"]) {
        for (const auto& p : h["points"]) s.hold.push_back(parseHold(p));
      }
      if (h["position"]) s.hold_position = getVec<3>(h["position"], "hold.position");
      if (h["lift"]) {
        for (const auto& w : h["lift"]) {
          const auto v = getVec<4>(w, "hold.lift[]");
          s.lift_times.push_back(v[0]);
          s.lift_offsets.push_back(v.tail<3>());
        }
      }
    } else {
      s.hold.push_back(HoldPoint{"corner_ul", Vec2::Zero()});
    }
    if (root["pinned_regions"])
      for (const auto& r : root["pinned_regions"]) s.pinned_regions.push_back(getVec<4>(r, "pinned_regions[]"));
    if (const YAML::Node m = root["model"]) {
      if (m["name"]) s.model = getString(m["name"], "model.name");
      if (m["jacobian"]) {
        const std::string j = getString(m["jacobian"], "model.jacobian");
        if (j == "exact") s.model_options.jacobian = JacobianMode::kExact;
        else if (j == "definite_fix") s.model_options.jacobian = JacobianMode::kDefiniteFix;
        else throw std::invalid_argument("scene: 'model.jacobian' must be exact or definite_fix");
      }
      s.model_options.gravity = getBool(m, "gravity", true, "model.");
      s.model_options.drag = getBool(m, "drag", true, "model.");
      s.model_options.shear = getBool(m, "shear", true, "model.");
      s.model_options.bending = getBool(m, "bending", true, "model.");
      if (m["settle_damping_per_s"]) {
        s.model_options.settle_damping = getReal(m["settle_damping_per_s"], "model.settle_damping_per_s");
        if (!(s.model_options.settle_damping >= 0))
          throw std::invalid_argument("scene: 'model.settle_damping_per_s' must be >= 0");
      }
    }
    if (const YAML::Node m = root["simulation"]) {
      SimulationSettings& t = s.settings;
      if (m["integrator"]) {
        const std::string name = getString(m["integrator"], "simulation.integrator");
        try {
          t.integrator = integratorFromString(name);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(std::string("scene: 'simulation.integrator': ") + e.what());
        }
      }
      if (m["policy"]) {
        const std::string name = getString(m["policy"], "simulation.policy");
        try {
          t.policy = stepPolicyFromString(name);
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument(std::string("scene: 'simulation.policy': ") + e.what());
        }
      }
      t.dt = positive(m, "dt_s", t.dt, "simulation.");
      t.dt_min = positive(m, "dt_min_s", t.dt_min, "simulation.");
      t.dt_max = positive(m, "dt_max_s", t.dt_max, "simulation.");
      t.error_tolerance = positive(m, "error_tolerance_m", t.error_tolerance, "simulation.");
      t.max_time = positive(m, "max_time_s", t.max_time, "simulation.");
      t.rest_speed = positive(m, "rest_speed_m_s", t.rest_speed, "simulation.");
      t.rest_mean_speed = positive(m, "rest_mean_speed_m_s", t.rest_mean_speed, "simulation.");
      t.rest_duration = positive(m, "rest_duration_s", t.rest_duration, "simulation.");
      t.max_edge_stretch = positive(m, "max_edge_stretch", t.max_edge_stretch, "simulation.");
      t.solver.relative_tolerance = positive(m, "cg_tolerance", t.solver.relative_tolerance, "simulation.");
      if (m["cg_max_iterations"]) t.solver.max_iterations = getInt(m["cg_max_iterations"], "simulation.cg_max_iterations");
      if (m["trajectory_every"]) t.trajectory_every = getInt(m["trajectory_every"], "simulation.trajectory_every");
      if (t.solver.max_iterations < 1) throw std::invalid_argument("scene: 'simulation.cg_max_iterations' must be >= 1");
      if (t.trajectory_every < 0) throw std::invalid_argument("scene: 'simulation.trajectory_every' must be >= 0");
    }
  } catch (const YAML::Exception& e) {
    throw std::invalid_argument(std::string("scene: wrong type: ") + e.what());
  } catch (const MaterialError& e) {
    throw std::invalid_argument(std::string("scene: material: ") + e.what());
  }
  return s;
}

DrapeSceneSpec loadDrapeSceneYaml(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) throw std::invalid_argument("scene: cannot open " + path);
  std::string text;
  char buf[4096];
  size_t k;
  while ((k = std::fread(buf, 1, sizeof buf, f)) > 0) text.append(buf, k);
  std::fclose(f);
  const auto slash = path.find_last_of('/');
  return parseDrapeSceneYaml(text, slash == std::string::npos ? "." : path.substr(0, slash));
}

}  // namespace textile_handling
