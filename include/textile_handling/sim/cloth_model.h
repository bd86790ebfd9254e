// The interface every cloth model implements, so that all models run on the same integrators,
// scenes, database and benchmarks. A model owns its DOFs, masses, forces and Jacobians; it knows
// nothing about time stepping, pinned nodes or collisions.
#pragma once

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

/// What a force evaluation found besides the forces.
struct ForceReport {
  /// Terms skipped because their geometry was degenerate (zero-length edge, non-finite input).
  Index degenerate_terms = 0;
};

class ClothModel {
 public:
  virtual ~ClothModel() = default;

  /// Short model name as used in CSV files and the database ("particle_kes", "choi_ko", ...).
  virtual std::string name() const = 0;
  virtual Index numNodes() const = 0;
  /// DOFs per node: 3 for particles (x, y, z), 5 for yarn crossings (x, y, z, u, v).
  virtual int dofsPerNode() const { return 3; }
  Index numDofs() const { return numNodes() * dofsPerNode(); }
  /// Diagonal (lumped) mass per DOF [kg, or kg*m^2 for non-positional DOFs].
  virtual const VecX& massPerDof() const = 0;
  /// Block pattern of df/dx and df/dv (block size = dofsPerNode()).
  virtual const BlockPattern& jacobianPattern() const = 0;
  /// Forces f(x, v) [N]; with `jac`, also df/dx and df/dv (values overwritten, pattern fixed).
  virtual ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) = 0;
  /// Potential energy of all conservative forces (gravity and elastic terms) [J].
  virtual Real potentialEnergy(const VecX& x) const = 0;
  /// World position of a node [m] (for rendering, rest detection and collision).
  virtual Vec3 nodePosition(const VecX& x, Index node) const { return node3(x, node); }
  /// Largest ratio of current to rest length over the structural edges (divergence detection).
  virtual Real maxEdgeStretch(const VecX& x) const = 0;
  /// Called once per accepted step; models with internal state (hysteresis) commit it here.
  virtual void acceptStep(const VecX& /*x*/, const VecX& /*v*/) {}
  /// Internal state for save/resume (empty for stateless models).
  virtual std::vector<Real> internalState() const { return {}; }
  virtual bool setInternalState(const std::vector<Real>& state) { return state.empty(); }

  /// Convenience: allocates Jacobian storage on this model's pattern.
  ForceJacobians makeJacobians() const {
    return ForceJacobians{BlockSparseMatrix(&jacobianPattern()), BlockSparseMatrix(&jacobianPattern())};
  }
};

}  // namespace textile_handling
