// Test pieces of the material lab (private to src/lab): a rectangle of cloth on the sample's grid, built
// through the cloth model registry, and the kinematic cycle that the KES tests share.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "textile_handling/lab/material_lab.h"
#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {
namespace lab {

/// A rectangular specimen. Test coordinates: `a` runs along the tested yarn direction, `b` across it;
/// a warp specimen has (x, y) = (a, b) in the textile frame, a weft one (x, y) = (b, a).
struct Specimen {
  YarnDirection direction = YarnDirection::kWarp;
  ParticleGrid grid;
  std::unique_ptr<ClothModel> model;
  VecX x_rest;                 ///< the model's full state, flat at z = 0 (further DOFs at their rest value 0)
  std::vector<Real> a, b;      ///< test coordinates of every node [m]
  Real area = 0;               ///< sample area [m^2] (the nodes' cells)
  Real a_min = 0, a_max = 0;   ///< extent along the direction [m]
};

/// Builds the specimen a in [a_min, a_min + cells_a d], b in [0, cells_b d] (d = sample.spacing).
/// Throws MaterialLabError naming the field for a bad spacing, too few or too many cells, an invalid
/// material; ClothModelError from the registry.
Specimen makeSpecimen(const LabSample& sample, YarnDirection direction, Real a_min, int cells_a, int cells_b);

/// Number of cells of `length` [m] at spacing d (rounded, at least `min_cells`); throws MaterialLabError
/// naming `field` if length is not finite and positive.
int cellsFor(Real length, Real spacing, int min_cells, const char* field);

/// Node positions (3N, world = textile frame with z up) for test-frame positions (a, b, z) of every node.
using SpecimenMap = std::function<Vec3(Real a, Real b, Real q)>;

/// The instrument's generalised force at q for the imposed deformation `map`:
/// -(f . dx/dq + dE_gravity/dq), f the model's forces at rest velocity, dx/dq a central difference with
/// step dq. Commits the model's internal state at x(q) afterwards.
Real generalisedForce(Specimen& specimen, const SpecimenMap& map, Real q, Real dq);

/// Four specimens of (cells_a, cells_b), (2 cells_a, cells_b), (cells_a, 2 cells_b) and
/// (2 cells_a, 2 cells_b) cells, loaded alike. With a response R = e A + (edge terms proportional to the
/// side lengths) + (corner terms), the mixed second difference R22 - R21 - R12 + R11 is e times the
/// smallest specimen's area: the specimen's edges and corners (free yarn ends, half-width border rows,
/// ends without a bending hinge) cancel and the interior response per unit area remains.
class InteriorResponse {
 public:
  /// `centred`: the specimens run a in [-L/2, L/2] (the bending arc), else a in [0, L].
  InteriorResponse(const LabSample& sample, YarnDirection direction, int cells_a, int cells_b, bool centred);
  /// The interior generalised force per unit area at q (commits every specimen's internal state).
  Real at(const SpecimenMap& map, Real q, Real dq);

 private:
  std::vector<Specimen> specimens_;
  Real area_ = 0;
};

/// `sample` as settlingModelSpec() sets up a settle, for the keys the sample does not set: damping 4/s
/// where the model has `settle_damping_per_s` (an equilibrium does not depend on it) and the definite-fix
/// Jacobian where it has `jacobian` (implicit steps far from equilibrium need it).
LabSample settlingSample(const LabSample& sample);

/// The path 0 -> +max -> -max -> 0 in `steps_per_quarter` increments per quarter (4 n + 1 values).
std::vector<Real> symmetricCycle(Real max, int steps_per_quarter);

}  // namespace lab
}  // namespace textile_handling
