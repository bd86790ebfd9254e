// Registration of the yarn-level woven cloth model (yarn_woven) with the cloth model registry: its
// option keys (the fabric: a YAML file and/or one key per field; docs/yarn_model.md), their validation,
// the factory on a particle grid (yarn bundles at the grid's spacing) and the parameter lines of a
// database build.
#include <sstream>

#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {

namespace {

const std::vector<std::pair<std::string, std::string>> kWeaves = {
    {"plain", "plain"}, {"twill_2_2", "twill_2_2"}, {"satin_5", "satin_5"}};

// The fabric's numeric keys: option key, field, lower bound, exclusive.
struct FabricKey {
  const char* key;
  Real WovenFabric::*field;
  Real min;
  bool exclusive;
};
const std::vector<FabricKey> kFabricKeys = {
    {"warp_density_per_m", &WovenFabric::warp_density_per_m, 0, true},
    {"weft_density_per_m", &WovenFabric::weft_density_per_m, 0, true},
    {"yarn_radius_m", &WovenFabric::yarn_radius_m, 0, true},
    {"young_modulus_pa", &WovenFabric::young_modulus_pa, 0, true},
    {"bending_modulus", &WovenFabric::bending_modulus, 0, true},
    {"shear_modulus_pa", &WovenFabric::shear_modulus_pa, 0, true},
    {"sliding_friction", &WovenFabric::sliding_friction, 0, false},
    {"damping_mass_per_s", &WovenFabric::damping_mass_per_s, 0, false},
    {"damping_stiffness_s", &WovenFabric::damping_stiffness_s, 0, false},
    {"linear_density_kg_per_m", &WovenFabric::linear_density_kg_per_m, 0, true},
};

struct ParsedYarnOptions {
  YarnWovenOptions model;
  std::string fabric_source = "defaults";  ///< the fabric file, or "defaults"
};

ParsedYarnOptions parseYarnOptions(const std::map<std::string, std::string>& values) {
  ParsedYarnOptions o;
  ModelOptionReader r("yarn_woven", values);
  std::string file;
  r.readText("fabric_file", &file);
  if (!file.empty()) {
    try {
      o.model.fabric = loadWovenFabricYaml(file);
    } catch (const std::exception& e) {
      throw ClothModelError(std::string("'model.fabric_file' ") + e.what() + " (model yarn_woven)");
    }
    o.fabric_source = file;
  }
  std::string weave;
  r.readChoice("weave", kWeaves, &weave);
  if (!weave.empty()) o.model.fabric.weave = namedWeave(weave);
  for (const FabricKey& k : kFabricKeys) r.readReal(k.key, k.min, k.exclusive, &(o.model.fabric.*k.field));
  YarnCrossingOptions& c = o.model.crossing;
  r.readBool("shear", &c.shear);
  r.readBool("friction", &c.friction);
  r.readBool("contact", &c.contact);
  r.readReal("friction_stiffness_factor", 0, true, &c.friction_stiffness_factor);
  r.readReal("shear_friction_stiffness_factor", 0, true, &c.shear_friction_stiffness_factor);
  r.readReal("jamming_gain", 0, false, &c.jamming_gain);
  r.readReal("compression_gain_per_n", 0, false, &c.compression_gain_per_n);
  r.readReal("contact_stiffness_factor", 0, true, &c.contact_stiffness_factor);
  r.readBool("gravity", &o.model.gravity);
  r.readBool("exact_hessian", &o.model.exact_hessian);
  r.readReal("tear_tension_n", 0, false, &o.model.tear_tension_n);
  YarnSelfContactOptions& sc = o.model.self_contact;
  r.readBool("self_contact", &sc.enabled);
  r.readReal("self_contact_thickness_factor", 0, true, &sc.thickness_factor);
  r.readReal("self_contact_stiffness_factor", 0, true, &sc.stiffness_factor);
  r.readReal("self_contact_damping", 0, false, &sc.damping);
  r.readReal("self_contact_friction", 0, false, &sc.friction);
  r.finish();
  const std::string errors = wovenFabricErrors(o.model.fabric);
  if (!errors.empty()) throw ClothModelError("model yarn_woven: fabric: " + errors);
  return o;
}

std::string repeatText(const WeavePattern& w) {
  std::ostringstream s;
  for (std::size_t i = 0; i < w.warp_on_top.size(); ++i) {
    if (i) s << '/';
    for (bool b : w.warp_on_top[i]) s << (b ? '1' : '0');
  }
  return s.str();
}

}  // namespace

ClothModelDescriptor yarnWovenModelDescriptor() {
  ClothModelDescriptor d;
  d.name = "yarn_woven";
  d.summary = "yarn-level woven cloth: crossings with sliding yarns (docs/yarn_model.md)";
  d.dofs_per_node = kYarnDofsPerNode;
  d.option_keys = {{"fabric_file", "woven-fabric YAML (docs/yarn_model.md); the keys below override it"},
                   {"weave", "plain | twill_2_2 | satin_5"}};
  for (const FabricKey& k : kFabricKeys) d.option_keys.emplace_back(k.key, "fabric field (docs/yarn_model.md)");
  for (const char* k : {"shear", "friction", "contact"}) d.option_keys.emplace_back(k, "true | false: crossing term on or off");
  d.option_keys.emplace_back("friction_stiffness_factor", "k_f = factor k_s / L, > 0 (default 1)");
  d.option_keys.emplace_back("shear_friction_stiffness_factor", "k_fphi = factor k_x L, > 0 (default 10)");
  d.option_keys.emplace_back("jamming_gain", "c_j >= 0 (default 1e5)");
  d.option_keys.emplace_back("compression_gain_per_n", "c_n [1/N] >= 0 of k_x (1 + c_n F_n) (default 250)");
  d.option_keys.emplace_back("contact_stiffness_factor", "k_c = factor k_s / L^2, > 0 (default 1)");
  d.option_keys.emplace_back("gravity", "true | false");
  d.option_keys.emplace_back("exact_hessian", "true | false: exact instead of clamped Hessians in df/dx");
  d.option_keys.emplace_back("tear_tension_n", "tension [N] >= 0 of one real yarn at which a segment tears (default 0: off)");
  d.option_keys.emplace_back("self_contact", "true | false: penalty self-contact on extruded triangles (default false)");
  d.option_keys.emplace_back("self_contact_thickness_factor", "gamma = factor R, > 0 (default 4)");
  d.option_keys.emplace_back("self_contact_stiffness_factor", "k_p = factor k_s / L, > 0 (default 1)");
  d.option_keys.emplace_back("self_contact_damping", "d_p = factor 2 sqrt(k_p m_crossing), >= 0 (default 1)");
  d.option_keys.emplace_back("self_contact_friction", "mu of the contact friction, >= 0 (default: sliding_friction)");
  d.parse_options = [](const std::map<std::string, std::string>& v) { return std::any(parseYarnOptions(v)); };
  d.create = [](const ParticleTopology& topology, const Material& /*material*/, const std::any& options) {
    const auto& o = std::any_cast<const ParsedYarnOptions&>(options);
    YarnWovenOptions model = o.model;
    model.bundle_size = yarnBundleSize(o.model.fabric, topology.spacing);
    YarnSheet sheet = buildYarnSheet(yarnGridOnParticles(topology, o.model.fabric.weave));
    return std::unique_ptr<ClothModel>(
        new YarnWovenModel(std::move(sheet), yarnBundleFabric(o.model.fabric, topology.spacing), model));
  };
  d.fingerprint = [](const std::any& options) {
    const auto& o = std::any_cast<const ParsedYarnOptions&>(options);
    ClothModelFingerprint f;
    f.lines.push_back("fabric: " + o.fabric_source);
    f.lines.push_back("weave: " + o.model.fabric.weave.name + " " + repeatText(o.model.fabric.weave));
    const YarnCrossingOptions& c = o.model.crossing;
    f.lines.push_back(std::string("forces: stretch bending") + (o.model.gravity ? " gravity" : "") +
                      (c.shear ? " shear" : "") + (c.friction ? " friction" : "") + (c.contact ? " contact" : "") +
                      (o.model.self_contact.enabled ? " self_contact" : "") + " rayleigh_damping");
    if (o.model.self_contact.enabled) {
      const YarnSelfContactOptions& sc = o.model.self_contact;
      f.numbers.emplace_back("model_options.self_contact_thickness_factor", sc.thickness_factor);
      f.numbers.emplace_back("model_options.self_contact_stiffness_factor", sc.stiffness_factor);
      f.numbers.emplace_back("model_options.self_contact_damping", sc.damping);
      f.numbers.emplace_back("model_options.self_contact_friction",
                             sc.friction >= 0 ? sc.friction : o.model.fabric.sliding_friction);
    }
    f.numbers.emplace_back("model_options.friction_stiffness_factor", c.friction_stiffness_factor);
    f.numbers.emplace_back("model_options.shear_friction_stiffness_factor", c.shear_friction_stiffness_factor);
    f.numbers.emplace_back("model_options.jamming_gain", c.jamming_gain);
    f.numbers.emplace_back("model_options.compression_gain_per_n", c.compression_gain_per_n);
    f.numbers.emplace_back("model_options.contact_stiffness_factor", c.contact_stiffness_factor);
    f.numbers.emplace_back("model_options.tear_tension_n", o.model.tear_tension_n);
    f.lines.push_back(std::string("hessian: ") + (o.model.exact_hessian ? "exact" : "clamped"));
    for (const FabricKey& k : kFabricKeys) f.numbers.emplace_back(std::string("model_options.") + k.key, o.model.fabric.*k.field);
    return f;
  };
  return d;
}

}  // namespace textile_handling
