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
//  - Members instead of a finer grid (optional, member_samples): where no spacing converges on a hanging
//    scene, the next coarser candidate than the finest plus extra database members (other materials) when its
//    silhouettes agree with the finest's on every sample and the members' work on the samples, added to the
//    coarser base's, stays below the finest candidate's.
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
  /// Members a database build may add instead of the finest spacing when no spacing converges on a hanging
  /// scene (a drape with several equilibria, where a finer grid is not nearer the drapes a robot sees):
  /// each the samples as that member makes them (same hold points, same order as the samples; the search's
  /// model, spacing and settings replace theirs). Tried in this order. Empty (the default): not considered.
  struct MemberSamples {
    std::string name;
    std::vector<DrapeSceneSpec> scenes;
  };
  std::vector<MemberSamples> member_samples;
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

/// The work of one search run, deterministic so that a resumed build repeats the choice: grid nodes times
/// (accepted steps + rejected steps + linear-solver iterations).
Real searchRunWork(Index nodes, long steps, long rejected_steps, long solver_iterations);

struct AutomaticChoice {
  ClothModelSpec model;            ///< the chosen model with the settling options of a build
  std::string model_reason;        ///< why this model
  Real spacing = 0;                ///< [m]
  SimulationSettings settings;     ///< integrator, policy and steps (error tolerance) as chosen
  bool converged = false;          ///< false: no candidate agreed with every finer one; the finest that completes was taken
  /// Members to build besides the base (names of options.member_samples), empty unless the members rule
  /// took a coarser spacing; `members_reason` gives the silhouettes and work it was decided on.
  std::vector<std::string> members;
  std::string members_reason;
  /// The rule's work (searchRunWork) summed over the samples: the finest candidate's, and the coarser base's
  /// plus the taken members' (both 0 when the rule stopped before comparing work: not asked, or silhouettes).
  Real work_finest = 0, work_with_members = 0;
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
/// error_tolerance != reference_error_tolerance); the samples' own is kept when no candidate agrees. Where
/// nothing converged on a hanging scene and options.member_samples is not empty, the members rule runs
/// first: the next coarser candidate than the finest that completes is taken, with the listed members in
/// order as long as (1) every sample completes there and its mean silhouette IoU against the finest is at
/// least min_mean_iou (its named points may lie in another equilibrium), (2) every sample of each taken
/// member completes there, and (3) the work (searchRunWork) of the coarser base and the taken members on
/// the samples stays below the finest's; with no member taken the finest stays. Throws InvalidInputError
/// for no samples, bad options, member samples that do not match the samples, or no candidate that
/// completes on every sample (the message lists each failing run).
AutomaticChoice chooseConfiguration(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options);

/// `spacings` sorted coarse to fine with near-equal values (within 1e-9 relative) kept once, the order in
/// which the search tries candidates.
std::vector<Real> distinctSpacingsCoarseFirst(std::vector<Real> spacings);

/// Up to `count` hold points spread over `candidates` (farthest-point sampling from the first one), for
/// the resolution search of a database build. Shapes: textile-frame points [m].
std::vector<Vec2> spreadSample(const std::vector<Vec2>& candidates, int count);

}  // namespace db
}  // namespace textile_handling
