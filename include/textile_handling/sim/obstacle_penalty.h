// Obstacles (planes, boxes, spheres) as penalty forces inside the model, instead of the post-step
// position pass: a ClothModel decorator for any model (docs/collision.md, "Obstacles as penalty
// forces"). Scene key `obstacles.method: penalty`. ROS-free.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/collision_obstacles.h"

namespace textile_handling {

struct ObstaclePenaltyOptions {
  /// gamma: a node closer than this to a surface, or inside, is pushed out by the penalty [m] (the
  /// scene's `obstacles.contact_distance_m`); > 0.
  Real thickness = 1e-3;
  /// k = factor * m g / gamma with m the mean node mass: a node's own weight presses it in by gamma /
  /// factor (a node carrying the weight of n nodes, by n gamma / factor); > 0.
  Real stiffness_factor = 1000;
  /// c = ratio * 2 sqrt(k m): the damping of the normal velocity relative to the obstacle as a ratio to
  /// critical damping of a node on the penalty spring; >= 0.
  Real damping_ratio = 1;
  /// Coulomb coefficient of the friction on the surface (the scene's `obstacles.friction`); >= 0, 0 =
  /// frictionless.
  Real friction = 0;
  /// epsilon_v: below this tangential speed relative to the obstacle the friction is viscous, reaching
  /// mu F_n at it, so a node whose drive stays below the Coulomb limit creeps at less than epsilon_v
  /// instead of sticking exactly [m/s]; > 0.
  Real stick_speed = 1e-4;
};

/// Empty if valid, else what is wrong (naming the field).
std::string obstaclePenaltyErrors(const ObstaclePenaltyOptions& o);

/// The surface of one obstacle nearest to a point: signed distance (negative inside) [m], outward unit
/// normal there, and the obstacle's velocity.
struct ObstacleSurfacePoint {
  Real distance = 0;
  Vec3 normal = Vec3::UnitZ();
  Vec3 velocity = Vec3::Zero();
};
/// `p.normal` must be a unit vector.
ObstacleSurfacePoint nearestSurface(const PlaneObstacle& p, const Vec3& x);
/// Outside: the distance to the box and the direction from its nearest point (rounded edges and
/// corners); inside: minus the depth below the nearest face and that face's normal.
ObstacleSurfacePoint nearestSurface(const BoxObstacle& b, const Vec3& x);
/// At the centre itself the normal is +z.
ObstacleSurfacePoint nearestSurface(const SphereObstacle& s, const Vec3& x);

/// A cloth model plus penalty contact with rigid obstacles, on every free node's position (its first
/// three DOFs). For a node at signed distance d from an obstacle with outward normal n, penetration
/// delta = gamma - d > 0 and tangential velocity u = P (v - v_obstacle) (P = I - n n^T):
///   normal force    F_n n = k delta n                           (energy 1/2 k delta^2)
///   damping         -c (n . (v - v_obstacle)) n
///   friction        -mu F_n u / max(|u|, epsilon_v): Coulomb's mu F_n against the sliding direction,
///                   regularised to a viscous force below epsilon_v (no anchors, no state).
/// Jacobians on the node's diagonal block: df/dx = -k n n^T (exact on a plane or a box face; the
/// curvature term of spheres and rounded box edges, of order k delta / radius, and the friction's
/// dependence on x through F_n and n are left out); df/dv = -c n n^T - mu F_n / max(|u|, epsilon_v) P:
/// exact below epsilon_v, and above it the secant, exact across the sliding direction (along it the
/// exact derivative is 0, and a constant friction force in a linearised step reverses a slowing node
/// instead of stopping it). Pinned nodes feel nothing.
/// Contacts are found at every force evaluation; nodes are independent (parallel, deterministic).
class ObstaclePenaltyModel : public ClothModel {
 public:
  /// Throws SimError for invalid options, a node mask of the wrong size, or bad obstacles (as
  /// ObstaclePass). `node_pinned` has one entry per node.
  ObstaclePenaltyModel(std::unique_ptr<ClothModel> base, std::vector<char> node_pinned,
                       std::vector<PlaneObstacle> planes, std::vector<BoxObstacle> boxes,
                       std::vector<SphereObstacle> spheres, const ObstaclePenaltyOptions& options);

  ClothModel& base() { return *base_; }
  const ClothModel& base() const { return *base_; }
  Real stiffness() const { return k_; }
  Real damping() const { return c_; }
  /// Free nodes in contact (delta > 0) with any obstacle at x.
  Index contactsAt(const VecX& x) const;

  std::string name() const override { return base_->name(); }
  Index numNodes() const override { return base_->numNodes(); }
  int dofsPerNode() const override { return base_->dofsPerNode(); }
  const VecX& massPerDof() const override { return base_->massPerDof(); }
  bool hasLumpedMass() const override { return base_->hasLumpedMass(); }
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override { base_->addMassMatrix(x, scale, a); }
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override { base_->multiplyMass(x, v, mv); }
  bool solveMass(const VecX& x, const VecX& f, const std::vector<char>& pinned, VecX& a) const override {
    return base_->solveMass(x, f, pinned, a);
  }
  Real kineticEnergy(const VecX& x, const VecX& v) const override { return base_->kineticEnergy(x, v); }
  Real gravitationalEnergy(const VecX& x) const override { return base_->gravitationalEnergy(x); }
  Real totalMass() const override { return base_->totalMass(); }
  const BlockPattern& jacobianPattern() const override { return base_->jacobianPattern(); }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  /// The wrapped model's plus 1/2 k delta^2 per contact (friction is not conservative).
  Real potentialEnergy(const VecX& x) const override;
  Vec3 nodePosition(const VecX& x, Index node) const override { return base_->nodePosition(x, node); }
  Real maxEdgeStretch(const VecX& x) const override { return base_->maxEdgeStretch(x); }
  std::vector<DrawnYarn> drawnYarns() const override { return base_->drawnYarns(); }
  void acceptStep(const VecX& x, VecX& v) override { base_->acceptStep(x, v); }
  std::vector<Real> internalState() const override { return base_->internalState(); }
  bool setInternalState(const std::vector<Real>& state) override { return base_->setInternalState(state); }

 private:
  Index obstacleCount() const { return static_cast<Index>(planes_.size() + boxes_.size() + spheres_.size()); }
  /// Obstacles are numbered planes, then boxes, then spheres.
  ObstacleSurfacePoint surface(Index obstacle, const Vec3& x) const;
  /// delta = gamma - d of a node against an obstacle at state x (> 0: in contact).
  Real penetration(const VecX& x, Index node, Index obstacle) const;

  std::unique_ptr<ClothModel> base_;
  std::vector<char> pinned_;
  std::vector<PlaneObstacle> planes_;
  std::vector<BoxObstacle> boxes_;
  std::vector<SphereObstacle> spheres_;
  ObstaclePenaltyOptions options_;
  Real k_ = 0, c_ = 0;
};

}  // namespace textile_handling
