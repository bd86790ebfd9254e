// Materials varied for held-out simulations (benchmarks): the KES curves and the areal density scaled.
#pragma once

#include <string>

#include "textile_handling/sim/material.h"

namespace textile_handling {
namespace bench {

/// `curve` with every value (table entries or polynomial coefficients) multiplied by `factor`.
MaterialCurve scaledCurve(const MaterialCurve& curve, double factor);

/// `base` with both bending curves times `bending`, both shear curves times `shear`, the areal density
/// times `density`, named `name`.
Material scaledMaterial(const Material& base, double bending, double shear, double density, const std::string& name);

}  // namespace bench
}  // namespace textile_handling
