// The yarn-level woven cloth model (`yarn_woven`): every warp/weft crossing a node with five DOFs
// (position, and the warp and weft sliding coordinates), yarn stretch, bending and gravity with the
// configuration-dependent mass of yarn material spread along the yarns, and Rayleigh damping.
// docs/yarn_model.md; source: the notes on the yarn-level model
// (../shared/reference/yarn-level-woven-cloth.md).
//
// DOF layout (ClothModel's contract): node k owns [5k, 5k + 5) = (x, y, z, s_u, s_v). The sliding DOFs
// are *displacements* of the arc-length coordinates from their flat values, u = u_rest + s_u, so the
// zero of every further DOF is the flat, unslid yarn (a scene starts there) and slides of micrometres
// are not lost against arc lengths of a metre (notes section 9.10).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_grid.h"
#include "textile_handling/sim/yarn_sheet.h"

namespace textile_handling {

struct YarnWovenOptions {
  WovenFabric fabric;          ///< the real fabric: weave, yarn densities and yarn parameters
  bool gravity = true;
  /// Jacobian df/dx from the kernels' exact Hessians (indefinite for compressed or bent yarns) instead
  /// of their clamped, positive semi-definite ones.
  bool exact_hessian = false;
};

/// The yarn grid of a particle grid: particle k is crossing k at (column, row) x spacing; every maximal
/// run of right (+x) neighbours is a warp piece (line = row), every run of up (+y) neighbours a weft
/// piece (line = column); weave flags from `weave`; no end nodes (a yarn ends at its last crossing).
YarnGrid yarnGridOnParticles(const ParticleTopology& topology, const WeavePattern& weave);

/// The fabric simulated on a grid of spacing `spacing` [m] instead of the real yarn spacing: each
/// simulated yarn stands for n = spacing (warp + weft density) / 2 real yarns side by side (a yarn
/// bundle). Stretch, bending and shear stiffness and linear density are n times the real yarn's, so the
/// sheet's mass and stiffness per area are the real fabric's; the radius is n R, so R / L and with it
/// the jamming angle keep their value. Densities become 1 / spacing. n = 1 is the real fabric.
/// Exact for equal warp and weft densities; for unequal ones both directions get the mean.
WovenFabric yarnBundleFabric(const WovenFabric& fabric, Real spacing);

class YarnWovenModel : public ClothModel {
 public:
  /// `fabric`: the simulated fabric (its spacings must match the sheet's). Throws SimError for an
  /// invalid fabric or a sheet with no segment.
  YarnWovenModel(YarnSheet sheet, WovenFabric fabric, YarnWovenOptions options);

  std::string name() const override { return "yarn_woven"; }
  Index numNodes() const override { return static_cast<Index>(sheet_.nodeCount()); }
  int dofsPerNode() const override { return kYarnDofsPerNode; }
  const BlockPattern& jacobianPattern() const override { return pattern_; }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override;
  /// Largest ratio of a segment's length to its rest length D = u1 - u0 (with the current slides).
  Real maxEdgeStretch(const VecX& x) const override;

  bool hasLumpedMass() const override { return false; }
  /// Per node: half of its segments' mass on all five DOFs (an estimate; the mass is M(x)).
  const VecX& massPerDof() const override { return lumped_; }
  /// scale M(x) (notes eq. 5) plus scale m_node on each held DOF's diagonal (a held DOF never moves:
  /// its force and Jacobian are zero, the unit entry only keeps the system regular).
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override;
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override;
  Real gravitationalEnergy(const VecX& x) const override;
  Real totalMass() const override { return total_mass_; }

  const YarnSheet& sheet() const { return sheet_; }
  const WovenFabric& fabric() const { return fabric_; }
  /// The generalised coordinates of the kernels (absolute arc lengths u, v) of state x.
  VecX kernelCoordinates(const VecX& x) const { return x + arc_offset_; }
  bool isHeld(Index dof) const { return held_[static_cast<std::size_t>(dof)] != 0; }

 private:
  struct Stencil;  // DOFs and block slots of one kernel's stencil
  void assembleHessian(const VecX& q, bool clamped, bool with_gravity, Real scale, BlockSparseMatrix& a) const;
  template <int Nodes>
  static std::array<std::size_t, 4 * Nodes> dofsOf(const Stencil& s);
  template <int Nodes, class Matrix>
  void scatterBlocks(const Matrix& m, const Stencil& s, Real scale, BlockSparseMatrix& a) const;

  YarnSheet sheet_;
  WovenFabric fabric_;
  YarnWovenOptions options_;
  Vec3 gravity_;
  BlockPattern pattern_;
  std::vector<Stencil> segments_, bends_;
  std::vector<char> held_;  ///< per DOF
  VecX arc_offset_;         ///< the flat arc lengths on the sliding DOFs, 0 on positions
  VecX lumped_;
  Real total_mass_ = 0;
  mutable BlockSparseMatrix scratch_;  // damping stiffness and mass products
};

}  // namespace textile_handling
