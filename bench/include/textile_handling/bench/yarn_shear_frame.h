// A picture-frame shear test of the yarn_woven model (benchmark library, bench/): a square of yarns
// whose border crossings are clamped to a frame hinged at its corners. The frame closes the angle phi
// between its warp side (along x) and its weft side from pi / 2 in small steps and opens it again;
// after each step the sheet relaxes and the frame's load is read. Yarn lengths along the frame are
// kept, so the load is shear: the warp/weft angle at every crossing follows the frame's (notes
// section 6.3, "Shear-frame test"). docs/yarn_model.md, "Shear frame".
#pragma once

#include <iosfwd>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/woven_fabric.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {

struct ShearFrameSpec {
  YarnWovenOptions model;        ///< gravity is turned off by the test
  int yarns = 11;                ///< warp and weft yarns of the square (yarns x yarns crossings)
  Real min_angle = 0.8;          ///< smallest frame angle phi [rad] (pi / 2 = unsheared)
  Real angle_step = 0.02;        ///< change of phi per load step [rad]
  Real relax_time = 0.05;        ///< simulated time per load step [s]
  Real dt = 2e-3;                ///< fixed time step of the relaxation [s]
  bool unload = true;            ///< open the frame again to pi / 2 after closing it
};

/// One load step: the frame angle, the shear angle pi / 2 - phi, and the load.
struct ShearFramePoint {
  Real frame_angle = 0;   ///< phi [rad]
  Real shear_angle = 0;   ///< pi / 2 - phi [rad]
  bool loading = true;    ///< closing (true) or opening
  /// The frame's generalised load conjugate to the shear angle: the work the frame does per radian of
  /// shear on the sheet, sum over clamped crossings of -f_i . dx_i / d(shear) [N m] (f_i the sheet's
  /// internal force on the crossing at rest).
  Real moment = 0;
  Real kinetic_energy = 0;  ///< at the end of the relaxation [J]
};

/// Runs the protocol; throws SimError if a relaxation diverges.
std::vector<ShearFramePoint> runShearFrame(const ShearFrameSpec& spec);

/// Writes the points as CSV (weave,frame_angle_rad,shear_angle_rad,loading,moment_N_m,kinetic_energy_J).
void writeShearFrameCsv(std::ostream& os, const std::string& weave, const std::vector<ShearFramePoint>& points);

}  // namespace textile_handling
