// The cloth model registry and the option reader every model's parser uses (cloth_model_registry.h).
#include "textile_handling/sim/cloth_model_registry.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>

namespace textile_handling {

namespace {
std::string number17(Real v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}
}  // namespace

// ---- ClothModelSpec ------------------------------------------------------------------------------

ClothModelSpec& ClothModelSpec::set(const std::string& key, const std::string& value) {
  options[key] = value;
  return *this;
}
ClothModelSpec& ClothModelSpec::set(const std::string& key, Real value) { return set(key, number17(value)); }
ClothModelSpec& ClothModelSpec::set(const std::string& key, bool value) {
  return set(key, std::string(value ? "true" : "false"));
}

std::string ClothModelSpec::text() const {
  std::string t = name;
  for (const auto& [k, v] : options) t += " " + k + "=" + v;
  return t;
}

ClothModelSpec parseClothModelSpecText(const std::string& text) {
  std::istringstream in(text);
  ClothModelSpec spec;
  if (!(in >> spec.name)) throw ClothModelError("model: empty model text");
  if (spec.name.find('=') != std::string::npos)
    throw ClothModelError("model: '" + spec.name + "' is not a model name (the text starts with the name)");
  std::string item;
  while (in >> item) {
    const auto eq = item.find('=');
    if (eq == std::string::npos || eq == 0)
      throw ClothModelError("model: option '" + item + "' of model '" + spec.name + "' is not key=value");
    if (!spec.options.emplace(item.substr(0, eq), item.substr(eq + 1)).second)
      throw ClothModelError("model." + item.substr(0, eq) + " appears twice");
  }
  return spec;
}

// ---- ModelOptionReader ---------------------------------------------------------------------------

ModelOptionReader::ModelOptionReader(const std::string& model, const std::map<std::string, std::string>& values)
    : model_(model), values_(values) {}

const std::string* ModelOptionReader::take(const std::string& key, const std::string& /*what*/) {
  known_.push_back(key);
  const auto it = values_.find(key);
  return it == values_.end() ? nullptr : &it->second;
}

void ModelOptionReader::fail(const std::string& key, const std::string& message) const {
  throw ClothModelError("'model." + key + "' " + message + " (model " + model_ + ")");
}

void ModelOptionReader::readBool(const std::string& key, bool* value) {
  const std::string* t = take(key, "true or false");
  if (!t) return;
  if (*t == "true" || *t == "True" || *t == "TRUE" || *t == "yes" || *t == "on") *value = true;
  else if (*t == "false" || *t == "False" || *t == "FALSE" || *t == "no" || *t == "off") *value = false;
  else fail(key, "must be true or false, not '" + *t + "'");
}

void ModelOptionReader::readText(const std::string& key, std::string* value) {
  const std::string* t = take(key, "text");
  if (!t) return;
  if (t->empty()) fail(key, "must not be empty");
  *value = *t;
}

void ModelOptionReader::readReal(const std::string& key, Real min, bool min_exclusive, Real* value) {
  const std::string* t = take(key, "a number");
  if (!t) return;
  char* end = nullptr;
  const Real v = std::strtod(t->c_str(), &end);
  if (t->empty() || end != t->c_str() + t->size() || !std::isfinite(v)) fail(key, "must be a finite number, not '" + *t + "'");
  if (min_exclusive ? !(v > min) : !(v >= min))
    fail(key, std::string("must be ") + (min_exclusive ? "> " : ">= ") + number17(min));
  *value = v;
}

void ModelOptionReader::readRealInRange(const std::string& key, Real lo, Real hi, bool hi_exclusive, Real* value) {
  Real v = *value;
  readReal(key, lo, false, &v);
  if (hi_exclusive ? !(v < hi) : !(v <= hi)) fail(key, std::string("must be ") + (hi_exclusive ? "< " : "<= ") + number17(hi));
  *value = v;
}

void ModelOptionReader::finish() const {
  for (const auto& [key, value] : values_) {
    if (std::find(known_.begin(), known_.end(), key) != known_.end()) continue;
    std::string list;
    for (const auto& k : known_) list += (list.empty() ? "" : ", ") + k;
    throw ClothModelError("unknown key 'model." + key + "' for model " + model_ + " (known: " + list + ")");
  }
}

// ---- ClothModelDescriptor / ClothModelRegistry -----------------------------------------------------

bool ClothModelDescriptor::hasOptionKey(const std::string& key) const {
  return std::any_of(option_keys.begin(), option_keys.end(), [&](const auto& k) { return k.first == key; });
}

ClothModelRegistry::ClothModelRegistry() {
  // The built-in models; a new built-in model adds its descriptor here (docs/architecture.md).
  for (auto d : {particleModelDescriptor(), choiKoModelDescriptor(), yarnWovenModelDescriptor()}) {
    const std::string name = d.name;  // d is moved from below
    models_.emplace(name, std::make_unique<ClothModelDescriptor>(std::move(d)));
  }
}

ClothModelRegistry& ClothModelRegistry::instance() {
  static ClothModelRegistry registry;
  return registry;
}

void ClothModelRegistry::add(ClothModelDescriptor d) {
  if (d.name.empty() || !d.parse_options || !d.create || !d.fingerprint || d.dofs_per_node < 3)
    throw ClothModelError("cloth model registry: descriptor of '" + d.name +
                          "' needs a name, parse_options, create, fingerprint and dofs_per_node >= 3");
  std::lock_guard<std::mutex> lock(mutex_);
  if (models_.count(d.name)) throw ClothModelError("cloth model registry: '" + d.name + "' is already registered");
  const std::string name = d.name;
  models_.emplace(name, std::make_unique<ClothModelDescriptor>(std::move(d)));
}

bool ClothModelRegistry::contains(const std::string& name) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return models_.count(name) > 0;
}

const ClothModelDescriptor& ClothModelRegistry::find(const std::string& name) const {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = models_.find(name);
    if (it != models_.end()) return *it->second;
  }
  const std::string shown = name.size() > 64 ? name.substr(0, 64) + "..." : name;
  throw ClothModelError("unknown cloth model '" + shown + "' (available: " + namesText() + ")");
}

std::vector<std::string> ClothModelRegistry::names() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> out;
  for (const auto& kv : models_) out.push_back(kv.first);
  return out;
}

std::string ClothModelRegistry::namesText() const {
  std::string s;
  for (const auto& n : names()) s += (s.empty() ? "" : ", ") + n;
  return s;
}

std::any ClothModelRegistry::parseOptions(const ClothModelSpec& spec) const {
  return find(spec.name).parse_options(spec.options);
}

std::unique_ptr<ClothModel> ClothModelRegistry::create(const ClothModelSpec& spec, const ParticleTopology& topology,
                                                       const Material& material) const {
  const ClothModelDescriptor& d = find(spec.name);
  return d.create(topology, material, d.parse_options(spec.options));
}

ClothModelFingerprint ClothModelRegistry::fingerprint(const ClothModelSpec& spec) const {
  const ClothModelDescriptor& d = find(spec.name);
  return d.fingerprint(d.parse_options(spec.options));
}

ClothModelSpec settlingModelSpec(const std::string& model, Real settle_damping_per_s) {
  const ClothModelDescriptor& d = ClothModelRegistry::instance().find(model);
  ClothModelSpec spec(model);
  if (d.hasOptionKey("settle_damping_per_s")) spec.set("settle_damping_per_s", settle_damping_per_s);
  if (d.hasOptionKey("jacobian")) spec.set("jacobian", "definite_fix");
  return spec;
}

}  // namespace textile_handling
