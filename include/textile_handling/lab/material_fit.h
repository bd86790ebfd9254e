// Material fitting across scales: the material a cheaper cloth model needs to reproduce another model's
// virtual fabric tests, typically the yarn-level model's (docs/material_lab.md, "Fitting").
#pragma once

#include <string>
#include <vector>

#include "textile_handling/lab/lab_material.h"

namespace textile_handling {
namespace lab {

struct MaterialFitOptions {
  int max_iterations = 8;
  /// Converged when every fitted figure (B per direction, G, the tensile figure) is within this relative error.
  Real tolerance = 0.01;
  /// The tensile figure: the strain at this force per width [gf/cm] on the loading curve. A drape loads
  /// cloth with its own weight, a few gf/cm (5 gf/cm = 4.9 N/m, the top of 2 m of 250 g/m^2 cotton), far
  /// below KES's F_max of 500 gf/cm, and a law of another shape (the particle model's quartic F = Y e^4
  /// against the yarn model's nearly linear curve) that matches at F_max is 100 times too stretchy there.
  /// 0 = fit EMT (the strain at F_max) instead.
  Real tension_force_gf_per_cm = 5;
  KesBendingProtocol bending;
  KesShearProtocol shear;
  KesTensileProtocol tensile;
};

/// One fitted figure: the target model's value and the fitted model's after the last iteration.
struct FittedFigure {
  std::string name;  ///< B_warp, B_weft, G, and strain_at_<F>gf_cm or EMT
  Real target = 0;
  Real fitted = 0;
  Real factor = 1;   ///< scale of the starting material's curve (or tension stiffness) that gives it
};

struct MaterialFitResult {
  Material material;         ///< the fitted material (a normal material file for the fitted model)
  LabReport fitted;          ///< the fitted model's lab run on `material`
  std::vector<FittedFigure> figures;
  int iterations = 0;        ///< lab runs of the fitted model
  bool converged = false;    ///< every figure within options.tolerance
};

/// Fits a material for `model` (run at `spacing`) to the lab figures of `target`, which must hold the
/// bending test in both directions, the shear test and the tensile test. Start: measuredMaterial(target)
/// (its curves; density of the target model). Then, per iteration, the lab runs `model` on the material
/// and each figure's factor is updated by a power-law secant step in log space: the warp and weft
/// bending curves for B_warp and B_weft, both shear curves together for the mean G (the particle-level
/// models shear with the mean of the two curves), and the tension stiffness for the mean strain at
/// options.tension_force_gf_per_cm (or the mean EMT).
/// The curves keep the target's shape; a model whose response has another shape (Choi-Ko's bending is
/// soft below 0.3 1/cm) matches the figures, not the whole curves. Throws MaterialLabError if `target`
/// lacks a test, and the lab's errors.
MaterialFitResult fitMaterial(const LabReport& target, const ClothModelSpec& model, Real spacing,
                              const std::string& name, const MaterialFitOptions& options = {});

}  // namespace lab
}  // namespace textile_handling
