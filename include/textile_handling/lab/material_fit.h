// Material fitting across scales: the material a cheaper cloth model needs to reproduce another model's
// virtual fabric tests, typically the yarn-level model's (docs/material_lab.md, "Fitting").
#pragma once

#include <string>
#include <vector>

#include "textile_handling/lab/lab_material.h"

namespace textile_handling {
namespace lab {

/// The figure each bending curve's factor is fitted to.
enum class BendingFitFigure {
  /// KES-FB2's B per direction: the slope at 0.5-1.5 1/cm of the moment on an imposed arc.
  kKesB,
  /// The ASTM D1388 cantilever's flexural rigidity w c^3 per direction: a free strip bent by its own weight,
  /// at the gentle curvatures of a drape and with the model's own in-plane response. A model whose imposed-arc
  /// moment and free-strip stiffness differ (Choi-Ko: the cantilever reads about half its material's curve,
  /// docs/material_lab.md) drapes like the target only when fitted this way.
  kCantilever,
};

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
  BendingFitFigure bending_figure = BendingFitFigure::kKesB;
  KesBendingProtocol bending;
  KesShearProtocol shear;
  KesTensileProtocol tensile;
  CantileverProtocol cantilever;  ///< used with BendingFitFigure::kCantilever
};

/// One fitted figure: the target model's value and the fitted model's after the last iteration.
struct FittedFigure {
  /// B_warp, B_weft (or cantilever_rigidity_warp, _weft [N m]), G, and strain_at_<F>gf_cm or EMT
  std::string name;
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

/// Fits a material for `model` (with its options, run at `spacing`) to the lab figures of `target`, which
/// must hold the bending test in both directions (with BendingFitFigure::kCantilever: the cantilever test in
/// both directions), the shear test and the tensile test. Start: measuredMaterial(target) (its curves;
/// density of the target model). Then, per iteration, the lab runs `model` on the material and each
/// figure's factor is updated by a power-law secant step in log space: the warp and weft bending curves for
/// B_warp and B_weft (or the cantilever rigidities), both shear curves together for the mean G (the
/// particle-level models shear with the mean of the two curves), and the tension stiffness for the mean
/// strain at options.tension_force_gf_per_cm (or the mean EMT).
/// The curves keep the target's shape; a model whose response has another shape (Choi-Ko's bending is
/// soft below 0.3 1/cm) matches the figures, not the whole curves. Throws MaterialLabError if `target`
/// lacks a test, and the lab's errors.
MaterialFitResult fitMaterial(const LabReport& target, const ClothModelSpec& model, Real spacing,
                              const std::string& name, const MaterialFitOptions& options = {});

}  // namespace lab
}  // namespace textile_handling
