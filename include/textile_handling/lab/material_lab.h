// The virtual material lab: the standard fabric tests run on any registered cloth model, so that a
// model's material can be read off the same way a textile's is measured (docs/material_lab.md).
//
//   KES-FB2 bending   runKesBending     a strip held on a circular arc of curvature kappa, cycled
//                                       0 -> +kappa_max -> -kappa_max -> 0; figures B, 2HB
//   KES-FB1 shear     runKesShear       a sheet sheared as a trellis (yarn lengths kept), cycled
//                                       0 -> +theta_max -> -theta_max -> 0; figures G, 2HG, 2HG5
//   KES-FB1 tensile   runKesTensile     a strip stretched along one yarn direction up to F_max, then
//                                       released; figures EMT, LT, WT, RT
//   ASTM D1388        runCantilever     a strip clamped at a platform edge droops under its weight; the
//                                       overhang whose tip reaches the 41.5 degree line is 2 c
//   BS 5058           runDrapeCoefficient a 30 cm disc of cloth on an 18 cm support drapes into folds;
//                                       DC = (shadow - support) / (sample - support)
//
// The three KES tests impose the instrument's ideal deformation on every node position (a model's further
// DOFs, such as a yarn crossing's sliding coordinates, keep their rest values) and read the instrument's
// force from the model's own forces by virtual work: Q(q) = -f(x(q), 0) . dx/dq - dE_gravity/dq per unit
// sample area. Along the cycle the model's internal state (hysteresis, friction anchors) is committed
// after every increment, so a model with hysteresis draws a loop. The cantilever is a static equilibrium
// of the free strip under gravity (solveStaticEquilibrium), so it also tests how the model deforms.
//
// Units: SI inside; the figures and curves come in the KES units of the package's material format
// (docs/materials.md): bending moment per width gf*cm/cm against curvature 1/cm, shear force per length
// gf/cm against shear angle (rad in the curves, degrees in G as KES reports it), tensile force per width
// gf/cm against strain.
#pragma once

#include <stdexcept>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/static_equilibrium.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace lab {

/// Every error of the lab core: a bad sample or protocol field (named in the message), or a test the
/// model could not complete (a static solve that did not converge, a curve that never reaches F_max).
class MaterialLabError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

/// What is tested: a cloth model (registry name and options) with a material, resolved at `spacing`.
struct LabSample {
  ClothModelSpec model;
  Material material = Material::cotton();
  Real spacing = 0.002;  ///< grid spacing d of the test pieces [m]
};

/// One measured point of a curve: abscissa (curvature 1/cm, shear angle rad or strain) and the
/// instrument's reading (gf*cm/cm or gf/cm).
struct CurvePoint {
  Real x = 0;
  Real y = 0;
};

/// The yarn direction a test loads: warp (the textile's x axis) or weft (y).
enum class YarnDirection { kWarp = 0, kWeft = 1 };
std::string toString(YarnDirection d);
/// Parses "warp", "weft"; throws MaterialLabError otherwise.
YarnDirection yarnDirectionFromString(const std::string& s);

// ---- KES-FB2 pure bending ---------------------------------------------------------------------------

struct KesBendingProtocol {
  Real length_cm = 1.0;           ///< sample length along the bending direction (KES-FB2: 1 cm)
  Real width_cm = 1.0;            ///< sample width (KES: 20 cm; the figures are per unit width)
  Real max_curvature_per_cm = 2.5;  ///< KES-FB2 cycles to +-2.5 1/cm
  int steps_per_quarter = 50;     ///< curvature increments from 0 to max_curvature
  /// Angle [deg] of the bending direction from the tested yarn direction, in [0, 90]. 0 is KES-FB2. At
  /// another angle (45 = bias bending) the arc is laid isometrically along that direction: surface
  /// distances kept, chords shortened to second order in kappa d.
  Real bias_deg = 0;
};

struct KesBendingResult {
  YarnDirection direction = YarnDirection::kWarp;
  /// The cycle 0 -> +max -> -max -> 0: curvature [1/cm], moment per width [gf*cm/cm].
  std::vector<CurvePoint> cycle;
  /// Bending rigidity B [gf*cm^2/cm]: the mean of the slopes of the loading branches (0 -> +max and
  /// 0 -> -max) between |kappa| = 0.5 and 1.5 1/cm.
  Real B = 0;
  /// Hysteresis 2HB [gf*cm/cm]: loop width at kappa = +1 and -1 1/cm, averaged.
  Real twoHB = 0;
};

/// Runs KES-FB2 on `sample` bending about the other yarn direction (a warp test bends the warp yarns).
/// Throws MaterialLabError for a bad protocol or sample, SimError from the model registry.
KesBendingResult runKesBending(const LabSample& sample, YarnDirection direction, const KesBendingProtocol& protocol = {});

// ---- KES-FB1 shear ----------------------------------------------------------------------------------

struct KesShearProtocol {
  Real length_cm = 2.0;           ///< sample extent along the clamps (KES: 20 cm)
  Real height_cm = 2.0;           ///< distance between the clamps (KES: 5 cm)
  Real max_angle_deg = 8.0;       ///< KES-FB1 cycles to +-8 degrees
  int steps_per_quarter = 80;
  /// Stretch [-] of the crossing yarns (across the clamps) held during the cycle. KES-FB1 shears under a
  /// tension of 10 gf/cm; with imposed deformation a strain stands for it (a model's tensile curve gives
  /// the strain of a tension). 0 = no pretension.
  Real pretension_strain = 0;
};

struct KesShearResult {
  YarnDirection direction = YarnDirection::kWarp;
  /// The cycle 0 -> +max -> -max -> 0: shear angle [rad], shear force per length [gf/cm].
  std::vector<CurvePoint> cycle;
  /// Shear rigidity G [gf/(cm*deg)]: mean loading-branch slope between |theta| = 0.5 and 5 degrees.
  Real G = 0;
  /// Hysteresis 2HG and 2HG5 [gf/cm]: loop width at |theta| = 0.5 and 5 degrees, averaged over the signs.
  Real twoHG = 0;
  Real twoHG5 = 0;
};

/// Runs KES-FB1 shear: the clamps lie along `direction`'s yarns (a warp test keeps the warp yarns
/// straight and turns the weft yarns). Throws as runKesBending.
KesShearResult runKesShear(const LabSample& sample, YarnDirection direction, const KesShearProtocol& protocol = {});

// ---- KES-FB1 tensile --------------------------------------------------------------------------------

struct KesTensileProtocol {
  Real length_cm = 1.0;            ///< gauge length (KES: 5 cm; uniform stretch makes it irrelevant)
  Real width_cm = 1.0;
  Real max_force_gf_per_cm = 500;  ///< KES-FB1 standard load
  Real strain_step = 2.5e-4;       ///< strain increment
  Real max_strain = 0.5;           ///< the test fails if F_max is not reached by this strain
};

struct KesTensileResult {
  YarnDirection direction = YarnDirection::kWarp;
  /// Loading then unloading: strain [-], force per width [gf/cm].
  std::vector<CurvePoint> cycle;
  Real EMT = 0;  ///< strain at F_max [%]
  Real LT = 0;   ///< linearity WT / (F_max EMT / 2) [-]
  Real WT = 0;   ///< tensile energy per area, loading [gf*cm/cm^2]
  Real RT = 0;   ///< resilience: unloading work / WT [%]
};

/// Runs KES-FB1 tensile along `direction` (uniaxial stretch of the node positions, no lateral
/// contraction). Throws as runKesBending; MaterialLabError if F_max is not reached by max_strain.
KesTensileResult runKesTensile(const LabSample& sample, YarnDirection direction, const KesTensileProtocol& protocol = {});

// ---- ASTM D1388 cantilever --------------------------------------------------------------------------

struct CantileverProtocol {
  Real width_m = 0.025;            ///< ASTM D1388: 25 mm
  Real angle_deg = 41.5;           ///< the inclined line of the instrument
  Real min_overhang_m = 0.005;     ///< search range of the overhang
  Real max_overhang_m = 0.5;
  Real settle_time_s = 10;         ///< cap of the dynamic settle used when a static solve from flat fails
  StaticEquilibriumSettings statics;  ///< force_tolerance 1e-4 (tighter than the solver's default), 200 iterations
  CantileverProtocol() { statics.force_tolerance = 1e-4; statics.max_iterations = 200; }
};

struct CantileverPoint {
  Real overhang_m = 0;   ///< length of the free strip beyond the edge
  Real angle_deg = 0;    ///< angle below the horizontal of the line from the edge to the tip
  int iterations = 0;    ///< Newton iterations of its static solve(s)
  bool settled_dynamically = false;  ///< the static solve from the flat strip failed; a dynamic settle came first
};

struct CantileverResult {
  YarnDirection direction = YarnDirection::kWarp;
  std::vector<CantileverPoint> samples;  ///< every overhang solved, in the order solved
  Real overhang_m = 0;          ///< overhang whose tip lies on the angle_deg line (interpolated)
  Real bending_length_m = 0;    ///< c = overhang / 2 (ASTM D1388; Peirce's relation at 41.5 degrees)
  /// Flexural rigidity G = w c^3 [N*m] with w the sample's weight per area (Peirce).
  Real flexural_rigidity_Nm = 0;
};

/// Runs the cantilever test along `direction`: overhangs on the spacing grid are solved until two
/// bracket the angle, then the overhang at the angle is interpolated linearly between them. Each
/// overhang is a static solve from the flat strip, or, if that fails, a dynamic settle (semi-implicit,
/// settling damping 4/s where the model has the key) finished by the static solve.
/// Throws MaterialLabError if no overhang in the range brackets the angle or a solve fails.
CantileverResult runCantilever(const LabSample& sample, YarnDirection direction, const CantileverProtocol& protocol = {});

// ---- Drape coefficient (BS 5058 / ISO 9073-9) -------------------------------------------------------

struct DrapeCoefficientProtocol {
  Real sample_diameter_m = 0.30;  ///< circular sample (BS 5058: 30 cm)
  Real disc_diameter_m = 0.18;    ///< support disc (BS 5058: 18 cm); the nodes on it are held
  /// Grid spacing of this test [m]; 0 = the sample's. A whole-sample shape, resolved like a database
  /// drape: 1 cm by default (the KES pieces need millimetres, this one does not).
  Real spacing_m = 0.01;
  /// Out-of-plane start noise [m] (fixed pseudo-random, from `seed`) that lets the folds choose their places.
  Real perturbation_m = 1e-3;
  unsigned seed = 1;
  Real max_time_s = 10;           ///< simulated-time cap of the settle
  Real shadow_pixel_m = 1e-3;     ///< pixel of the projected-area raster
};

struct DrapeCoefficientResult {
  Real drape_coefficient = 0;     ///< (A_shadow - A_disc) / (A_sample - A_disc) [-]
  Real shadow_area_m2 = 0;        ///< vertical projection of the draped sample
  Real sample_area_m2 = 0;        ///< the same projection of the flat sample
  Real disc_area_m2 = 0;          ///< the same projection of the cells held on the disc
  Index nodes = 0;
  bool rest_reached = false;      ///< false: the settle stopped at max_time_s (the figure is still reported)
  Real sim_time_s = 0;
  long steps = 0;
  Real wall_time_s = 0;
};

/// Drapes a circular sample over a disc (the nodes within the disc radius held flat, everything else
/// free under gravity) by a dynamic settle (semi-implicit, error-controlled steps, settling damping 4/s
/// where the model has the key) and measures the shadow area. Throws MaterialLabError for a bad protocol
/// or a diverged settle.
DrapeCoefficientResult runDrapeCoefficient(const LabSample& sample, const DrapeCoefficientProtocol& protocol = {});

// ---- What a material file implies -------------------------------------------------------------------

/// The KES-FB2 figure B [gf*cm^2/cm] of `material`'s bending curve in `direction`: (M(1.5) - M(0.5)) / 1.
Real materialKesB(const Material& material, YarnDirection direction);
/// The KES-FB1 figure G [gf/(cm*deg)] of `material`'s shear curve: (F(5 deg) - F(0.5 deg)) / 4.5.
Real materialKesG(const Material& material, YarnDirection direction);

/// The cantilever bending length [m] that `material`'s bending curve implies: the inextensible elastica
/// of a clamped strip under its own weight, M(kappa(s)) = w * integral of the lever arm beyond s (a
/// shooting method on the curve, 1000 RK4 arc steps), with the overhang whose tip lies on the angle_deg
/// line found by bisection; c = overhang / 2. For a linear curve M = B kappa this is (B/w)^(1/3) up to
/// the accuracy of Peirce's relation. Throws MaterialLabError if the curve is not increasing.
Real materialCantileverBendingLength(const Material& material, YarnDirection direction, Real angle_deg = 41.5);

}  // namespace lab
}  // namespace textile_handling
