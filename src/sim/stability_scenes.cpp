#include "textile_handling/sim/stability_scenes.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>

#include "textile_handling/sim/collision_obstacles.h"
#include "textile_handling/sim/position_view_pass.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

AnchoredClothModel::AnchoredClothModel(ClothModel& inner, std::vector<Index> nodes, std::vector<Vec3> anchors,
                                       Real stiffness)
    : inner_(inner), nodes_(std::move(nodes)), anchors_(std::move(anchors)), k_(stiffness) {
  if (nodes_.size() != anchors_.size()) throw SimError("AnchoredClothModel: nodes and anchors differ in length");
  if (!(k_ >= 0) || !std::isfinite(k_)) throw SimError("AnchoredClothModel: stiffness must be finite and >= 0");
  for (Index p : nodes_)
    if (p < 0 || p >= inner_.numNodes()) throw SimError("AnchoredClothModel: node out of range");
}

ForceReport AnchoredClothModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const ForceReport rep = inner_.computeForces(x, v, f, jac);
  const BlockPattern& p = inner_.jacobianPattern();
  const int b = inner_.dofsPerNode();  // a node's first three DOFs are its position
  for (size_t k = 0; k < nodes_.size(); ++k) {
    f.segment<3>(b * nodes_[k]) -= k_ * (x.segment<3>(b * nodes_[k]) - anchors_[k]);
    if (jac) {
      Real* block = jac->dfdx.block(p.diagonal(nodes_[k]));
      for (int c = 0; c < 3; ++c) block[c * b + c] -= k_;
    }
  }
  return rep;
}

Real AnchoredClothModel::potentialEnergy(const VecX& x) const {
  Real e = inner_.potentialEnergy(x);
  const int b = inner_.dofsPerNode();
  for (size_t k = 0; k < nodes_.size(); ++k) e += 0.5 * k_ * (x.segment<3>(b * nodes_[k]) - anchors_[k]).squaredNorm();
  return e;
}

std::string toString(CompressionScene s) {
  return s == CompressionScene::kPushedEdges ? "pushed_edges" : "lowered_onto_table";
}

CompressionScene compressionSceneFromString(const std::string& s) {
  if (s == "pushed_edges") return CompressionScene::kPushedEdges;
  if (s == "lowered_onto_table") return CompressionScene::kLoweredOntoTable;
  throw SimError("unknown compression scene '" + s + "' (expected pushed_edges or lowered_onto_table)");
}

namespace {

// Deterministic pseudo-random number in [-1, 1] from an integer (splitmix64), platform independent.
Real hashNoise(std::uint64_t k) {
  std::uint64_t z = k + 0x9E3779B97F4A7C15ull;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  z ^= z >> 31;
  return 2.0 * static_cast<Real>(z >> 11) / static_cast<Real>(1ull << 53) - 1.0;
}

Real rmsSpeed(const ClothModel& model, const VecX& v) {
  const VecX& m = model.massPerDof();
  const Real ke = 0.5 * (m.array() * v.array().square()).sum();
  return std::sqrt(2 * ke / std::max(m.sum() / model.dofsPerNode(), 1e-300));
}

}  // namespace

StabilityResult runCompressionScene(const CompressionSceneSpec& sc, const StabilityRunSpec& run) {
  if (!(sc.side > 0) || !(sc.spacing > 0) || !(sc.spacing < sc.side) || !(sc.hold_time >= 0) ||
      !std::isfinite(sc.perturbation) || !std::isfinite(sc.noise) || !(sc.push_time > 0) || !(sc.lower_time > 0) || !(sc.table_gap >= 0) ||
      !(sc.table_friction >= 0) || !(sc.anchor_stiffness > 0))
    throw SimError("compression scene: sizes and times must be positive");
  if (!(run.dt > 0) || !std::isfinite(run.dt)) throw SimError("stability run: dt must be positive");

  TextileOutline outline;
  outline.name = "square";
  outline.outline = {Vec2(0, 0), Vec2(sc.side, 0), Vec2(sc.side, sc.side), Vec2(0, sc.side)};
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(outline, sc.spacing, &error);
  if (grid.empty()) throw SimError("compression scene: " + error);
  const ParticleTopology topo = ParticleTopology::fromGrid(grid);
  const Index n = grid.numActive();
  const bool pushed = sc.scene == CompressionScene::kPushedEdges;
  const Real zeta = run.damping ? run.damping_per_s : 0.0;

  ClothModelSpec model_spec = run.model;
  const ClothModelDescriptor& descriptor = ClothModelRegistry::instance().find(model_spec.name);
  if (descriptor.hasOptionKey("settle_damping_per_s")) model_spec.set("settle_damping_per_s", zeta);
  if (pushed && descriptor.hasOptionKey("gravity")) model_spec.set("gravity", sc.push_gravity);
  std::unique_ptr<ClothModel> model = ClothModelRegistry::instance().create(model_spec, topo, run.material);

  // Initial pose with the out-of-plane perturbation: a smooth first mode plus pseudo-random noise.
  VecX positions0(3 * n);
  for (Index r = 0; r < n; ++r) {
    const Vec2 q = grid.activePosition(r) - grid.origin();
    const Real mode = pushed ? std::sin(kPi * q.x() / sc.side) : std::sin(kPi * q.y() / sc.side);
    const Real off =
        sc.spacing * (sc.perturbation * mode + sc.noise * hashNoise(static_cast<std::uint64_t>(r)));
    if (pushed) {
      positions0.segment<3>(3 * r) = Vec3(q.x(), q.y(), off);  // horizontal sheet at z = 0
    } else {
      positions0.segment<3>(3 * r) = Vec3(q.x(), off, sc.table_gap + q.y());  // vertical sheet above the table
    }
  }
  // Positions into the position DOFs; a model's further DOFs (yarn sliding coordinates) start at 0.
  VecX state0 = VecX::Zero(model->numDofs());
  model->setPositions(positions0, state0);
  const VecX v0 = VecX::Zero(model->numDofs());

  PinnedNodes pins;
  std::vector<Index> anchored;
  std::vector<Vec3> anchors;
  Real end_time = 0;
  const Index last_col = grid.cols() - 1, last_row = grid.rows() - 1;
  for (Index r = 0; r < n; ++r) {
    const Index i = grid.compactRows()[r], j = grid.compactCols()[r];
    if (pushed) {
      if (j == last_col) {
        pins.nodes.push_back(r);
        pins.anchors.push_back(positions0.segment<3>(3 * r));
      } else if (j == 0) {
        anchored.push_back(r);
        anchors.push_back(positions0.segment<3>(3 * r));
      }
    } else if (i == last_row) {
      pins.nodes.push_back(r);
      pins.anchors.push_back(positions0.segment<3>(3 * r));
    }
  }
  // The holder follows a smoothstep profile tau^2 (3 - 2 tau) (starts and stops without a jump in
  // velocity), sampled at kWaypoints + 1 piecewise-linear waypoints.
  const Real travel_time = pushed ? sc.push_time : sc.lower_time;
  const Vec3 travel = pushed ? Vec3(-sc.push_fraction * sc.side, 0, 0)
                             : Vec3(0, 0, -(sc.table_gap + sc.lower_fraction * sc.side));
  constexpr int kWaypoints = 20;
  for (int k = 0; k <= kWaypoints; ++k) {
    const Real tau = static_cast<Real>(k) / kWaypoints;
    pins.waypoint_times.push_back(tau * travel_time);
    pins.waypoint_offsets.push_back(tau * tau * (3 - 2 * tau) * travel);
  }
  end_time = travel_time + sc.hold_time;

  std::unique_ptr<AnchoredClothModel> anchored_model;
  ClothModel* sim_model = model.get();
  if (!anchored.empty()) {
    anchored_model = std::make_unique<AnchoredClothModel>(*model, anchored, anchors, sc.anchor_stiffness);
    sim_model = anchored_model.get();
  }

  SimulationSettings settings;
  settings.integrator = run.integrator;
  settings.solver = run.solver;
  settings.policy = StepPolicy::kFixed;
  settings.dt = run.dt;
  settings.dt_min = std::min(settings.dt_min, run.dt);
  settings.dt_max = std::max(settings.dt_max, run.dt);
  settings.max_time = end_time;
  settings.rest_min_time = end_time + 1;  // never stop early at rest
  settings.max_speed = run.max_rms_speed;
  settings.max_edge_stretch = run.max_edge_stretch;
  if (!(run.max_wall_time >= 0)) throw SimError("stability run: max_wall_time must be >= 0");

  DrapeSimulation sim(*sim_model, pins, settings, state0, v0);
  std::unique_ptr<ObstaclePass> table;
  std::unique_ptr<PositionViewPass> table_on_positions;  // the table pass on the node positions (> 3 DOFs)
  if (!pushed) {
    ObstacleOptions oo;
    oo.friction = sc.table_friction;
    table = std::make_unique<ObstaclePass>(n, pins, oo);
    PlaneObstacle floor;
    floor.point = Vec3::Zero();
    floor.normal = Vec3::UnitZ();
    table->addPlane(floor);
    if (model->dofsPerNode() == 3) {
      sim.setPostStepPass(table.get());
    } else {
      table_on_positions = std::make_unique<PositionViewPass>(*table, *model);
      sim.setPostStepPass(table_on_positions.get());
    }
  }

  StabilityResult res;
  res.end_time = end_time;
  res.nodes = n;
  const Real chunk = std::max(run.dt, 0.01);
  RunResult rr;
  const auto wall_start = std::chrono::steady_clock::now();
  while (sim.time() < end_time - 1e-12) {
    rr = sim.run(std::min(sim.time() + chunk, end_time));
    if (rr.diverged) break;
    if (run.max_wall_time > 0 &&
        std::chrono::duration<Real>(std::chrono::steady_clock::now() - wall_start).count() > run.max_wall_time) {
      res.wall_cap_reached = true;
      break;
    }
    res.peak_rms_speed = std::max(res.peak_rms_speed, rmsSpeed(*model, sim.velocities()));
    res.peak_edge_stretch = std::max(res.peak_edge_stretch, model->maxEdgeStretch(sim.state()));
  }
  res.stable = !rr.diverged && sim.time() >= end_time - 1e-9;
  res.reason = rr.diverged ? rr.divergence_reason : "";
  res.sim_time = sim.time();
  res.steps = rr.steps;
  res.solver_iterations = rr.solver_iterations;
  res.wall_time = rr.wall_time;
  res.obstacle_events = rr.post_step_events;
  res.final_rms_speed = rmsSpeed(*model, sim.velocities());
  Real zmin = std::numeric_limits<Real>::infinity();
  for (Index r = 0; r < n; ++r) zmin = std::min(zmin, sim.positions()[3 * r + 2]);
  res.final_min_z = zmin;
  res.grid = grid;
  res.final_positions = sim.positions();
  return res;
}

}  // namespace textile_handling
