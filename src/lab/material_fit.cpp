// Material fitting across scales (material_fit.h).
#include "textile_handling/lab/material_fit.h"

#include <cmath>

namespace textile_handling {
namespace lab {
namespace {

const KesBendingResult* findBending(const LabReport& r, YarnDirection d) {
  for (const auto& b : r.bending)
    if (b.direction == d) return &b;
  return nullptr;
}

const CantileverResult* findCantilever(const LabReport& r, YarnDirection d) {
  for (const auto& c : r.cantilever)
    if (c.direction == d) return &c;
  return nullptr;
}

// The bending figure of `r` in direction `d` under `figure`; the caller has checked that `r` holds that test.
Real bendingFigure(const LabReport& r, YarnDirection d, BendingFitFigure figure) {
  if (figure == BendingFitFigure::kCantilever) return findCantilever(r, d)->flexural_rigidity_Nm;
  return findBending(r, d)->B;
}

Real meanG(const LabReport& r) {
  Real g = 0;
  for (const auto& s : r.shear) g += s.G;
  return g / static_cast<Real>(r.shear.size());
}

// Strain [%] at force per width `force` [gf/cm] on the loading branch of a tensile cycle; 0 = EMT.
Real strainAt(const KesTensileResult& t, Real force) {
  if (force <= 0) return t.EMT;
  for (std::size_t k = 0; k + 1 < t.cycle.size() && t.cycle[k + 1].x > t.cycle[k].x; ++k) {
    const CurvePoint a = t.cycle[k], b = t.cycle[k + 1];
    if (a.y <= force && force <= b.y && b.y > a.y) return 100 * (a.x + (force - a.y) / (b.y - a.y) * (b.x - a.x));
  }
  throw MaterialLabError("fit: the tensile curve does not pass " + std::to_string(force) + " gf/cm while loading");
}

Real meanStrain(const LabReport& r, Real force) {
  Real e = 0;
  for (const auto& t : r.tensile) e += strainAt(t, force);
  return e / static_cast<Real>(r.tensile.size());
}

// "5", "2.5": a force for a figure name.
std::string figureText(Real v) {
  std::string t = std::to_string(v);
  t.erase(t.find_last_not_of('0') + 1);
  if (!t.empty() && t.back() == '.') t.pop_back();
  return t;
}

// One fitted quantity: its factor, the secant's memory and the response exponent guess.
struct Knob {
  Real target = 0;
  Real factor = 1;
  Real exponent = 1;  // d log(figure) / d log(factor), refined by the secant
  Real last_factor = 0, last_value = 0;

  // The next factor for the measured `value` at `factor`.
  void update(Real value) {
    if (last_factor > 0 && std::abs(std::log(factor / last_factor)) > 1e-9) {
      const Real p = std::log(value / last_value) / std::log(factor / last_factor);
      // Keep the sign of the first guess and a sane magnitude; a flat response would step forever.
      if (p * exponent > 0 && std::abs(p) > 0.05 && std::abs(p) < 20) exponent = p;
    }
    last_factor = factor;
    last_value = value;
    factor *= std::pow(target / value, 1 / exponent);
  }
};

}  // namespace

MaterialFitResult fitMaterial(const LabReport& target, const ClothModelSpec& model, Real spacing,
                              const std::string& name, const MaterialFitOptions& options) {
  const bool cantilever = options.bending_figure == BendingFitFigure::kCantilever;
  if (!findBending(target, YarnDirection::kWarp) || !findBending(target, YarnDirection::kWeft) || target.shear.empty() ||
      target.tensile.empty())
    throw MaterialLabError("fit: the target report needs bending in both directions, shear and tensile");
  if (cantilever && (!findCantilever(target, YarnDirection::kWarp) || !findCantilever(target, YarnDirection::kWeft)))
    throw MaterialLabError("fit: fitting the cantilever (fit.bending_figure) needs the target's cantilever in both directions");
  if (options.max_iterations < 1 || options.max_iterations > 50) throw MaterialLabError("fit.max_iterations must be in [1, 50]");
  if (!std::isfinite(options.tolerance) || !(options.tolerance > 0)) throw MaterialLabError("fit.tolerance must be finite and > 0");
  const Real force = options.tension_force_gf_per_cm;
  if (!std::isfinite(force) || force < 0) throw MaterialLabError("fit.tension_force_gf_per_cm must be finite and >= 0");
  const Real target_warp = bendingFigure(target, YarnDirection::kWarp, options.bending_figure);
  const Real target_weft = bendingFigure(target, YarnDirection::kWeft, options.bending_figure);
  for (const Real v : {target_warp, target_weft, meanG(target), meanStrain(target, force)})
    if (!std::isfinite(v) || !(v > 0))
      throw MaterialLabError("fit: the target's bending figures, G and tensile figure must be finite and > 0");

  const Material start = measuredMaterial(target, name);
  Knob kb_warp{target_warp}, kb_weft{target_weft}, kg{meanG(target)}, ke{meanStrain(target, force)};
  ke.exponent = -0.25;  // strain against Y under the particle model's quartic law; the secant corrects it
  MaterialFitResult result;
  LabSample sample;
  sample.model = model;
  sample.spacing = spacing;
  auto material = [&] {
    Material m = start;
    m.bend_warp = scaledCurve(start.bend_warp, kb_warp.factor);
    m.bend_weft = scaledCurve(start.bend_weft, kb_weft.factor);
    m.shear_warp = scaledCurve(start.shear_warp, kg.factor);
    m.shear_weft = scaledCurve(start.shear_weft, kg.factor);
    m.tension_stiffness = start.tension_stiffness * ke.factor;
    return m;
  };
  for (int it = 0; it < options.max_iterations; ++it) {
    LabReport run;
    // A model far too soft in tension never reaches F_max: stiffen by 10x (at most 8 times) until it does.
    for (int tries = 0;; ++tries) {
      sample.material = material();
      try {
        run.tensile = {runKesTensile(sample, YarnDirection::kWarp, options.tensile)};
        break;
      } catch (const MaterialLabError&) {
        if (tries == 8) throw;
        ke.factor *= 10;
        ke.last_factor = 0;
      }
    }
    const Material m = sample.material;
    run.sample = sample;
    // The KES bending runs in either case: with a cantilever fit it shows how the imposed-arc figure compares.
    run.bending = {runKesBending(sample, YarnDirection::kWarp, options.bending),
                   runKesBending(sample, YarnDirection::kWeft, options.bending)};
    if (cantilever)
      run.cantilever = {runCantilever(sample, YarnDirection::kWarp, options.cantilever),
                        runCantilever(sample, YarnDirection::kWeft, options.cantilever)};
    run.shear = {runKesShear(sample, YarnDirection::kWarp, options.shear)};
    result.material = m;
    result.fitted = run;
    result.iterations = it + 1;
    const Real values[4] = {bendingFigure(run, YarnDirection::kWarp, options.bending_figure),
                            bendingFigure(run, YarnDirection::kWeft, options.bending_figure), meanG(run),
                            meanStrain(run, force)};
    Knob* knobs[4] = {&kb_warp, &kb_weft, &kg, &ke};
    const std::string tensile_name = force > 0 ? "strain_at_" + figureText(force) + "gf_cm" : "EMT";
    const char* names[4] = {cantilever ? "cantilever_rigidity_warp" : "B_warp",
                            cantilever ? "cantilever_rigidity_weft" : "B_weft", "G", tensile_name.c_str()};
    result.figures.clear();
    bool all = true;
    for (int k = 0; k < 4; ++k) {
      result.figures.push_back({names[k], knobs[k]->target, values[k], knobs[k]->factor});
      if (!(std::abs(values[k] - knobs[k]->target) <= options.tolerance * knobs[k]->target)) all = false;
    }
    if (all) {
      result.converged = true;
      break;
    }
    for (int k = 0; k < 4; ++k)
      if (!(values[k] > 0) || !std::isfinite(values[k]))
        throw MaterialLabError(std::string("fit: the fitted model's ") + names[k] + " is not positive");
    for (int k = 0; k < 4; ++k) knobs[k]->update(values[k]);
  }
  return result;
}

}  // namespace lab
}  // namespace textile_handling
