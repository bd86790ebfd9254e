// Scenes shared by the simulation tests.
#pragma once

#include "textile_handling/sim/drape_scene.h"

namespace textile_handling {
namespace sim_test_support {

/// A cotton square of side `side` [m] at spacing d, held at its upper-left corner ("corner") at
/// (0, 0, 1), released flat and at rest; the default model (particle_kes with its defaults).
inline DrapeSceneSpec heldSquareSpec(Real side, Real d) {
  TextileOutline t;
  t.name = "test_square";
  t.outline = {Vec2(0, 0), Vec2(side, 0), Vec2(side, side), Vec2(0, side)};
  t.named_points = {NamedPoint{"corner", "corner", Vec2(0, side)}};
  DrapeSceneSpec s;
  s.textile = t;
  s.material = Material::cotton();
  s.spacing = d;
  s.hold = {HoldPoint{"corner", Vec2::Zero()}};
  s.hold_position = Vec3(0, 0, 1);
  return s;
}

}  // namespace sim_test_support
}  // namespace textile_handling
