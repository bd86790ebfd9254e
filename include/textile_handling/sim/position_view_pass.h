// Runs a post-step pass written for 3N position vectors (collision handling: obstacles, self-collision)
// on a model with more than three DOFs per node. The pass sees the node positions and their
// velocities; what it changes is scattered back into the position DOFs, and the model's other DOFs
// (sliding coordinates) are left as the integrator produced them.
#pragma once

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/drape_simulation.h"

namespace textile_handling {

class PositionViewPass : public PostStepPass {
 public:
  /// `inner` and `model` must outlive this pass.
  PositionViewPass(PostStepPass& inner, const ClothModel& model) : inner_(inner), model_(model) {}
  long apply(const VecX& x_old, VecX& x, VecX& v) override;

 private:
  PostStepPass& inner_;
  const ClothModel& model_;
  VecX p_old_, p_, pv_;
};

}  // namespace textile_handling
