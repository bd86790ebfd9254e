// Compression scenes for the stability benchmark of the cloth models (issue 7, docs/choi_ko.md,
// "Stability under compression"). ROS-free; runs on DrapeSimulation with a fixed step, so a step the
// integrator cannot take, or one that blows up, ends the run as a divergence.
//
//  (a) pushed_edges: a flat square cloth whose two opposite edges are pushed together (one edge held,
//      the other moved towards it by a prescribed pin trajectory), then held;
//  (b) lowered_onto_table: a cloth hanging from its top edge is lowered onto a table (a plane
//      obstacle, ObstaclePass), so it must fold or crumple, then held.
//
// DrapeSimulation moves all pinned nodes along one common offset trajectory, so scene (a) holds the
// static edge with stiff zero-length anchor springs (AnchoredClothModel, integrated implicitly like
// every other force) and moves the other edge with the pins.
//
// The scans over step sizes and the stability.csv writer are in the benchmark library
// (bench/include/textile_handling/bench/stability_scan.h).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

/// Wraps a cloth model and ties some nodes to fixed points with zero-length springs on their positions
/// (a node's first three DOFs, for any DOFs per node) f = -k (x - anchor), df/dx = -k I (on the
/// diagonal blocks, which every pattern has). Everything else (masses, pattern, name, internal state,
/// acceptStep) is the wrapped model's.
class AnchoredClothModel : public ClothModel {
 public:
  AnchoredClothModel(ClothModel& inner, std::vector<Index> nodes, std::vector<Vec3> anchors, Real stiffness);

  std::string name() const override { return inner_.name(); }
  Index numNodes() const override { return inner_.numNodes(); }
  int dofsPerNode() const override { return inner_.dofsPerNode(); }
  const VecX& massPerDof() const override { return inner_.massPerDof(); }
  bool hasLumpedMass() const override { return inner_.hasLumpedMass(); }
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override { inner_.addMassMatrix(x, scale, a); }
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override { inner_.multiplyMass(x, v, mv); }
  bool solveMass(const VecX& x, const VecX& f, const std::vector<char>& pinned, VecX& a) const override {
    return inner_.solveMass(x, f, pinned, a);
  }
  Real kineticEnergy(const VecX& x, const VecX& v) const override { return inner_.kineticEnergy(x, v); }
  Real gravitationalEnergy(const VecX& x) const override { return inner_.gravitationalEnergy(x); }
  Real totalMass() const override { return inner_.totalMass(); }
  const BlockPattern& jacobianPattern() const override { return inner_.jacobianPattern(); }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override;
  Vec3 nodePosition(const VecX& x, Index node) const override { return inner_.nodePosition(x, node); }
  Real maxEdgeStretch(const VecX& x) const override { return inner_.maxEdgeStretch(x); }
  std::vector<DrawnYarn> drawnYarns() const override { return inner_.drawnYarns(); }
  void acceptStep(const VecX& x, VecX& v) override { inner_.acceptStep(x, v); }
  std::vector<Real> internalState() const override { return inner_.internalState(); }
  bool setInternalState(const std::vector<Real>& s) override { return inner_.setInternalState(s); }

 private:
  ClothModel& inner_;
  std::vector<Index> nodes_;
  std::vector<Vec3> anchors_;
  Real k_;
};

enum class CompressionScene { kPushedEdges, kLoweredOntoTable };
std::string toString(CompressionScene s);
/// Parses "pushed_edges", "lowered_onto_table"; throws std::invalid_argument otherwise.
CompressionScene compressionSceneFromString(const std::string& s);

struct CompressionSceneSpec {
  CompressionScene scene = CompressionScene::kPushedEdges;
  Real side = 0.3;        ///< side of the square cloth [m]
  Real spacing = 0.02;    ///< grid spacing d [m]
  Real hold_time = 1.0;   ///< simulated time after the motion [s]
  /// Out-of-plane perturbation of the flat start, in units of d: amplitude of a smooth first mode
  /// (a half sine across the sheet) ...
  Real perturbation = 0.05;
  /// ... plus a fixed pseudo-random part of this amplitude (breaks the symmetry; kept small, since
  /// node-to-node roughness pre-stretches the tension springs).
  Real noise = 0.001;
  // (a) pushed edges.
  Real push_fraction = 0.4;     ///< travel of the moving edge / side
  Real push_time = 1.0;         ///< [s]
  bool push_gravity = false;    ///< gravity in scene (a) (off: pure in-plane compression)
  Real anchor_stiffness = 1e4;  ///< [N/m] per anchored node of the held edge
  // (b) lowered onto a table.
  Real table_gap = 0.02;        ///< initial height of the bottom edge above the table [m]
  Real lower_fraction = 0.6;    ///< travel of the holder below first contact / side
  Real lower_time = 1.5;        ///< [s]
  Real table_friction = 0.5;    ///< ObstacleOptions::friction
};

struct StabilityRunSpec {
  /// Any registered model and its options; settle_damping_per_s (and gravity in the pushed-edges
  /// scene) are set by the run.
  ClothModelSpec model = ClothModelSpec("choi_ko");
  Real dt = 0.01;                 ///< fixed step [s]
  bool damping = false;           ///< add settle (mass-proportional) damping
  Real damping_per_s = 5.0;       ///< zeta [1/s] used when `damping` is on
  Material material = Material::cotton();
  IntegratorType integrator = IntegratorType::kSemiImplicitEuler;
  SolverSettings solver;
  /// Divergence bounds handed to DrapeSimulation (RMS speed, edge stretch).
  Real max_rms_speed = 5.0;       ///< [m/s]
  Real max_edge_stretch = 2.0;
  Real max_wall_time = 0;         ///< wall-clock cap of the run [s] (0 = none); a capped run is not stable
};

struct StabilityResult {
  bool stable = false;           ///< ran to the end without divergence
  std::string reason;            ///< why not (DrapeSimulation's divergence reason)
  Real end_time = 0;             ///< scheduled end of the scene [s]
  Real sim_time = 0;             ///< reached [s]
  long steps = 0;
  long solver_iterations = 0;
  Real wall_time = 0;            ///< [s]
  Real peak_rms_speed = 0;       ///< sampled every max(dt, 10 ms) [m/s]
  Real final_rms_speed = 0;      ///< [m/s]
  Real peak_edge_stretch = 0;    ///< sampled
  Real final_min_z = 0;          ///< lowest node at the end [m] (scene b: the table is at z = 0)
  long obstacle_events = 0;
  Index nodes = 0;
  bool wall_cap_reached = false;  ///< stopped at StabilityRunSpec::max_wall_time
  ParticleGrid grid;              ///< the square sheet's grid (textile frame, origin at a corner)
  VecX final_positions;           ///< node positions at the end, 3 x nodes [m]
};

/// Runs one scene with one model, step and damping setting. Throws std::invalid_argument on bad specs.
StabilityResult runCompressionScene(const CompressionSceneSpec& scene, const StabilityRunSpec& run);

}  // namespace textile_handling
