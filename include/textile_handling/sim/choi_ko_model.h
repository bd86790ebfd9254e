// The Choi–Ko cloth model ("Stable but Responsive Cloth", Choi & Ko 2002; patent EP 1 439 476, seed
// shared/seeds/002_8c736abc780ab69f.txt, English notes with errata
// shared/reference/choi-ko-buckling-hysteresis.md). Its point is stability under compression
// without damping: compression is never resisted by a spring but by the immediate buckling model,
// so the Jacobian stays negative semi-definite and the semi-implicit step stays well posed.
//
// Same particles as the particle model (ParticleTopology, 3 DOFs per node, lumped masses, the same
// quadratic drag and optional settle damping), different interactions:
//  * type 1 (stretch and shear): linear springs that act only in tension (eqs (10)-(12)): the grid
//    edges (warp, weft) and both diagonals of every complete cell (shear);
//  * type 2 (bending and compression): immediate buckling units (eqs (1)-(9)) with the linear segment
//    below the critical load; either the beam version (particles two grid steps apart along warp and
//    weft, L = 2d) or the plate version (the two unshared vertices of every pair of triangles that
//    share an edge, on the triangulation of collision.h). The Jacobian drops the negative term of
//    eq (7) by default.
//  * optional hysteresis of the moment-curvature law (discrete or continuous Choi–Ko model), with one
//    state per bending unit, committed in acceptStep().
// Parameter mapping from KES data and every decision: docs/choi_ko.md.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/choi_ko_kernels.h"
#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/material.h"

namespace textile_handling {

enum class ChoiKoBending {
  kBeam,   ///< beam units (Choi & Ko 2002, Fig. 2): (i, j) two steps apart along warp and weft
  kPlate,  ///< plate units (claim 1, Fig. 3): unshared vertices of two triangles sharing an edge
};
std::string toString(ChoiKoBending b);
/// Parses "beam", "plate"; throws std::invalid_argument otherwise.
ChoiKoBending choiKoBendingFromString(const std::string& s);

/// How a rigidity is read off a KES curve.
enum class KesSlopeRule {
  /// KES-FB definitions: B = mean slope of the bending curve between 0.5 and 1.5 1/cm; G = mean slope
  /// of the shear curve between 0.5 and 5 degrees ("kes").
  kKesStandard,
  /// Slope at the origin ("initial").
  kInitial,
};
std::string toString(KesSlopeRule r);
/// Parses "kes", "initial"; throws std::invalid_argument otherwise.
KesSlopeRule kesSlopeRuleFromString(const std::string& s);

struct ChoiKoOptions {
  bool gravity = true;
  bool drag = true;
  bool stretch = true;  ///< type-1 warp/weft springs
  bool shear = true;    ///< type-1 diagonal springs
  bool bending = true;  ///< type-2 units
  ChoiKoBending bending_version = ChoiKoBending::kBeam;
  /// s* = r/L below which the buckling curve replaces the linear segment (c_b = F0 |g(s*)| / (L (1 - s*))).
  Real buckling_onset = 0.999;
  /// kappa* [1/m]; > 0 replaces buckling_onset by the onset of a beam unit (L = 2d) bent to kappa* on the
  /// model's grid, s* = sin(kappa* d) / (kappa* d): bends gentler than kappa*, whose moment grows like
  /// kappa^3 on the linear segment, then stay below kappa* at every spacing (with a fixed s* they reach
  /// 0.155 / d: 0.77 1/cm at d = 1 mm; docs/choi_ko.md, "Linear segment below P_cr").
  Real buckling_onset_curvature = 0;
  /// Jacobian of the bending units. Default: the seed's (eq (7) without its negative term) with the
  /// secant slope where it is steeper; kDropNegative is the seed's alone, which lets a unit on the
  /// buckling curve push with ~P_cr through a whole step and diverges at d = 1 cm, dt = 10 ms
  /// (docs/choi_ko.md, "Stability under compression").
  choi_ko::BendingJacobian bending_jacobian = choi_ko::BendingJacobian::kSecant;
  KesSlopeRule slope_rule = KesSlopeRule::kKesStandard;
  /// Membrane tensile stiffness E_t [N/m] (force per width per unit strain); 0 = derive from the
  /// material's quintic tension law as its secant at `reference_strain`: E_t = Y eps_ref^3.
  Real tensile_stiffness = 0;
  Real reference_strain = 0.01;
  /// In-plane shear stiffness G [N/m per rad]; 0 = from the KES shear curves (mean of warp and weft).
  Real shear_stiffness = 0;
  /// Bending rigidity B [N m] per direction; 0 = from the KES bending curves.
  Real bending_rigidity_warp = 0;
  Real bending_rigidity_weft = 0;
  /// Moment-curvature hysteresis of every bending unit (none = linear M = B kappa).
  choi_ko::HysteresisSpec hysteresis;
  /// Mass-proportional damping -zeta m v [1/s] as in the particle model. 0 by default: the model's
  /// point is stability without damping.
  Real settle_damping = 0;
};

/// The SI parameters a model was built with (docs/choi_ko.md, "Parameters from KES data").
struct ChoiKoParameters {
  Real tensile_stiffness = 0;        ///< E_t [N/m]
  Real shear_stiffness = 0;          ///< G [N/m per rad]
  Real bending_rigidity[2] = {0, 0}; ///< B warp, weft [N m] (plate version: their mean)
  Real areal_density = 0;            ///< [kg/m^2]
  Real diagonal_spring = 0;          ///< k_d = 2 G [N/m] of one shear spring
  choi_ko::BucklingLaw law;          ///< linear segment (gamma = c_b L / F0)
};
/// Derives the parameters from a material and the options (throws std::invalid_argument on bad values).
/// `spacing` [m] is the grid the law is for; needed only with options.buckling_onset_curvature.
ChoiKoParameters choiKoParameters(const Material& material, const ChoiKoOptions& options, Real spacing = 0);

class ChoiKoClothModel : public ClothModel {
 public:
  ChoiKoClothModel(ParticleTopology topology, Material material, ChoiKoOptions options = {});

  std::string name() const override { return "choi_ko"; }
  Index numNodes() const override { return topo_.size(); }
  const VecX& massPerDof() const override { return mass_; }
  const BlockPattern& jacobianPattern() const override { return pattern_; }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  /// Gravity + springs + bending units. With hysteresis the bending part is that of the linear law
  /// with the reference rigidity (a report only: hysteretic forces are path dependent and have no
  /// potential).
  Real potentialEnergy(const VecX& x) const override;
  Real maxEdgeStretch(const VecX& x) const override;
  /// Commits the bend sign and the hysteresis state of every bending unit at the accepted x.
  void acceptStep(const VecX& x, VecX& v) override;
  /// Empty without hysteresis; else a flat vector (layout in docs/choi_ko.md).
  std::vector<Real> internalState() const override;
  bool setInternalState(const std::vector<Real>& state) override;

  const ParticleTopology& topology() const { return topo_; }
  const Material& material() const { return material_; }
  const ChoiKoOptions& options() const { return options_; }
  const ChoiKoParameters& parameters() const { return params_; }

  /// Interaction kinds, for introspection and tests.
  enum class SpringKind { kWarp, kWeft, kShear };
  struct Spring {
    Index i, j;
    Real rest;       ///< [m]
    Real k;          ///< [N/m]
    SpringKind kind;
  };
  struct BendingUnit {
    Index i, j;      ///< the unit's end particles
    Real rest;       ///< L [m]
    Real weight;     ///< W [m^2]: beam: width share x d; plate: (A_i + A_j) / 0.93
    Real rigidity;   ///< B [N m] of the linear law
    Real f0;         ///< W B / L^3 [N] (B: reference rigidity, see docs)
    int dir;         ///< 0 warp beam, 1 weft beam, 2 plate
  };
  const std::vector<Spring>& springs() const { return springs_; }
  const std::vector<BendingUnit>& bendingUnits() const { return bends_; }
  /// Committed bend sign (+1 / -1) and hysteresis state of bending unit k (hysteresis only).
  Real committedSign(Index k) const { return sign_[static_cast<size_t>(k)]; }
  const choi_ko::HysteresisState& hysteresisState(Index k) const { return hyst_[static_cast<size_t>(k)]; }
  /// Signed curvature X = sign * kappa [1/m] of unit k at x, with the sign rule of docs/choi_ko.md
  /// (geometric sign where the unit is clearly bent, else the committed one).
  Real signedCurvature(Index k, const VecX& x) const;

 private:
  // Evaluates one bending unit: fills the pair result (force/Jacobian) from the law or hysteresis.
  bool evalBending(Index k, const VecX& x, bool want_jac, choi_ko::PairTermResult* out) const;
  Real trialSign(Index k, const VecX& x, Real theta) const;
  // Unit cloth normal at node p (warp tangent x weft tangent from its neighbours); false if undefined.
  bool vertexNormal(Index p, const VecX& x, Vec3* n) const;
  Real unitEnergy(const BendingUnit& b, const VecX& x) const;

  ParticleTopology topo_;
  Material material_;
  ChoiKoOptions options_;
  ChoiKoParameters params_;
  VecX mass_;
  std::vector<Real> drag_coeff_;
  std::vector<Spring> springs_;
  std::vector<BendingUnit> bends_;
  BlockPattern pattern_;
  // Deterministic two-phase assembly: per-term results, then a gather per node (each row of the
  // Jacobian is written by one thread, terms in a fixed order).
  struct Incidence {
    Index term;   // springs first, then bending units
    Index other;  // the other node
    Index slot_other;
    Real side;    // +1: node is the term's i (gets +f_i), -1: node is j
  };
  std::vector<Index> inc_start_;
  std::vector<Incidence> inc_;
  std::vector<choi_ko::PairTermResult> term_;  // scratch of computeForces
  std::vector<char> term_ok_;
  // Hysteresis: committed sign and state per bending unit.
  std::vector<Real> sign_;
  std::vector<choi_ko::HysteresisState> hyst_;
};

}  // namespace textile_handling
