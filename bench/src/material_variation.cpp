#include "textile_handling/bench/material_variation.h"

#include <vector>

namespace textile_handling {
namespace bench {

MaterialCurve scaledCurve(const MaterialCurve& c, double k) {
  if (c.kind() == MaterialCurve::Kind::kTable) {
    std::vector<Real> y = c.tableY();
    for (Real& v : y) v *= k;
    return MaterialCurve::table(c.tableX(), y);
  }
  std::vector<std::vector<Real>> coef = c.coefficients();
  for (auto& piece : coef)
    for (Real& v : piece) v *= k;
  return MaterialCurve::polynomial(c.breakpoints(), coef);
}

Material scaledMaterial(const Material& base, double bending, double shear, double density, const std::string& name) {
  Material m = base;
  m.name = name;
  m.bend_warp = scaledCurve(base.bend_warp, bending);
  m.bend_weft = scaledCurve(base.bend_weft, bending);
  m.shear_warp = scaledCurve(base.shear_warp, shear);
  m.shear_weft = scaledCurve(base.shear_weft, shear);
  m.areal_density = base.areal_density * density;
  return m;
}

}  // namespace bench
}  // namespace textile_handling
