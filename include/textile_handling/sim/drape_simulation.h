// Runs a cloth model with an integrator, a time-step policy, pinned nodes, rest detection, divergence
// detection, an optional post-step pass (self-collision, obstacles), trajectory output and
// save/resume. One object per simulation run; not thread-safe, but many can run in parallel.
#pragma once

#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/integrators.h"

namespace textile_handling {

enum class StepPolicy {
  kFixed,            ///< constant dt; a failed step is a divergence
  kThesis,           ///< the thesis rule on the moved-distance norm (thesis 4.5), see docs/simulation.md
  kErrorControlled,  ///< local error estimate against a tolerance, with step rejection
};
std::string toString(StepPolicy p);
/// Parses "fixed", "thesis", "error"; throws std::invalid_argument otherwise.
StepPolicy stepPolicyFromString(const std::string& s);

struct SimulationSettings {
  IntegratorType integrator = IntegratorType::kSemiImplicitEuler;
  SolverSettings solver;
  StepPolicy policy = StepPolicy::kErrorControlled;
  Real dt = 1e-3;                 ///< initial (or fixed) step [s]
  Real dt_min = 1e-7;             ///< below this an adaptive run gives up: divergence [s]
  Real dt_max = 2e-2;             ///< [s]
  Real error_tolerance = 1e-4;    ///< local position error per step for kErrorControlled [m]
  Real max_time = 10.0;           ///< simulated-time cap [s]
  // Rest detection: kinetic energy per unit mass and max speed below thresholds for rest_duration.
  Real rest_speed = 5e-3;         ///< max particle speed [m/s]
  Real rest_mean_speed = 1e-3;    ///< sqrt(2 E_kin / M) [m/s]
  Real rest_duration = 0.2;       ///< [s]
  Real rest_min_time = 0.0;       ///< rest is not declared before this simulated time [s]
  // Divergence detection.
  Real max_edge_stretch = 3.0;    ///< current/rest edge length
  Real max_speed = 50.0;          ///< RMS speed bound [m/s]
  // With static pins, kinetic + gravitational energy above the initial total energy (+1 % of
  // M g extent) is also a divergence: energy was created.
  int trajectory_every = 0;       ///< store a frame every k accepted steps (0 = off)
  /// Wall-time cap of one run() call [s] (0 = none): run() returns with wall_cap_reached, neither at
  /// rest nor diverged; a later run() continues. For benchmarks and services that must answer.
  Real max_wall_time = 0;
  /// Memory budget of this simulation [bytes], a property of the machine and never read from scene
  /// files; 0 = half of physical memory. buildDrapeScene() refuses scenes whose estimate exceeds it
  /// (memory_budget.h).
  std::size_t memory_budget_bytes = 0;
};

struct RunResult {
  bool rest_reached = false;
  bool diverged = false;
  std::string divergence_reason;  ///< empty unless diverged
  Real divergence_time = 0;       ///< simulated time of the divergence [s]
  Real sim_time = 0;              ///< simulated time at the end [s]
  long steps = 0;                 ///< accepted steps
  long rejected_steps = 0;
  long solver_iterations = 0;
  /// Newton iterations (linear solves) of backward_euler_newton steps, rejected steps included; counted
  /// since the simulation was made or resumed (not part of a saved state).
  long newton_iterations = 0;
  Real wall_time = 0;             ///< [s]
  Real kinetic_energy = 0;        ///< at the end [J]
  Real potential_energy = 0;      ///< at the end [J]
  Real mean_dt = 0;               ///< sim_time / steps [s]
  Real post_step_ms = 0;          ///< total wall time in the post-step pass [ms]
  Real step_ms = 0;               ///< total wall time in integrator steps [ms]
  long post_step_events = 0;      ///< e.g. resolved collisions
  Real assembly_ms = 0;           ///< total wall time in force/Jacobian/system assembly [ms] (semi_implicit)
  Real solve_ms = 0;              ///< total wall time in linear solves [ms] (semi_implicit)
  bool wall_cap_reached = false;  ///< the last run() stopped at settings.max_wall_time
  Index degenerate_terms = 0;     ///< max over steps
  Index torn_segments = 0;        ///< structural elements broken (ForceReport::torn_segments), max over steps
};

/// A pass run after every accepted step (collision handling). It may change x and v; it returns the
/// number of events it handled (e.g. collisions resolved).
class PostStepPass {
 public:
  virtual ~PostStepPass() = default;
  virtual long apply(const VecX& x_old, VecX& x, VecX& v) = 0;
};

struct TrajectoryFrame {
  Real t;
  VecX x;
};

class DrapeSimulation {
 public:
  DrapeSimulation(ClothModel& model, PinnedNodes pins, SimulationSettings settings, VecX x0, VecX v0);

  /// Runs until rest, divergence or settings.max_time (or `until` if smaller) and returns the result
  /// so far (counters accumulate over calls).
  RunResult run(Real until = std::numeric_limits<Real>::infinity());

  /// Node positions, 3N (node after node) [m]; the state itself for 3-DOF models.
  const VecX& positions() const;
  /// The model's whole state and its velocity (numDofs() each); save/resume and the integrators use these.
  const VecX& state() const { return x_; }
  const VecX& velocities() const { return v_; }
  Real time() const { return t_; }
  Real currentDt() const { return dt_; }
  const RunResult& result() const { return result_; }
  const std::vector<TrajectoryFrame>& trajectory() const { return trajectory_; }
  const PinnedNodes& pins() const { return pins_; }
  const SimulationSettings& settings() const { return settings_; }
  void setPostStepPass(PostStepPass* pass) { post_ = pass; }
  Real kineticEnergy() const;

  /// Writes the full dynamic state (time, dt, step-controller memory, rest timer, counters, x, v,
  /// pins, model internal state) to a text file; values are written exactly (hex floats).
  /// The file is written to PATH.tmp, checked after flush and close, then renamed (writeFileAtomically,
  /// output_files.h). Throws OutputError (a std::runtime_error) naming the path on I/O errors.
  void save(const std::string& path) const;
  /// Restores a state written by save() for the same model size; throws std::runtime_error with a
  /// clear message on a malformed or mismatching file (and leaves this object unchanged).
  void load(const std::string& path);

 private:
  bool stepOnce();  // false when the run must stop (divergence)
  void adaptThesis(const VecX& x_old, Real h);
  bool checkDivergence(const VecX& x, const VecX& v, std::string* why) const;
  void resetEnergyBudget();
  Real gravitationalEnergy(const VecX& x) const;

  ClothModel& model_;
  PinnedNodes pins_;
  SimulationSettings settings_;
  std::unique_ptr<Integrator> integrator_;
  PostStepPass* post_ = nullptr;
  VecX x_, v_, x_new_, v_new_;
  mutable VecX positions_view_;  // positions() of a model with more than 3 DOFs per node
  Real t_ = 0;
  Real dt_ = 0;
  // Thesis rule memory.
  Real prev_norm_ = -1, prev_growth_ = 0;
  int decrease_count_ = 0;
  // Rest timer.
  Real rest_since_ = -1;
  RunResult result_;
  std::vector<TrajectoryFrame> trajectory_;
  Real total_mass_ = 0;
  bool energy_check_ = false;
  Real energy_budget_ = 0;  // upper bound of kinetic + gravitational energy (static pins)
};

}  // namespace textile_handling
