#include "textile_handling/sim/position_view_pass.h"

namespace textile_handling {

long PositionViewPass::apply(const VecX& x_old, VecX& x, VecX& v) {
  if (model_.dofsPerNode() == 3) return inner_.apply(x_old, x, v);
  p_old_ = model_.positionsOf(x_old);
  p_ = model_.positionsOf(x);
  pv_ = model_.positionsOf(v);  // the velocity DOFs have the same layout as the state
  const long events = inner_.apply(p_old_, p_, pv_);
  if (events != 0) {
    model_.setPositions(p_, x);
    model_.setPositions(pv_, v);
  }
  return events;
}

}  // namespace textile_handling
