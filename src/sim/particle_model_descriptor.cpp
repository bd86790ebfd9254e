// Registration of the thesis's particle model (particle_kes) with the cloth model registry: its
// option keys (the scene file's model: section), their validation, the factory and the parameter
// lines of a database build.
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/particle_cloth_model.h"

namespace textile_handling {

namespace {
const std::vector<std::pair<std::string, JacobianMode>> kJacobianModes = {{"exact", JacobianMode::kExact},
                                                                          {"definite_fix", JacobianMode::kDefiniteFix}};

ParticleModelOptions parseParticleOptions(const std::map<std::string, std::string>& values) {
  ParticleModelOptions o;
  ModelOptionReader r("particle_kes", values);
  r.readChoice("jacobian", kJacobianModes, &o.jacobian);
  r.readBool("gravity", &o.gravity);
  r.readBool("drag", &o.drag);
  r.readBool("shear", &o.shear);
  r.readBool("bending", &o.bending);
  r.readReal("settle_damping_per_s", 0, false, &o.settle_damping);
  r.finish();
  return o;
}
}  // namespace

ClothModelDescriptor particleModelDescriptor() {
  ClothModelDescriptor d;
  d.name = "particle_kes";
  d.summary = "the thesis's particle model with KES curves (docs/simulation.md)";
  d.dofs_per_node = 3;
  d.option_keys = {{"jacobian", "exact | definite_fix: Hessian of the angle and tension terms"},
                   {"gravity", "true | false"},
                   {"drag", "true | false: quadratic air drag"},
                   {"shear", "true | false"},
                   {"bending", "true | false"},
                   {"settle_damping_per_s", "mass-proportional damping [1/s], >= 0"}};
  d.parse_options = [](const std::map<std::string, std::string>& v) { return std::any(parseParticleOptions(v)); };
  d.create = [](const ParticleTopology& topology, const Material& material, const std::any& options) {
    return std::unique_ptr<ClothModel>(
        new ParticleClothModel(topology, material, std::any_cast<const ParticleModelOptions&>(options)));
  };
  // The lines and their order are those database builds have always stored for this model, so that
  // existing databases resume.
  d.fingerprint = [](const std::any& options) {
    const auto& o = std::any_cast<const ParticleModelOptions&>(options);
    ClothModelFingerprint f;
    f.lines.push_back(std::string("jacobian: ") + (o.jacobian == JacobianMode::kExact ? "exact" : "definite_fix"));
    f.lines.push_back(std::string("forces: ") + (o.gravity ? "gravity " : "") + (o.drag ? "drag " : "") +
                      (o.shear ? "shear " : "") + (o.bending ? "bending" : ""));
    f.numbers.emplace_back("model_options.settle_damping_per_s", o.settle_damping);
    return f;
  };
  return d;
}

}  // namespace textile_handling
