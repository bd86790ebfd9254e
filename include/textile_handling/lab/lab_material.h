// What the material lab reports: the KES-style figures of its tests side by side with the values the
// material file implies, and the measured curves as a material file (docs/material_lab.md).
#pragma once

#include <limits>
#include <ostream>
#include <string>
#include <vector>

#include "textile_handling/lab/material_lab.h"

namespace textile_handling {
namespace lab {

/// The results of one lab run (any subset of the tests and directions).
struct LabReport {
  LabSample sample;
  std::vector<KesBendingResult> bending;
  std::vector<KesShearResult> shear;
  std::vector<KesTensileResult> tensile;
  std::vector<CantileverResult> cantilever;
  std::vector<DrapeCoefficientResult> drape;  ///< at most one (the test has no direction)
};

/// One figure: its KES name, direction, unit, the lab's value and the value the sample's material file
/// implies under the thesis's particle model laws (NaN where the file says nothing, e.g. 2HB).
struct LabFigure {
  std::string name;       ///< B, 2HB, G, 2HG, 2HG5, EMT, LT, WT, RT, c, G_cantilever, DC
  std::string direction;  ///< warp | weft | both (DC)
  std::string unit;
  Real value = 0;
  Real material_value = std::numeric_limits<Real>::quiet_NaN();
};

/// Every figure of `report`, test by test in the order bending, shear, tensile, cantilever, drape.
std::vector<LabFigure> labFigures(const LabReport& report);

/// CSV with header figure,direction,unit,lab,material_file,relative_difference (empty cells for NaN).
void writeFiguresCsv(std::ostream& os, const std::vector<LabFigure>& figures);

/// Mass per area [kg/m^2] of `sample`'s model (total mass of a small specimen over its area).
Real sampleArealDensity(const LabSample& sample);

/// A material for the particle-level models (particle_kes, choi_ko) with the lab's measured curves:
/// bending and shear curves are tables of the loading branch 0 -> max of each test (shifted so that
/// F(0) = 0; a direction not tested takes the other direction's curve), the tension stiffness Y is the
/// quartic law through (EMT, F_max) averaged over the tested directions, and the areal density is the
/// tested model's. Other fields, and curves of tests not run, come from report.sample.material.
/// Throws MaterialLabError if the result does not validate.
Material measuredMaterial(const LabReport& report, const std::string& name);

}  // namespace lab
}  // namespace textile_handling
