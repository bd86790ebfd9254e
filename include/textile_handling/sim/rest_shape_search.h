// The rest shape of a drape scene (the static equilibrium a hanging textile settles in), by one of two
// methods:
//  - kDynamic: the scene's simulation run until its rest detection fires (the reference);
//  - kQuasiStatic: the dynamics only choose the equilibrium's basin, a Newton solve finishes it:
//      1. a dynamic run until the textile has nearly settled (settle_* thresholds), on a coarse particle
//         grid of the same textile when coarse_spacing allows (the swing and fall cost little there);
//      2. on the coarse grid, the static equilibrium near that state (solveStaticEquilibrium);
//      3. prolongation to the scene's grid (prolongPositions), shifted so the held particle sits on
//         its pin, its edge lengths brought into a band around their rest lengths (relaxEdgeLengths),
//         and the static equilibrium there.
//    If a stage fails (the finish does not converge, the coarse run diverges), the scene falls back to
//    the dynamic method, and the result says so.
// The quasi-static method needs static pins and no post-step pass (self-collision, obstacles): Newton
// iterations do not see collisions. Scenes with either always run kDynamic (docs/simulation.md).
#pragma once

#include <string>

#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/edge_length_relaxation.h"
#include "textile_handling/sim/static_equilibrium.h"

namespace textile_handling {

enum class RestShapeMethod { kDynamic, kQuasiStatic };
std::string toString(RestShapeMethod m);
/// Parses "dynamic", "quasi_static"; throws SimError otherwise.
RestShapeMethod restShapeMethodFromString(const std::string& s);

/// How the quasi-static method finishes on the scene's grid after a coarse level.
enum class FineFinish {
  kNewton,   ///< solveStaticEquilibrium from the prolonged coarse equilibrium
  kDynamic,  ///< the scene's dynamics and rest detection from the prolonged coarse equilibrium, at rest
};

struct RestShapeSettings {
  RestShapeMethod method = RestShapeMethod::kDynamic;
  /// Particle spacing of the coarse level [m]; used when it is at least 1.5 times the scene's spacing
  /// (otherwise the dynamic phase runs on the scene's own grid). 0 = never.
  Real coarse_spacing = 0.02;
  /// The dynamic phase ends when, for settle_duration, every particle is slower than settle_speed and
  /// the mean speed sqrt(2 E_kin / M) is below settle_mean_speed (the scene's rest detection with
  /// these thresholds), or at the scene's max_time.
  Real settle_speed = 0.05;        ///< [m/s]
  Real settle_mean_speed = 0.01;   ///< [m/s]
  Real settle_duration = 0.1;      ///< [s]
  /// Local error tolerance of the dynamic phase [m] (error-controlled steps); 0 = the scene's.
  Real settle_error_tolerance = 0;
  StaticEquilibriumSettings finish;
  FineFinish fine_finish = FineFinish::kDynamic;
  /// Whether stage 2 (the coarse static equilibrium) runs. With the dynamic fine finish the fine run settles
  /// the prolonged shape anyway; on the towel's 1 cm level the Newton finish stops at its 60 iterations
  /// unconverged and costs about a third of the whole method (docs/simulation.md).
  bool coarse_static_finish = true;
  /// After prolongation, grid edges outside [min, max] times their rest length are brought into that band
  /// (relaxEdgeLengths, the pins fixed, up to 200 sweeps): a folded coarse cell squeezes fine edges, and
  /// the particle model's forces there stopped the fine run at its first step. min in (0, 1] (0 = off),
  /// max >= 1.
  Real prolonged_min_edge_ratio = 0.9;
  Real prolonged_max_edge_ratio = 1.1;

  /// Canonical text of the settings (empty for kDynamic), for database parameter texts.
  std::string text() const;
  /// Throws SimError naming the field if a value is out of range.
  void validate() const;
};

struct RestShapeResult {
  bool rest_reached = false;
  bool diverged = false;
  std::string failure;             ///< why no rest shape (empty when rest_reached)
  /// "dynamic", "quasi_static", or "dynamic (quasi-static finish failed: REASON)".
  std::string method_used;
  bool coarse_level = false;       ///< the dynamic phase ran on the coarse grid
  VecX state;                      ///< the scene model's state at the end (numDofs())
  VecX positions;                  ///< its node positions (3N) [m]
  RunResult dynamic;               ///< the dynamic phase (or the whole dynamic run)
  StaticEquilibriumResult coarse_finish, finish;
  RunResult finish_run;            ///< the fine dynamic finish (FineFinish::kDynamic)
  EdgeRelaxationResult relaxation; ///< the prolonged shape's edge-length band (coarse level only)
  double wall_seconds = 0;         ///< everything, scene building of the coarse level included
  long steps = 0;                  ///< accepted dynamic steps (coarse and fine)
  long rejected_steps = 0;
  Real sim_time = 0;               ///< simulated time of the dynamic phase [s]
};

/// The rest shape of `scene` (built from its spec by buildDrapeScene; its model's internal state is
/// used and advanced). `settings` chooses the method; see the file comment.
RestShapeResult findRestShape(DrapeScene& scene, const RestShapeSettings& settings);

/// True if the quasi-static method applies to `scene` (static pins, no post-step pass, hold points
/// only); otherwise findRestShape runs kDynamic.
bool quasiStaticApplies(const DrapeScene& scene);

}  // namespace textile_handling
