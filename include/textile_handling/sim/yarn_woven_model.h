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
#include <atomic>
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_crossing_kernels.h"
#include "textile_handling/sim/yarn_grid.h"
#include "textile_handling/sim/yarn_penalty_contact.h"
#include "textile_handling/sim/yarn_sheet.h"

namespace textile_handling {

struct RowShare;          // src/sim/ordered_parallel.h
class RowRangeSchedule;  // src/sim/ordered_parallel.h

/// The constants of the crossing terms the source leaves open (notes section 9.1, 9.5), as factors of
/// the fabric's own stiffnesses so that they keep their meaning for any yarn and bundle size.
/// docs/yarn_model.md, "Crossing terms in the model".
struct YarnCrossingOptions {
  bool shear = true;             ///< shear with jamming (eq. 11) and shear friction (eq. 12)
  bool friction = true;          ///< sliding friction (eq. 10) and shear friction (eq. 12)
  bool contact = true;           ///< contact between neighbouring parallel yarns (eq. 13)
  /// k_f = factor k_s / L: a crossing's stick spring is as stiff as one yarn segment in stretch.
  Real friction_stiffness_factor = 1;
  /// k_fphi = factor k_x L: the shear stick spring is this many times stiffer than elastic shear.
  Real shear_friction_stiffness_factor = 10;
  /// c_j: the shear stiffness at phi = 0 is (1 + c_j) k; 1e5 makes it 100 times k 10 % below phi_j, a
  /// sharp knee (notes 3.5: "grows cubically").
  Real jamming_gain = 1e5;
  /// c_n [1/N] of k_x(F_n) = k_x (1 + c_n F_n) for one real crossing (a bundle uses c_n / n^2).
  Real compression_gain_per_n = 250;
  /// k_c = factor k_s / L^2 (the notes' "k_c ~ k_s / L" with the units of eq. 13).
  Real contact_stiffness_factor = 1;
};

struct YarnWovenOptions {
  WovenFabric fabric;          ///< the real fabric: weave, yarn densities and yarn parameters
  YarnCrossingOptions crossing;
  /// Real yarns per simulated yarn (yarnBundleFabric()); 1 = every yarn simulated. Set by the factory.
  Real bundle_size = 1;
  bool gravity = true;
  /// Jacobian df/dx from the kernels' exact Hessians (indefinite for compressed or bent yarns) instead
  /// of their clamped, positive semi-definite ones.
  bool exact_hessian = false;
  /// Tension of one real yarn [N] above which a yarn segment tears (a simulated bundle of n yarns at n
  /// times it); 0 = no tearing. docs/yarn_model.md, "Tearing".
  Real tear_tension_n = 0;
  YarnSelfContactOptions self_contact;  ///< penalty self-contact on extruded triangles
};

/// Throws SimError naming tear_tension_n unless `tension_n` is finite and >= 0.
void validateTearTension(Real tension_n);

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
/// The bundle size n = spacing (warp density + weft density) / 2 of yarnBundleFabric().
Real yarnBundleSize(const WovenFabric& fabric, Real spacing);

class YarnWovenModel : public ClothModel {
 public:
  /// `fabric`: the simulated fabric (its spacings must match the sheet's). Throws SimError for an
  /// invalid fabric or a sheet with no segment.
  YarnWovenModel(YarnSheet sheet, WovenFabric fabric, YarnWovenOptions options);
  YarnWovenModel(YarnWovenModel&&) noexcept;
  YarnWovenModel& operator=(YarnWovenModel&&) noexcept;
  ~YarnWovenModel() override;

  std::string name() const override { return "yarn_woven"; }
  Index numNodes() const override { return static_cast<Index>(sheet_.nodeCount()); }
  int dofsPerNode() const override { return kYarnDofsPerNode; }
  const BlockPattern& jacobianPattern() const override { return pattern_; }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override;
  /// Commits the friction anchors (stick/slip, notes 3.4 and 3.6), tears overloaded segments (with
  /// tear_tension_n; zeroes the velocities of the sliding DOFs a tear holds) and evaluates the normal
  /// compression F_n of the new state (eq. 9), which the next step uses as a constant (lagged, notes 9.2).
  void acceptStep(const VecX& x, VecX& v) override;
  /// [sliding anchors (2 per node), angle anchors (4 per crossing pair slot), F_n (per crossing), 1 if
  /// F_n was evaluated], with self_contact [1 if detected, count, per contact: node, triangle, side,
  /// 3 anchor weights] (the sides and anchors carry history: they cannot be recomputed from x), then,
  /// if any segment is torn, the torn segments' indices (ascending) and their count. A state without
  /// torn segments is the same as before tearing existed.
  std::vector<Real> internalState() const override;
  bool setInternalState(const std::vector<Real>& state) override;
  /// The lagged normal compression per crossing [N] (of the simulated bundle), empty before the first
  /// force evaluation.
  const std::vector<Real>& compression() const { return compression_; }
  /// Largest ratio of a segment's length to its rest length D = u1 - u0 (with the current slides).
  Real maxEdgeStretch(const VecX& x) const override;

  bool hasLumpedMass() const override { return false; }
  /// Per node: half of its segments' mass on all five DOFs (an estimate; the mass is M(x)).
  const VecX& massPerDof() const override { return lumped_; }
  /// scale M(x) (notes eq. 5; a torn segment's mass lumped on its two nodes) plus scale m_node on each
  /// held DOF's diagonal (a held DOF never moves: its force and Jacobian are zero, the unit entry only
  /// keeps the system regular).
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override;
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override;
  Real gravitationalEnergy(const VecX& x) const override;
  Real totalMass() const override { return total_mass_; }

  /// One polyline per warp and per weft piece of the sheet: its nodes (crossings and ends) in order.
  std::vector<DrawnYarn> drawnYarns() const override;

  /// The sheet as simulated: after a tear its pieces are split at the torn segment and the cut ends'
  /// sliding DOFs are among its held DOFs.
  const YarnSheet& sheet() const { return sheet_; }
  const WovenFabric& fabric() const { return fabric_; }
  /// The generalised coordinates of the kernels (absolute arc lengths u, v) of state x.
  VecX kernelCoordinates(const VecX& x) const { return x + arc_offset_; }
  bool isHeld(Index dof) const { return held_[static_cast<std::size_t>(dof)] != 0; }
  /// The penalty self-contacts of the last accepted step (yarn_woven_self_contact.cpp) and their triangles.
  const std::vector<yarn::PenaltyContact>& selfContacts() const { return self_contacts_; }
  const yarn::YarnTriangles& selfContactTriangles() const { return triangles_; }

  // Tearing (yarn_woven_tearing.cpp, docs/yarn_model.md "Tearing").
  /// Segments torn so far.
  std::size_t tornSegmentCount() const { return tears_.torn.size(); }
  /// The two nodes of every torn segment (by segment index, not in the order they tore).
  std::vector<std::array<Index, 2>> tornSegmentNodes() const;
  /// Largest tension T = k_s (l / D - 1) over the intact segments of state x [N] (of the simulated
  /// yarn: a bundle's tension is n times a real yarn's).
  Real maxSegmentTension(const VecX& x) const;

 private:
  /// One kernel's stencil: its nodes along one yarn piece, the DOFs of its 4 n coordinates (a DOF
  /// modulo 5 is its node-local coordinate: the sliding one may differ per node on a seam), and the
  /// block slots of every node pair (row-major, n x n).
  struct Stencil {
    int nodes = 0;
    std::array<Index, 3> node{};
    std::array<std::size_t, 12> dof{};
    std::array<Index, 9> slot{};
    bool torn = false;  ///< a torn segment, or a bending stencil spanning one: no longer acts
  };
  /// One (warp segment, weft segment) pair at a crossing: nodes (crossing, warp neighbour, weft
  /// neighbour), whether jamming applies, and the block slots of the 3 x 3 node pairs.
  struct ShearPair {
    std::array<Index, 3> node{};
    bool interlaced = false;
    std::array<Index, 9> slot{};
    bool torn = false;  ///< one of its two segments is torn: no angle left, the pair no longer acts
  };
  /// A free sliding DOF of a crossing: where sliding friction acts.
  struct SlidingDof {
    Eigen::Index dof = 0;
    std::size_t crossing = 0;
  };
  /// Two crossings neighbouring along one yarn: their sliding DOFs on it (lower arc length first), the
  /// contact distance d and the block slots (00, 01, 10, 11).
  struct ContactPair {
    std::array<std::size_t, 2> dof{};
    std::array<Index, 2> node{};
    Real distance = 0;
    std::array<Index, 4> slot{};
    bool torn = false;  ///< the segment between the two crossings is torn: no longer acts
  };
  /// Adds scale times the Hessian of stretch and bending (clamped or exact), held DOFs left out.
  void assembleHessian(const VecX& q, bool clamped, Real scale, BlockSparseMatrix& a) const;
  /// The diagonal entry of `dof` in a matrix on the model's pattern.
  Real& diagonalEntry(BlockSparseMatrix& a, std::size_t dof) const;
  // Crossing terms (yarn_woven_crossings.cpp).
  void buildCrossingTerms(const std::vector<std::array<Index, 4>>& around);
  /// sliding_dofs_: every sliding DOF of a crossing that is not held.
  void collectSlidingDofs();
  void updateCompression(const VecX& q);
  /// The lagged F_n at a pair's crossing (0 before the first evaluation).
  Real pairCompression(const ShearPair& p) const;
  /// The pair's shear term: k_x (1 + c_n F_n), L, phi_j, c_j and whether it jams.
  yarn::ShearParameters shearParameters(const ShearPair& p, Real F_n) const;
  Real crossingEnergy(const VecX& q) const;
  /// Which crossing terms addCrossingForces() adds: the conservative ones (forces and Jacobians, or
  /// with kConservativeForceTerms their forces only) and friction (forces and Jacobians).
  enum CrossingTerms { kConservativeTerms = 1, kFrictionTerms = 2, kAllCrossingTerms = 3, kConservativeForceTerms = 4 };
  /// Adds the chosen crossing terms' forces into f (all DOFs; held ones are zeroed by the caller) and,
  /// with `dfdx` / `dfdv`, their Jacobians times `scale` (held rows and columns left out).
  void addCrossingForces(const VecX& q, const VecX& v, VecX* f, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv,
                         bool clamped, int terms, Real scale) const;
  /// Adds scale times gravity's (constant) Hessian.
  void addGravityHessian(Real scale, BlockSparseMatrix& a) const;
  // Tearing (yarn_woven_tearing.cpp).
  /// The torn set and what it needs to be re-derived: the laid sheet's pieces and held DOFs, kept from
  /// the first change of the sheet on.
  struct TearRecord {
    std::vector<std::size_t> torn;  ///< indices into segments_, ascending
    bool intact_saved = false;
    std::vector<YarnPiece> intact_pieces;
    std::vector<std::size_t> intact_held;
  };
  Real segmentTension(const VecX& q, const Stencil& s) const;
  /// The segments to tear after a step at q: in every run of intact segments along a yarn, the one
  /// under the largest tension if that is above the threshold.
  std::vector<std::size_t> overloadedSegments(const VecX& q) const;
  /// Tears overloaded segments (acceptStep) and zeroes the velocities of the sliding DOFs it holds.
  void tearOverloadedSegments(const VecX& q, VecX& v);
  /// Re-derives all that the torn set decides: stencil and crossing-term flags, the sheet's split
  /// pieces and held DOFs, held_ and the free sliding DOFs.
  void applyTornSegments();
  /// Reads the torn-segment suffix of an internal state after its first `base` values (empty suffix:
  /// none torn). False if malformed.
  bool readTornSegments(const std::vector<Real>& state, std::size_t base, std::vector<std::size_t>* torn) const;
  /// A torn segment's two halves: rho D / 2 on each node's position (lumped), at kernel coordinates q.
  void addTornSegmentMass(const VecX& q, Real scale, BlockSparseMatrix& a) const;
  void addTornSegmentMassProduct(const VecX& q, const VecX& v, VecX& mv) const;
  /// The torn segments' weight (their gravity terms, whose arc lengths no longer move) [J].
  Real tornSegmentWeightEnergy(const VecX& q) const;
  // Penalty self-contact (yarn_woven_self_contact.cpp).
  void buildSelfContact();
  void detectSelfContacts(const VecX& x);
  /// Adds the contacts' forces into f and their diagonal Jacobian blocks into dfdx and dfdv (each if not null).
  void addSelfContactForces(const VecX& x, const VecX& v, VecX* f, BlockSparseMatrix* dfdx, BlockSparseMatrix* dfdv) const;
  Real selfContactEnergy(const VecX& x) const;
  void acceptSelfContacts(const VecX& x);
  void appendSelfContactState(std::vector<Real>& s) const;
  /// Reads the self-contact part of an internal state from `from` and sets *end past it; false if
  /// malformed (nothing changed).
  bool readSelfContactState(const std::vector<Real>& s, std::size_t from, std::vector<yarn::PenaltyContact>* contacts,
                            bool* detected, std::size_t* end) const;
  template <int Nodes>
  static std::array<std::size_t, 4 * Nodes> dofsOf(const Stencil& s);
  template <int Nodes, class Matrix>
  /// Adds scale m into a's blocks of the stencil's free DOFs, in the rows of nodes `rows` owns only.
  void scatterBlocks(const Matrix& m, const Stencil& s, Real scale, BlockSparseMatrix& a, const RowShare& rows) const;
  /// Adds kernel(s) (4 Nodes entries, a torn stencil's included) of every stencil s of `list` into
  /// `out` on all threads in stencil order (ordered_parallel.h); a vector with a NaN or infinity is
  /// left out and counted in `degenerate`, or added as it is when `degenerate` is null.
  template <int Nodes, class Kernel>
  void addStencilVectors(const std::vector<Stencil>& list, VecX& out, std::atomic<Index>* degenerate, Kernel&& kernel) const;
  /// Adds scale kernel(s) (a 4 Nodes x 4 Nodes matrix) of every untorn stencil s of `list` into a, on
  /// all threads in stencil order; with skip_non_finite, a matrix with a NaN or infinity (a degenerate
  /// term) is left out instead of added.
  template <int Nodes, class Kernel>
  void addStencilMatrices(const std::vector<Stencil>& list, Real scale, bool skip_non_finite, BlockSparseMatrix& a,
                          Kernel&& kernel) const;

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
  // Crossing terms: stencils, constants, lagged compression and friction anchors.
  std::vector<ShearPair> shear_pairs_;
  std::vector<ContactPair> contacts_;
  std::vector<SlidingDof> sliding_dofs_;
  Real k_x_ = 0, k_f_ = 0, d_f_ = 0, k_fphi_ = 0, mu_phi_ = 0, c_n_ = 0, k_c_ = 0, spacing_ = 0;
  WovenFabric compression_fabric_;     ///< bending scaled by n^3: a bundle crossing's n^2 real crimps
  std::vector<Real> compression_;      ///< F_n per crossing, lagged
  VecX slide_anchor_;                  ///< per DOF (sliding DOFs of crossings used), as displacements
  std::vector<Real> angle_anchor_;     ///< per shear pair [rad]
  TearRecord tears_;
  BlockSparseMatrix stiffness_;  // the clamped Hessian K(x) of the elastic terms (clamped df/dx)
  // Rayleigh damping held over a step: K and M at the first state computeForces() sees after
  // construction, acceptStep() or setInternalState() - the step's start state.
  BlockSparseMatrix damping_stiffness_;  // K(x_n); allocated only when beta > 0
  VecX damping_positions_;               // x_n, the positions of the damping's mass matrix
  bool damping_stale_ = true;
  VecX damping_;                 // K v and M v of the damping force, reused
  // Penalty self-contact: triangles, constants, the contacts of the last accepted step.
  yarn::YarnTriangles triangles_;
  std::vector<yarn::PenaltyContact> self_contacts_;
  bool self_contacts_detected_ = false;
  Real gamma_ = 0, k_p_ = 0, d_p_ = 0, mu_p_ = 0;
  // Which thread adds which stencils' rows (ordered_parallel.h): one schedule per stencil list
  // (segments, bends, shear pairs), rebuilt on use when the thread count changes; owned through a
  // pointer so that const methods can rebuild it. Not shared between models.
  struct StencilSchedules;
  std::unique_ptr<StencilSchedules> schedules_;
  RowRangeSchedule& schedule(const std::vector<Stencil>& list) const;
  RowRangeSchedule& shearPairSchedule() const;
};

}  // namespace textile_handling
