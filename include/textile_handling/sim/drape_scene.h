// A drape scene: which textile, which material, how finely resolved, where it is held, which model
// and which simulation settings. Scenes load from YAML (docs/simulation.md, config/scenes/*.yaml) and
// build into a ready-to-run model + initial state.
#pragma once

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/collision.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/heap_start.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/position_view_pass.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

/// A point to hold: a named point of the textile, or a position in the textile frame [m].
struct HoldPoint {
  std::string name;               ///< named point; empty = use `position`
  Vec2 position = Vec2::Zero();
  std::string label() const;      ///< the name, or "x,y" with millimetre precision
};

/// Obstacles of a scene, in world coordinates (docs/collision.md).
/// How a scene's obstacles act: the post-step position pass ("position", ObstaclePass) or penalty
/// forces inside the model ("penalty", ObstaclePenaltyModel; docs/collision.md).
enum class ObstacleMethod { kPosition, kPenalty };

struct ObstacleSpec {
  ObstacleMethod method = ObstacleMethod::kPosition;
  ObstacleOptions options;  ///< contact distance (the penalty's thickness) and friction, both methods
  Real penalty_stiffness_factor = 1000;  ///< ObstaclePenaltyOptions::stiffness_factor
  Real penalty_damping_ratio = 1;        ///< ObstaclePenaltyOptions::damping_ratio
  Real penalty_stick_speed = 1e-4;       ///< ObstaclePenaltyOptions::stick_speed [m/s]
  std::vector<PlaneObstacle> planes;
  std::vector<BoxObstacle> boxes;
  std::vector<SphereObstacle> spheres;
  bool empty() const { return planes.empty() && boxes.empty() && spheres.empty(); }
};

/// Scene key `model: {name: auto, ...}`: the model, spacing, integrator and time-step policy are left to the
/// automatic choice (chooseConfiguration(), db/automatic_configuration.h, docs/automatic_configuration.md),
/// which a tool runs before it builds the scene. buildDrapeScene() refuses a spec that still asks for it.
struct AutomaticModelRequest {
  bool requested = false;
  std::string question = "none";          ///< model.question: none | pull_out | sliding | tearing
  std::vector<Real> spacings;             ///< model.spacings_m: candidates [m] (empty = the choice's default)
  Real named_point_tolerance_m = 0.03;    ///< model.named_point_tolerance_m
  Real min_mean_iou = 0.85;               ///< model.min_mean_iou
};

struct DrapeSceneSpec {
  TextileOutline textile = presetTextile("towel");
  Material material = Material::cotton();
  Real spacing = 0.01;                         ///< particle grid spacing d [m]
  std::vector<HoldPoint> hold;                 ///< held points (each pins its nearest particle)
  Vec3 hold_position = Vec3(0, 0, 1.0);        ///< world position of the first held point [m]
  /// Axis-aligned rectangles (x0, y0, x1, y1) in the textile frame whose particles are pinned,
  /// e.g. the 50x50 cm table of the thesis's tablecloth validation.
  std::vector<Eigen::Matrix<Real, 4, 1>> pinned_regions;
  /// Starting pose (scene key start: {tilt_deg, tilt_axis_deg}): the flat sheet is released rotated by
  /// start_tilt_deg (|.| <= 90) about the horizontal line through the first held point whose direction
  /// is start_tilt_axis_deg from the textile's x axis (right-handed about that direction). 0 = the
  /// thesis's flat horizontal sheet. Another start can lead to another equilibrium (docs/simulation.md).
  Real start_tilt_deg = 0;
  Real start_tilt_axis_deg = 0;
  /// Picked from a heap (scene keys start: {heap_folds, heap_seed, heap_lift_deg}): the sheet folded
  /// heap_folds times along random lines and lifted by the held point (heap_start.h), layers
  /// max(d, 3 cm) apart (creases of radius 1.5 cm or more: a heap is loose); applied before the tilt. folds = 0: no heap start.
  HeapStart start_heap;
  std::vector<Real> lift_times;                ///< waypoints of the holder offset [s]
  std::vector<Vec3> lift_offsets;              ///< [m]
  /// Cloth model and its options (scene key model:; the names and keys of ClothModelRegistry).
  ClothModelSpec model;
  AutomaticModelRequest automatic;  ///< model: {name: auto}; `model` then holds the default until chosen
  SimulationSettings settings;
  /// Self-collision after every step (scene key collision.self: off | v1 | v2 | v3). Off by default:
  /// a scene gets no more model than it needs; the demo scene and the database builder turn v3 on.
  bool self_collision = false;
  SelfCollisionOptions collision;
  ObstacleSpec obstacles;
};

/// A built scene. The initial pose is the flat horizontal sheet at the holder's height, released at
/// rest (thesis decision 10): textile frame (x, y) maps to world (x, y, 0) + shift.
struct DrapeScene {
  DrapeSceneSpec spec;
  ParticleGrid grid;
  std::unique_ptr<ClothModel> model;
  PinnedNodes pins;
  VecX x0, v0;
  Index hold_particle = -1;                             ///< particle of the first held point
  std::vector<std::pair<std::string, Index>> named_particles;  ///< named points -> particles
  Vec3 textile_to_world = Vec3::Zero();                 ///< world = (x, y, 0) + this
  /// Post-step passes built from spec.obstacles and spec.self_collision (null when not used).
  std::unique_ptr<ObstaclePass> obstacle_pass;
  std::unique_ptr<SelfCollisionPass> self_collision_pass;
  std::unique_ptr<PostStepPassChain> pass_chain;  ///< obstacles first, then self-collision
  /// For models with more than 3 DOFs per node: the passes above, run on the node positions.
  std::unique_ptr<PositionViewPass> position_view;
  /// The pass to give DrapeSimulation::setPostStepPass() (its wall time and events are reported in
  /// RunResult::post_step_ms / post_step_events); null when the scene has no collision handling.
  PostStepPass* postStepPass() const;
  /// Triangulation for countIntersectingTrianglePairs() on the scene's grid.
  ClothTriangles triangles() const;
};

/// Builds a scene. Bad input throws SceneError (a scene field), ClothModelError (the model or one of its
/// options) or MemoryBudgetError, all SimError (sim_errors.h), with a message naming the field.
DrapeScene buildDrapeScene(const DrapeSceneSpec& spec);
/// A cloth model buildDrapeScene() knows (registered in ClothModelRegistry).
bool isClothModelName(const std::string& name);

/// Parses a scene from YAML text; relative material paths resolve against `base_dir`.
/// Throws SceneError naming the offending field (key path).
DrapeSceneSpec parseDrapeSceneYaml(const std::string& text, const std::string& base_dir = ".");
DrapeSceneSpec loadDrapeSceneYaml(const std::string& path);

/// Vertical extent of the textile below its first held point [m]; `positions` are the 3N node
/// positions (DrapeSimulation::positions()).
Real hangingDepth(const DrapeScene& scene, const VecX& positions);

/// The benchmark's towel scene (drape_bench, docs/simulation.md): the 64 x 46 cm cotton towel at spacing
/// `spacing` held at the named point `hold` 1 m up, the model `model` with settlingModelSpec() options
/// (settle damping 4/s, the definite-fix Jacobian where the model has one), 8 s cap, error-controlled
/// steps (tolerance 1 mm, dt_max 20 ms).
DrapeSceneSpec benchmarkTowelSpec(Real spacing, const std::string& hold, const std::string& model = "particle_kes");
/// The recommended fast semi-implicit settings (the demo scene's): dt_max 12.5 ms, CG tolerance 0.03
/// with warm start.
void useFastSolverSettings(SimulationSettings& s);

}  // namespace textile_handling
