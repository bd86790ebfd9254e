// Speed against accuracy of every cloth model x integrator x resolution on the same scenes (issue 20,
// item 4): each configuration runs a scene to rest (or to the end of its motion), and its final shape is
// compared with a fine reference by measureDrapeDifference() (node and named-point distances on the finer
// grid, silhouette IoU). Used by bench/speed_accuracy_bench.cpp; docs/speed_accuracy.md.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "textile_handling/db/drape_difference.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

/// The benchmark's scenes.
///  - towel_corner / towel_edge: the 64 x 46 cm towel hung 1 m up by a corner / the middle of a short side,
///    released flat, run to rest (benchmarkTowelSpec(): settle damping 4/s, 8 s cap).
///  - square_corner: the 30 x 30 cm square hung by a corner (the sheet of the material fit's comparison).
///  - small_square_corner: a 10 x 10 cm square hung by a corner, small enough for the yarn model at the
///    1 mm spacing at which its drape has converged (docs/yarn_model.md, "In scenes: yarn bundles").
///  - small_sheet_edge: a 16 x 8 cm sheet hung by the middle of a short side, the second sheet of that size
///    (another aspect and another kind of hold) for checking a fitted material.
///  - table_drape: a 48 x 48 cm cloth laid flat over a 24 x 24 cm table (its centre pinned), run to rest;
///    both sizes are whole multiples of 3, 2, 1.5, 1 and 0.75 cm, so every grid has the same cloth and table.
///  - pushed_edges: the 30 x 30 cm compression scene of stability_scenes.h: one edge pushed 12 cm towards
///    the other in 1 s, held 1 s; fixed steps (the scene's design), gravity off.
enum class AccuracyScene { kTowelCorner, kTowelEdge, kSquareCorner, kSmallSquareCorner, kSmallSheetEdge, kTableDrape, kPushedEdges };
std::string toString(AccuracyScene s);
/// Parses the names above; throws std::invalid_argument listing them.
AccuracyScene accuracySceneFromString(const std::string& s);
std::vector<AccuracyScene> allAccuracyScenes();

/// A model as the benchmark runs it: registry name, extra option keys (weave=plain) and material.
struct AccuracyModel {
  std::string label;  ///< for rows and charts (e.g. "particle_kes" or "particle_kes fitted")
  ClothModelSpec spec;
  Material material = Material::cotton();
};

/// One configuration of a scene.
struct AccuracyConfig {
  AccuracyModel model;
  IntegratorType integrator = IntegratorType::kSemiImplicitEuler;
  Real spacing = 0.01;  ///< [m]
};

/// The time-step settings each integrator runs with (docs/speed_accuracy.md): semi_implicit and
/// backward_euler_newton error-controlled at 1 mm (semi_implicit with CG 0.03, Newton with conjugate residuals
/// to 1e-2, both warm-started); the explicit
/// rk4 and block_diagonal error-controlled at 10 um. The pushed-edges scene uses fixed steps instead: 5 ms
/// for the implicit integrators, 0.2 ms for the explicit ones. `reference`: semi_implicit at 0.1 mm error
/// tolerance with CG 1e-6 (pushed edges: fixed 1 ms).
struct AccuracyRunLimits {
  Real max_wall_s = 60;  ///< wall-clock cap of one run [s]; a capped run is a failure
  Real reference_max_wall_s = 600;  ///< the same for a reference run
  /// Simulated-time cap of the drape scenes [s] (0 = the scene's own, 8 s): a sheet still moving at the
  /// cap ends as "time_cap".
  Real max_sim_time_s = 0;
};

/// The outcome of one run.
struct AccuracyRun {
  /// "rest" (hanging/table scene at rest), "end" (pushed edges ran to its end), "time_cap" (not at rest by
  /// the scene's simulated-time cap; shape still compared), "diverged", "wall_cap", "error".
  std::string status;
  std::string note;   ///< divergence reason or error text
  bool failed() const { return status == "diverged" || status == "wall_cap" || status == "error"; }
  Real wall_s = 0;
  long steps = 0;
  Real sim_time = 0;
  Index nodes = 0;
  ParticleGrid grid;             ///< textile frame
  VecX positions;                ///< final node positions, 3 x nodes [m]
  Vec3 view_centre = Vec3::Zero();  ///< world point at the silhouettes' hold position
  std::vector<Vec2> named_points;   ///< textile frame [m]
  bool held_at_one_point = false;   ///< compared after the best turn about the hold axis (align_yaw)
  db::DrapeDifferenceOptions differenceOptions() const;
};

/// The drape scene of a configuration, with the integrator's settings above (not for pushed_edges, which
/// is a compression scene: throws std::invalid_argument).
DrapeSceneSpec accuracyDrapeSpec(AccuracyScene scene, const AccuracyConfig& config);

/// Which rows of one scene lie on the speed/accuracy front: `x` cost (> 0), `y` error (>= 0), NaN for
/// failed rows. Row i is on the front when no row is at most as costly and at most as wrong, and better in
/// one. Shapes: x, y of equal length; the result has the same length.
std::vector<bool> speedAccuracyFront(const std::vector<Real>& x, const std::vector<Real>& y);
/// How far row `row` lies from the front: the largest factor f - 1 such that some row is better by at least
/// f in both cost and error (0 on the front; 0.1 = a row exists that is 10 % cheaper and 10 % more accurate).
Real frontMargin(const std::vector<Real>& x, const std::vector<Real>& y, std::size_t row);

/// Runs one configuration (or, `reference` = true, the scene's reference settings for config.model at
/// config.spacing; config.integrator is then ignored). Never throws for a failed simulation: the status
/// says so. Bad configurations (unknown model options, a spacing the scene cannot take) come back as
/// status "error" with the message.
AccuracyRun runAccuracyScene(AccuracyScene scene, const AccuracyConfig& config, const AccuracyRunLimits& limits,
                             bool reference = false);

}  // namespace textile_handling
