// The particle cloth model of the thesis: particles on a square grid, each interacting with its four
// direct neighbours through tension (Breen quintic law), shear (KES shear curve, four angles) and
// bending (KES bending curve, two angles), plus gravity and isotropic quadratic fluid drag.
//
// Modelling decisions (thesis section 12 of shared/reference/thesis-hanging-textiles.md); each is
// explained in docs/simulation.md:
//  1 bending angle -> KES abscissa: curvature kappa = (pi - Phi)/d, moment times width d;
//  2 C^s, C^b: secant reading, so dE/dtheta is the KES curve value and d2E/dtheta2 its slope;
//  3 warp = grid x (columns), weft = grid y (rows); Phi_1 (left-right) bends with the warp curve,
//    Phi_2 (up-down) with the weft curve; every shear angle uses the mean of the two shear curves;
//  4 tension: C0 ((r-d)/d)^5 stretch branch, each edge counted once with C0 = d^2 Y / 5, so the membrane
//    force per width is Y strain^4 whatever the resolution;
//  5 SI units; shear energy weight d^2/4 per angle (four corner angles share a cell), bending d^2;
//  6 angles with atan2 and the exact flat-sheet limit (see energy_kernels.h);
//  7 terms with a missing neighbour are dropped;
//  8 mass and drag area per particle = its share of the adjacent grid cells (d^2/4 per cell); likewise
//    every tension edge and bending hinge carries its width share (1/2 d per adjacent cell row), so a
//    border row is as stiff as the half-width strip whose mass it carries.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/energy_kernels.h"
#include "textile_handling/sim/material.h"

namespace textile_handling {

enum class JacobianMode {
  kExact,        ///< full analytic Hessian (the thesis)
  kDefiniteFix,  ///< angle terms: Gauss-Newton part only; tension: compression transverse term dropped
};

struct ParticleModelOptions {
  bool gravity = true;
  bool drag = true;
  bool shear = true;
  bool bending = true;
  JacobianMode jacobian = JacobianMode::kExact;
  /// Mass-proportional (linear) damping f = -zeta m v [1/s]. A settling aid for database builds: an
  /// equilibrium does not depend on it, so rest shapes are unchanged while swinging dies out fast.
  /// 0 = only the thesis's quadratic fluid drag.
  Real settle_damping = 0;
};

class ParticleClothModel : public ClothModel {
 public:
  ParticleClothModel(ParticleTopology topology, Material material, ParticleModelOptions options = {});

  std::string name() const override { return "particle_kes"; }
  Index numNodes() const override { return topo_.size(); }
  const VecX& massPerDof() const override { return mass_; }
  const BlockPattern& jacobianPattern() const override { return pattern_; }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override;
  Real maxEdgeStretch(const VecX& x) const override;

  const ParticleTopology& topology() const { return topo_; }
  const Material& material() const { return material_; }
  const ParticleModelOptions& options() const { return options_; }
  void setOptions(const ParticleModelOptions& o) { options_ = o; }
  /// Per-edge tension constant C0 = d^2 Y / 5 [J].
  Real tensionConstant() const { return c0_; }

  /// Profiles of the angle energies as functions of theta (exposed for tests).
  // Energy of one shear angle / bending hinge (unweighted by the hinge width); the profiles' energy.
  Real shearEnergy(Real theta) const;
  Real bendEnergy(int dir, Real theta) const;
  AngleProfile shearProfile(Real theta) const;
  AngleProfile bendProfile(int dir, Real theta) const;

 private:
  struct Stencil {
    Index node[5];      // centre, right, up, left, down (-1 if missing)
    Index slot[5][5];   // block slot between stencil nodes (-1 if either is missing)
    Real edge_width[2]; // width share (in units of d) of the edges to the right and up neighbours
    Real bend_width[2]; // width share (in units of d) of the left-right and up-down bending hinges
  };
  // Adds the terms of one stencil; returns the number of degenerate terms.
  Index addStencil(const Stencil& st, const VecX& x, VecX& f, BlockSparseMatrix* K, Real* energy) const;
  // The stencil's energy alone (the terms of addStencil, same order, no derivatives).
  Real stencilEnergy(const Stencil& st, const VecX& x) const;
  // Calls f(a, b, kind, dir) for each angle term of the stencil, in the order both use.
  template <class F>
  void forEachAngle(const Stencil& st, F&& f) const;

  ParticleTopology topo_;
  Material material_;
  ParticleModelOptions options_;
  Real c0_ = 0;
  VecX mass_;
  std::vector<Real> drag_coeff_;  // 1/2 rho c_w A per particle
  std::vector<Stencil> stencils_;
  std::vector<std::vector<Index>> colour_;  // stencils by colour; same-colour stencils are disjoint
  BlockPattern pattern_;
};

}  // namespace textile_handling
