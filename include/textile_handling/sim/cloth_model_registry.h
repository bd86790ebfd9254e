// The one place where cloth models are known by name. A model registers its name, its option keys
// with their parser and validation, its factory and the parameter lines that fingerprint a database
// build; scenes, the database builder, drape_db, the registry node and the benchmarks look models up
// here and never name a model's option struct. docs/architecture.md, "How to add a cloth model".
#pragma once

#include <any>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/material.h"
#include "textile_handling/sim/sim_errors.h"

namespace textile_handling {

/// A model and its options as text, as they come from the scene file's `model:` section, a service
/// request or a command line. Keys are the model's option keys (docs/simulation.md); values are the
/// scalar text ("4", "definite_fix", "true"). Keys the model does not know are refused when parsed.
struct ClothModelSpec {
  std::string name = "particle_kes";
  std::map<std::string, std::string> options;

  ClothModelSpec() = default;
  explicit ClothModelSpec(std::string model_name, std::map<std::string, std::string> values = {})
      : name(std::move(model_name)), options(std::move(values)) {}
  ClothModelSpec& set(const std::string& key, const std::string& value);
  ClothModelSpec& set(const std::string& key, const char* value) { return set(key, std::string(value)); }
  ClothModelSpec& set(const std::string& key, Real value);  ///< written with 17 significant digits
  ClothModelSpec& set(const std::string& key, bool value);  ///< "true" / "false"
  /// "name" or "name key=value key=value ..." (keys sorted); parseClothModelSpecText() reads it back.
  std::string text() const;
  bool operator==(const ClothModelSpec& o) const { return name == o.name && options == o.options; }
  bool operator!=(const ClothModelSpec& o) const { return !(*this == o); }
};

/// Reads ClothModelSpec::text(). Throws ClothModelError on malformed text (values may not hold spaces).
ClothModelSpec parseClothModelSpecText(const std::string& text);

/// What a model contributes to a database build's parameter text: lines "key: value" that describe
/// categorical choices, and named numbers (written with 17 digits and checked to be finite).
struct ClothModelFingerprint {
  std::vector<std::string> lines;
  std::vector<std::pair<std::string, double>> numbers;
};

/// Reads the option keys of one model and records which were read, so that unknown keys are refused
/// with the list of known ones. Every error is a ClothModelError naming "model.<key>".
class ModelOptionReader {
 public:
  ModelOptionReader(const std::string& model, const std::map<std::string, std::string>& values);
  void readBool(const std::string& key, bool* value);
  /// A finite number >= `min` (strictly greater when `min_exclusive`).
  void readReal(const std::string& key, Real min, bool min_exclusive, Real* value);
  /// A finite number in [lo, hi] (hi exclusive when `hi_exclusive`).
  void readRealInRange(const std::string& key, Real lo, Real hi, bool hi_exclusive, Real* value);
  /// Non-empty text (a file path, a name).
  void readText(const std::string& key, std::string* value);
  /// One of the names in `choices` (name -> value).
  template <typename T>
  void readChoice(const std::string& key, const std::vector<std::pair<std::string, T>>& choices, T* value) {
    const std::string* text = take(key, choiceList(choices));
    if (!text) return;
    for (const auto& c : choices)
      if (c.first == *text) {
        *value = c.second;
        return;
      }
    fail(key, "must be " + choiceList(choices));
  }
  /// Throws for every key that no read*() call asked for.
  void finish() const;

 private:
  template <typename T>
  static std::string choiceList(const std::vector<std::pair<std::string, T>>& choices) {
    std::string s;
    for (size_t k = 0; k < choices.size(); ++k)
      s += (k == 0 ? "" : (k + 1 == choices.size() ? " or " : ", ")) + choices[k].first;
    return s;
  }
  const std::string* take(const std::string& key, const std::string& what);
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;

  std::string model_;
  const std::map<std::string, std::string>& values_;
  std::vector<std::string> known_;
};

/// Everything the package needs to know about one cloth model.
struct ClothModelDescriptor {
  std::string name;     ///< "particle_kes"; also ClothModel::name() of the models it creates
  std::string summary;  ///< one line for usage texts and docs
  int dofs_per_node = 3;
  /// Option keys -> what each sets (the scene file's model: keys, service and command-line options).
  std::vector<std::pair<std::string, std::string>> option_keys;
  /// Parses and validates option values into the model's own options struct (held in the std::any).
  /// Missing keys keep the model's defaults. Throws ClothModelError naming the key.
  std::function<std::any(const std::map<std::string, std::string>& values)> parse_options;
  /// Builds the model for a particle grid from parsed options.
  std::function<std::unique_ptr<ClothModel>(const ParticleTopology& topology, const Material& material,
                                            const std::any& options)>
      create;
  /// The parameter lines of a database build with these parsed options.
  std::function<ClothModelFingerprint(const std::any& options)> fingerprint;

  bool hasOptionKey(const std::string& key) const;
};

/// The models known to this process. Built-in models (particle_kes, choi_ko, yarn_woven) are registered on first
/// use; tests and plug-ins add their own with add(). Thread-safe.
class ClothModelRegistry {
 public:
  static ClothModelRegistry& instance();

  /// Registers a model; throws ClothModelError if the name is taken or the descriptor is incomplete.
  void add(ClothModelDescriptor descriptor);
  bool contains(const std::string& name) const;
  /// Throws ClothModelError naming the model and listing the registered ones.
  const ClothModelDescriptor& find(const std::string& name) const;
  /// Registered names, sorted.
  std::vector<std::string> names() const;
  /// "choi_ko, particle_kes" (for messages and usage texts).
  std::string namesText() const;

  /// find(spec.name).parse_options(spec.options).
  std::any parseOptions(const ClothModelSpec& spec) const;
  /// Validates the spec (throws ClothModelError naming the model or key).
  void validate(const ClothModelSpec& spec) const { (void)parseOptions(spec); }
  std::unique_ptr<ClothModel> create(const ClothModelSpec& spec, const ParticleTopology& topology,
                                     const Material& material) const;
  ClothModelFingerprint fingerprint(const ClothModelSpec& spec) const;

 private:
  ClothModelRegistry();
  mutable std::mutex mutex_;
  std::map<std::string, std::unique_ptr<ClothModelDescriptor>> models_;
};

/// Options for settling a drape to rest, for any registered model: mass-proportional damping
/// `settle_damping_per_s` (an equilibrium does not depend on it) and, where the model has the key, the
/// definite-fix Jacobian (`jacobian: definite_fix`), which implicit steps far from equilibrium need.
ClothModelSpec settlingModelSpec(const std::string& model, Real settle_damping_per_s);

/// The built-in models' registrations (each in its model's source file).
ClothModelDescriptor particleModelDescriptor();
ClothModelDescriptor choiKoModelDescriptor();
ClothModelDescriptor yarnWovenModelDescriptor();

}  // namespace textile_handling
