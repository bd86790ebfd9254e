// The interface every cloth model implements, so that all models run on the same integrators,
// scenes, database and benchmarks. A model owns its DOFs, its mass, its forces and Jacobians; it knows
// nothing about time stepping, pinned nodes or collisions.
//
// DOF layout (the contract every model keeps): node i owns the DOFs [i b, (i + 1) b) of the stacked
// state vector, b = dofsPerNode(), and the first three of them are the node's world position [m].
// Further DOFs (a yarn crossing's sliding coordinates u, v, ...) follow. Pins, collision handling, the
// renderers and the database read and write positions only, through positionsOf() / setPositions().
//
// Mass: a model either has a constant diagonal (lumped) mass, hasLumpedMass() == true, massPerDof() is
// then exact and everything takes a fast path; or it assembles a block-sparse, possibly
// configuration-dependent mass matrix M(x) on its Jacobian pattern (addMassMatrix) and overrides the
// mass operations below. The quadratic-velocity terms of a configuration-dependent mass
// (-dM/dt v + 1/2 d(v^T M v)/dx) are part of the model's computeForces(); the integrators treat M(x) as
// constant during a step.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "textile_handling/sim/block_sparse.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// df/dx and df/dv on the model's fixed block pattern.
struct ForceJacobians {
  BlockSparseMatrix dfdx;
  BlockSparseMatrix dfdv;
};

/// One yarn of a model, as pictures draw it: its nodes in order along the yarn, and its direction.
struct DrawnYarn {
  std::vector<Index> nodes;  ///< node indices, in order of arc length along the yarn
  bool warp = true;          ///< a warp yarn (along the textile's x axis) or a weft yarn (along y)
  /// The yarn's line across the textile, counted per direction (the pieces of one line share it);
  /// pictures thin out dense yarns by line.
  std::size_t line = 0;
};

/// What a force evaluation found besides the forces.
struct ForceReport {
  /// Terms skipped because their geometry was degenerate (zero-length edge, non-finite input).
  Index degenerate_terms = 0;
  /// Structural elements broken so far, by a model that tears (yarn_woven with tear_tension_n).
  Index torn_segments = 0;
};

class ClothModel {
 public:
  virtual ~ClothModel() = default;

  /// Short model name as used in CSV files and the database ("particle_kes", "choi_ko", ...).
  virtual std::string name() const = 0;
  virtual Index numNodes() const = 0;
  /// DOFs per node, >= 3: 3 for particles (x, y, z), 5 for yarn crossings (x, y, z, u, v).
  virtual int dofsPerNode() const { return 3; }
  Index numDofs() const { return numNodes() * dofsPerNode(); }
  /// Block pattern of df/dx and df/dv (block size = dofsPerNode()); it also holds the mass's couplings.
  virtual const BlockPattern& jacobianPattern() const = 0;
  /// Forces f(x, v) [N]; with `jac`, also df/dx and df/dv (values overwritten, pattern fixed).
  virtual ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) = 0;
  /// Potential energy of all conservative forces (gravity and elastic terms) [J].
  virtual Real potentialEnergy(const VecX& x) const = 0;
  /// Largest ratio of current to rest length over the structural edges (divergence detection).
  virtual Real maxEdgeStretch(const VecX& x) const = 0;
  /// Called once per accepted step; models with internal state (hysteresis) commit it here. A model
  /// may change v: one that holds a DOF from now on (a torn yarn's cut end) sets its velocity to 0.
  virtual void acceptStep(const VecX& /*x*/, VecX& /*v*/) {}
  /// Internal state for save/resume (empty for stateless models).
  virtual std::vector<Real> internalState() const { return {}; }
  virtual bool setInternalState(const std::vector<Real>& state) { return state.empty(); }

  // ---- Mass ---------------------------------------------------------------------------------------
  /// True if the mass matrix is constant and diagonal, i.e. equal to massPerDof() (the fast path).
  virtual bool hasLumpedMass() const { return true; }
  /// Lumped mass per DOF [kg, or kg m^2 for angular DOFs], size numDofs(), all > 0. Exact when
  /// hasLumpedMass(); otherwise a lumped approximation of M(x0) that only estimates use.
  virtual const VecX& massPerDof() const = 0;
  /// Adds scale * M(x) to `a`, a matrix on jacobianPattern(). Default: the lumped diagonal.
  virtual void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const;
  /// mv = M(x) v (size numDofs()). Default: the lumped diagonal.
  virtual void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const;
  /// Accelerations of the free nodes: solves M_ff(x) a_f = f_f, with a = 0 on every DOF of the nodes
  /// flagged in `node_pinned` (size numNodes(), may be empty = none pinned). Returns false if the solve
  /// failed. Default: a = f / massPerDof() for lumped models, preconditioned conjugate gradients on
  /// the assembled M(x) otherwise (massSolveByConjugateGradients).
  virtual bool solveMass(const VecX& x, const VecX& f, const std::vector<char>& node_pinned, VecX& a) const;
  /// Kinetic energy 1/2 v^T M(x) v [J].
  virtual Real kineticEnergy(const VecX& x, const VecX& v) const;
  /// Gravitational part of potentialEnergy() [J] (z up). Default: sum of m_z g z over the nodes.
  virtual Real gravitationalEnergy(const VecX& x) const;
  /// Total mass of the textile [kg] (rest detection's mean speed, divergence bounds). Default: the sum of
  /// massPerDof() over the first DOF of every node.
  virtual Real totalMass() const;

  // ---- Positions ----------------------------------------------------------------------------------
  /// World position of a node [m] (the first three DOFs of its block; decorators forward it).
  virtual Vec3 nodePosition(const VecX& x, Index node) const {
    return Eigen::Map<const Vec3>(x.data() + static_cast<Eigen::Index>(node) * dofsPerNode());
  }
  /// The 3N vector of node positions (node after node) of state x. For 3-DOF models this is x itself.
  VecX positionsOf(const VecX& x) const;
  /// Writes the 3N positions `p` into the position DOFs of `x`; the other DOFs keep their values.
  void setPositions(const VecX& p, VecX& x) const;

  // ---- Pictures -----------------------------------------------------------------------------------
  /// The yarns to draw over the shape in pictures (writeRestShapePicture), as polylines of nodes;
  /// empty for models without yarns (the particle models). Decorators forward it.
  virtual std::vector<DrawnYarn> drawnYarns() const { return {}; }

  /// Convenience: allocates Jacobian storage on this model's pattern.
  ForceJacobians makeJacobians() const {
    return ForceJacobians{BlockSparseMatrix(&jacobianPattern()), BlockSparseMatrix(&jacobianPattern())};
  }
};

/// Solves M_ff(x) a_f = f_f for a model with a non-lumped mass: M assembled with addMassMatrix(),
/// block-Jacobi preconditioned conjugate gradients to a relative residual of 1e-12 (the mass matrix is
/// symmetric positive definite and well conditioned). Returns false if CG breaks down or does not
/// converge in numDofs() iterations.
bool massSolveByConjugateGradients(const ClothModel& model, const VecX& x, const VecX& f,
                                   const std::vector<char>& node_pinned, VecX& a);

}  // namespace textile_handling
