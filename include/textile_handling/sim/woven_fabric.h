// Woven fabric for the yarn-level cloth model: the weave pattern (which yarn lies on top at each
// warp/weft crossing), the yarn densities and the yarn parameters, and their YAML form.
// Source: the yarn-level model's notes (../shared/reference/yarn-level-woven-cloth.md, sections 1.1,
// 1.3, 6.1 and 9); docs/yarn_model.md explains every key, default and unit.
//
// yaml-cpp is used only in woven_fabric.cpp; this header stays light.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Which yarn lies on top at each crossing, as a repeat: warp_on_top[i % rows][j % cols] for warp yarn
/// i and weft yarn j (true = the warp is on top, seen from the panel's warp x weft normal).
struct WeavePattern {
  std::string name;                          ///< "plain", "twill_2_2", "satin_5" or "custom"
  std::vector<std::vector<bool>> warp_on_top;  ///< rows x cols, every row the same length

  bool warpOnTop(std::size_t warp, std::size_t weft) const {
    const auto& row = warp_on_top[warp % warp_on_top.size()];
    return row[weft % row.size()];
  }
};

/// Largest custom repeat (rows and columns): real weaves repeat within a few dozen yarns.
constexpr std::size_t kMaxWeaveRepeat = 64;

/// The named weaves (notes section 1.3; the source does not say which twill or satin it used):
///   plain:     warp on top iff (i + j) mod 2 = 0;
///   twill_2_2: warp on top iff (i + j) mod 4 < 2;
///   satin_5:   weft on top iff (j - 2 i) mod 5 = 0, else warp on top (5-harness satin).
/// Throws SimError naming the weave and the known names for any other name ("custom" needs a matrix:
/// customWeave()).
WeavePattern namedWeave(const std::string& name);

/// A custom repeat from a 0/1 matrix (1 = warp on top). Throws SimError for an empty or ragged
/// matrix, an entry other than 0 or 1, or more than kMaxWeaveRepeat rows or columns.
WeavePattern customWeave(const std::vector<std::vector<int>>& matrix);

/// A woven fabric: weave, yarn spacing and yarn parameters, SI units. Defaults: the source's
/// sleeveless shirt (notes section 6.1: L = 1 mm, R = 0.25 mm, Y = 1e7 Pa, B = 1e-2, S = 1e4 Pa,
/// mu = 0.3, alpha = 10, beta = 0.05) with the linear density the notes propose for 100 g/m^2 at
/// 1 yarn/mm (section 9.1).
struct WovenFabric {
  WeavePattern weave = namedWeave("plain");
  Real warp_density_per_m = 1000;   ///< warp yarns per metre across the warp (their spacing is 1 / density)
  Real weft_density_per_m = 1000;   ///< weft yarns per metre across the weft
  Real yarn_radius_m = 0.25e-3;     ///< R; must stay below half of both spacings
  Real young_modulus_pa = 1e7;      ///< Y: stretch stiffness k_s = Y pi R^2 [N]
  /// B: bending stiffness k_b = B pi R^2 [N m^2]; the source's table value read as SI gives
  /// k_b = 2e-9 N m^2 for the shirts (so B acts in Pa m^2; notes section 6.1, "unit caveat").
  Real bending_modulus = 1e-2;
  Real shear_modulus_pa = 1e4;      ///< S: shear stiffness k_x = S R^2 [N m]
  Real sliding_friction = 0.3;      ///< mu: Coulomb coefficient of yarn sliding at a crossing
  Real damping_mass_per_s = 10;     ///< alpha: Rayleigh damping, mass-proportional [1/s]
  Real damping_stiffness_s = 0.05;  ///< beta: Rayleigh damping, stiffness-proportional [s]
  Real linear_density_kg_per_m = 5e-5;  ///< rho: yarn mass per length

  Real warpSpacing() const { return 1 / warp_density_per_m; }
  Real weftSpacing() const { return 1 / weft_density_per_m; }
  /// k_s = Y pi R^2 [N] (notes eq. 7).
  Real stretchStiffness() const;
  /// k_b = B pi R^2 [N m^2] (notes eq. 8).
  Real bendingStiffness() const;
  /// The jamming angle phi_j = 2 asin(R / L) for the smaller spacing L [rad] (notes eq. 11).
  Real jammingAngle() const;
};

/// Checks every field; returns an empty string if the fabric is usable, else one line per bad field,
/// each naming it ("yarn_radius_m 0.0006 must be below half the warp spacing 0.001 m", "weft_density_per_m
/// must be finite and > 0", ...). Densities above 1e5 per metre (10 yarns per mm) are refused: finer
/// than any woven fabric.
std::string wovenFabricErrors(const WovenFabric& fabric);

/// Throws SimError with wovenFabricErrors() if it is not empty.
void validateWovenFabric(const WovenFabric& fabric);

/// Parses a woven-fabric YAML document (format in docs/yarn_model.md): `type: woven_fabric`, `weave`
/// (a name, or `custom` with `weave_repeat`, a list of 0/1 rows), and the keys of WovenFabric's fields
/// by the same names, each optional (default as above). Unknown keys are refused with the list of known
/// ones. Throws MaterialError (material.h) naming `source` and the field for malformed text, a wrong
/// type, a document over kMaxYamlDocumentBytes, or a fabric wovenFabricErrors() refuses.
WovenFabric parseWovenFabricYaml(const std::string& text, const std::string& source = "<string>");

/// Reads and parses a woven-fabric YAML file (readBoundedTextFile() limits its size). Throws
/// MaterialError.
WovenFabric loadWovenFabricYaml(const std::string& path);

/// The YAML text of `fabric` (parseWovenFabricYaml() reads it back to the same fabric).
std::string wovenFabricToYaml(const WovenFabric& fabric);

}  // namespace textile_handling
