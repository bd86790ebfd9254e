// Contact-force feedback of the self-collision pass's proximity stage into the implicit solve: a
// ClothModel decorator (docs/collision.md, "Persistent contact"). ROS-free.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/self_collision_pass.h"

namespace textile_handling {

/// A cloth model that adds the contact forces of a SelfCollisionPass's proximity stage (the
/// multipliers of its last step, as forces) to the forces of another model, so that the implicit
/// solve of the next step sees the support the contacts give (docs/collision.md, "Persistent
/// contact"): without them every step lets the supported cloth sag and the pass pushes it back,
/// which at rest never stops. Everything else is forwarded. Creating one switches the pass to
/// contact-force feedback; the pass must stay alive as long as this model is used. The contact
/// forces are part of internalState(), so save/resume continues exactly.
class ContactForceModel : public ClothModel {
 public:
  ContactForceModel(std::unique_ptr<ClothModel> base, SelfCollisionPass& pass);
  ContactForceModel(ClothModel& base, SelfCollisionPass& pass);

  ClothModel& base() { return base_; }
  const ClothModel& base() const { return base_; }
  const SelfCollisionPass& pass() const { return pass_; }
  std::string name() const override { return base_.name(); }
  Index numNodes() const override { return base_.numNodes(); }
  int dofsPerNode() const override { return base_.dofsPerNode(); }
  const VecX& massPerDof() const override { return base_.massPerDof(); }
  bool hasLumpedMass() const override { return base_.hasLumpedMass(); }
  void addMassMatrix(const VecX& x, Real scale, BlockSparseMatrix& a) const override { base_.addMassMatrix(x, scale, a); }
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override { base_.multiplyMass(x, v, mv); }
  bool solveMass(const VecX& x, const VecX& f, const std::vector<char>& pinned, VecX& a) const override {
    return base_.solveMass(x, f, pinned, a);
  }
  Real kineticEnergy(const VecX& x, const VecX& v) const override { return base_.kineticEnergy(x, v); }
  Real gravitationalEnergy(const VecX& x) const override { return base_.gravitationalEnergy(x); }
  Real totalMass() const override { return base_.totalMass(); }
  const BlockPattern& jacobianPattern() const override { return base_.jacobianPattern(); }
  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override;
  Real potentialEnergy(const VecX& x) const override { return base_.potentialEnergy(x); }
  Vec3 nodePosition(const VecX& x, Index node) const override { return base_.nodePosition(x, node); }
  Real maxEdgeStretch(const VecX& x) const override { return base_.maxEdgeStretch(x); }
  std::vector<DrawnYarn> drawnYarns() const override { return base_.drawnYarns(); }
  void acceptStep(const VecX& x, VecX& v) override { base_.acceptStep(x, v); }
  std::vector<Real> internalState() const override;
  bool setInternalState(const std::vector<Real>& state) override;

 private:
  std::unique_ptr<ClothModel> owned_;
  ClothModel& base_;
  SelfCollisionPass& pass_;
  VecX ma_;  // contact forces M a, reused between evaluations
};

/// Wraps `model` in a ContactForceModel when the pass runs v3 with the proximity stage and
/// options().contact_forces (what a scene does), else returns it unchanged. `pass` must outlive the
/// returned model.
std::unique_ptr<ClothModel> withContactForces(std::unique_ptr<ClothModel> model, SelfCollisionPass& pass);

}  // namespace textile_handling
