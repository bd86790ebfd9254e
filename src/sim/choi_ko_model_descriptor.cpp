// Registration of the Choi-Ko model (choi_ko) with the cloth model registry: its option keys (the
// scene file's model: section, docs/choi_ko.md), their validation, the factory and the parameter lines
// of a database build.
#include "textile_handling/sim/choi_ko_model.h"
#include "textile_handling/sim/cloth_model_registry.h"

namespace textile_handling {

namespace {
const std::vector<std::pair<std::string, ChoiKoBending>> kBendingVersions = {{"beam", ChoiKoBending::kBeam},
                                                                             {"plate", ChoiKoBending::kPlate}};
const std::vector<std::pair<std::string, choi_ko::BendingJacobian>> kBendingJacobians = {
    {"secant", choi_ko::BendingJacobian::kSecant},
    {"drop_negative", choi_ko::BendingJacobian::kDropNegative},
    {"exact", choi_ko::BendingJacobian::kExact}};

template <typename T>
std::string nameOf(const std::vector<std::pair<std::string, T>>& choices, T value) {
  for (const auto& c : choices)
    if (c.second == value) return c.first;
  return "unknown";
}

ChoiKoOptions parseChoiKoOptions(const std::map<std::string, std::string>& values) {
  ChoiKoOptions o;
  ModelOptionReader r("choi_ko", values);
  r.readBool("gravity", &o.gravity);
  r.readBool("drag", &o.drag);
  r.readBool("shear", &o.shear);
  r.readBool("bending", &o.bending);
  r.readReal("settle_damping_per_s", 0, false, &o.settle_damping);
  r.readChoice("bending_version", kBendingVersions, &o.bending_version);
  r.readChoice("bending_jacobian", kBendingJacobians, &o.bending_jacobian);
  r.readReal("buckling_onset", 0, true, &o.buckling_onset);
  if (!(o.buckling_onset < 1)) throw ClothModelError("'model.buckling_onset' must be < 1 (model choi_ko)");
  r.readReal("buckling_onset_curvature_per_m", 0, true, &o.buckling_onset_curvature);
  if (values.count("buckling_onset") && values.count("buckling_onset_curvature_per_m"))
    throw ClothModelError("'model.buckling_onset' and 'model.buckling_onset_curvature_per_m' exclude each other (model choi_ko)");
  r.readReal("tensile_stiffness_N_m", 0, true, &o.tensile_stiffness);
  r.readReal("reference_strain", 0, true, &o.reference_strain);
  r.finish();
  return o;
}
}  // namespace

ClothModelDescriptor choiKoModelDescriptor() {
  ClothModelDescriptor d;
  d.name = "choi_ko";
  d.summary = "Choi-Ko buckling model with hysteresis (docs/choi_ko.md)";
  d.dofs_per_node = 3;
  d.option_keys = {{"gravity", "true | false"},
                   {"drag", "true | false: quadratic air drag"},
                   {"shear", "true | false"},
                   {"bending", "true | false"},
                   {"settle_damping_per_s", "mass-proportional damping [1/s], >= 0 (default 0)"},
                   {"bending_version", "beam | plate"},
                   {"bending_jacobian", "secant | drop_negative | exact"},
                   {"buckling_onset", "s* in (0, 1)"},
                   {"buckling_onset_curvature_per_m", "kappa* [1/m] > 0: the onset of a beam bent to kappa* on the model's grid (replaces buckling_onset)"},
                   {"tensile_stiffness_N_m", "E_t [N/m], > 0 (default: from the material)"},
                   {"reference_strain", "strain of the secant E_t, > 0"}};
  d.parse_options = [](const std::map<std::string, std::string>& v) { return std::any(parseChoiKoOptions(v)); };
  d.create = [](const ParticleTopology& topology, const Material& material, const std::any& options) {
    return std::unique_ptr<ClothModel>(
        new ChoiKoClothModel(topology, material, std::any_cast<const ChoiKoOptions&>(options)));
  };
  d.fingerprint = [](const std::any& options) {
    const auto& o = std::any_cast<const ChoiKoOptions&>(options);
    ClothModelFingerprint f;
    f.lines.push_back("bending_version: " + nameOf(kBendingVersions, o.bending_version));
    f.lines.push_back("bending_jacobian: " + nameOf(kBendingJacobians, o.bending_jacobian));
    f.lines.push_back(std::string("forces: ") + (o.gravity ? "gravity " : "") + (o.drag ? "drag " : "") +
                      (o.stretch ? "stretch " : "") + (o.shear ? "shear " : "") + (o.bending ? "bending" : ""));
    f.numbers.emplace_back("model_options.settle_damping_per_s", o.settle_damping);
    f.numbers.emplace_back("model_options.buckling_onset", o.buckling_onset);
    // Only when set, so that the builds of every other configuration keep their parameter text (and resume).
    if (o.buckling_onset_curvature > 0)
      f.numbers.emplace_back("model_options.buckling_onset_curvature_per_m", o.buckling_onset_curvature);
    f.numbers.emplace_back("model_options.tensile_stiffness_N_m", o.tensile_stiffness);
    f.numbers.emplace_back("model_options.reference_strain", o.reference_strain);
    return f;
  };
  return d;
}

}  // namespace textile_handling
