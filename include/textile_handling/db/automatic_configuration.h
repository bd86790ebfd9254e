// Automatic choice of cloth model, resolution, integrator and time-step policy for a scene or a database
// build (scene `model: auto`, `drape_db build --auto`; docs/automatic_configuration.md).
//
//  - Model, by what the scene asks: the yarn model only for yarn-scale questions (pull-out, sliding,
//    tearing); Choi-Ko where compression and buckling dominate (a supported scene: pinned regions or
//    obstacles, e.g. a table drape) or where the particle model fails at the chosen settings; otherwise
//    the particle model.
//  - Integrator and policy: semi_implicit with error-controlled steps (the speed/accuracy benchmark's front
//    on every scene it completes; bench/results/*-speed-accuracy).
//  - Resolution: the coarsest candidate spacing whose recognition-relevant output agrees with every finer
//    candidate on every sampled hold point: named points (corners, grasp points) within a distance,
//    silhouettes at the database's frame and views above a mean IoU (measureDrapeDifference(), turned about
//    the hold axis for one-point holds).
//  - Step tolerance (optional, error_tolerance_factors): at the chosen spacing, the loosest of the scene's
//    step error tolerance times each factor whose drapes agree with the scene's own tolerance on every
//    sample, by the same measure.
// The choice and its evidence (every comparison made) are returned, printed by the tools and stored in the
// database build's parameter text.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "textile_handling/db/database_errors.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

/// Questions only the yarn-level model answers.
enum class YarnScaleQuestion { kNone, kPullOut, kSliding, kTearing };
std::string toString(YarnScaleQuestion q);
/// Parses "none", "pull_out", "sliding", "tearing"; throws InvalidInputError naming the value otherwise.
YarnScaleQuestion yarnScaleQuestionFromString(const std::string& s);

struct AutomaticChoiceOptions {
  /// Candidate spacings [m]; tried coarse to fine (sorted here), at least two, each finite and > 0.
  std::vector<Real> spacings = {0.03, 0.02, 0.015, 0.01, 0.0075};
  Real named_point_tolerance_m = 0.03;  ///< largest named-point distance to any finer candidate [m]
  Real min_mean_iou = 0.85;             ///< smallest mean silhouette IoU against any finer candidate
  YarnScaleQuestion question = YarnScaleQuestion::kNone;
  /// Looser step error tolerances to try at the chosen spacing, as multiples (each finite and > 1) of the
  /// samples' own `settings.error_tolerance`; the loosest whose drapes agree with the samples' own tolerance
  /// on every sample is taken. Empty (the default): the samples' tolerance is kept (`drape_db build --auto
  /// --auto-step-factors 3` tries 3; docs/automatic_configuration.md).
  std::vector<Real> error_tolerance_factors;
  /// Silhouettes as the database stores them.
  vision::ViewSet views;
  vision::CanonicalFrame frame;
  /// Called with one line per simulation run (for the tools' terminal output).
  std::function<void(const std::string& line)> on_progress;
  /// Throws InvalidInputError naming the field.
  void validate() const;
};

/// One comparison of the resolution search: a sampled hold point at `spacing` against `finer_spacing`.
struct AutomaticChoiceEvidence {
  std::string hold;                ///< HoldPoint::label() of the sample
  std::string model;
  Real spacing = 0, finer_spacing = 0;
  /// Step error tolerances [m] of the two runs: equal in the resolution search; in the tolerance search the
  /// looser candidate and the samples' own.
  Real error_tolerance = 0, reference_error_tolerance = 0;
  std::string status;              ///< "compared", or why not ("diverged at ...", "not at rest", ...)
  Real named_point_distance = 0;   ///< [m]
  Real max_node_distance = 0;      ///< [m]
  Real mean_iou = 0;
  Real wall_s = 0;                 ///< both runs of the comparison [s] (each run is simulated once and reused)
  bool agrees = false;
};

struct AutomaticChoice {
  ClothModelSpec model;            ///< the chosen model with the settling options of a build
  std::string model_reason;        ///< why this model
  Real spacing = 0;                ///< [m]
  SimulationSettings settings;     ///< integrator, policy and steps (error tolerance) as chosen
  bool converged = false;          ///< false: no candidate agreed with every finer one; the finest that completes was taken
  std::vector<AutomaticChoiceEvidence> evidence;
  Real search_wall_s = 0;          ///< wall time of the whole search [s]
  /// Multi-line report: the choice, the reason, the tolerances and one line per comparison.
  std::string text() const;
  /// The choice applied to a scene spec (model, spacing, settings).
  void applyTo(DrapeSceneSpec& spec) const;
};

/// Chooses for the scenes `samples` (the same textile and material, one scene per sampled hold point; their
/// model, spacing and integrator settings are ignored, the rest of each spec is kept). Every simulation
/// runs to rest with the chosen settings; a sample that fails or does not reach rest at a spacing counts
/// as disagreement, and a particle model that diverges switches the search to Choi-Ko. If no candidate
/// agrees with every finer one, the finest candidate that completes on every sample is taken. Then, with
/// options.error_tolerance_factors, the step tolerance is searched at that spacing (evidence rows with
/// error_tolerance != reference_error_tolerance); the samples' own is kept when no candidate agrees. Throws
/// InvalidInputError for no samples, bad options, or no candidate that completes on every sample (the
/// message lists each failing run).
AutomaticChoice chooseConfiguration(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options);

/// `spacings` sorted coarse to fine with near-equal values (within 1e-9 relative) kept once, the order in
/// which the search tries candidates.
std::vector<Real> distinctSpacingsCoarseFirst(std::vector<Real> spacings);

/// Up to `count` hold points spread over `candidates` (farthest-point sampling from the first one), for
/// the resolution search of a database build. Shapes: textile-frame points [m].
std::vector<Vec2> spreadSample(const std::vector<Vec2>& candidates, int count);

}  // namespace db
}  // namespace textile_handling
