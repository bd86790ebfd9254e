// Woven fabric: named and custom weaves, field checks, YAML I/O (woven_fabric.h).
#include "textile_handling/sim/woven_fabric.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "textile_handling/sim/material.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/text_input.h"

namespace textile_handling {

namespace {

constexpr Real kMaxYarnDensityPerMetre = 1e5;

// Exact (round-trip) text for the YAML output; six significant digits in messages.
std::string numberText(Real v) {
  std::ostringstream s;
  s << std::setprecision(std::numeric_limits<Real>::max_digits10) << v;
  return s.str();
}
std::string shortNumber(Real v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

// The fabric's scalar fields by their YAML key, in the order of the file format.
struct ScalarField {
  const char* key;
  Real WovenFabric::*member;
};
constexpr ScalarField kScalarFields[] = {
    {"warp_density_per_m", &WovenFabric::warp_density_per_m},
    {"weft_density_per_m", &WovenFabric::weft_density_per_m},
    {"yarn_radius_m", &WovenFabric::yarn_radius_m},
    {"young_modulus_pa", &WovenFabric::young_modulus_pa},
    {"bending_modulus", &WovenFabric::bending_modulus},
    {"shear_modulus_pa", &WovenFabric::shear_modulus_pa},
    {"sliding_friction", &WovenFabric::sliding_friction},
    {"damping_mass_per_s", &WovenFabric::damping_mass_per_s},
    {"damping_stiffness_s", &WovenFabric::damping_stiffness_s},
    {"linear_density_kg_per_m", &WovenFabric::linear_density_kg_per_m},
};

std::string knownKeys() {
  std::string keys = "type, weave, weave_repeat";
  for (const ScalarField& f : kScalarFields) keys += std::string(", ") + f.key;
  return keys;
}

}  // namespace

WeavePattern namedWeave(const std::string& name) {
  WeavePattern w;
  w.name = name;
  auto make = [&](std::size_t rows, std::size_t cols, auto warp_on_top) {
    w.warp_on_top.assign(rows, std::vector<bool>(cols, false));
    for (std::size_t i = 0; i < rows; ++i)
      for (std::size_t j = 0; j < cols; ++j) w.warp_on_top[i][j] = warp_on_top(static_cast<int>(i), static_cast<int>(j));
  };
  if (name == "plain")
    make(2, 2, [](int i, int j) { return (i + j) % 2 == 0; });
  else if (name == "twill_2_2")
    make(4, 4, [](int i, int j) { return (i + j) % 4 < 2; });
  else if (name == "satin_5")
    make(5, 5, [](int i, int j) { return ((j - 2 * i) % 5 + 5) % 5 != 0; });
  else
    throw SimError("weave '" + name.substr(0, 64) + "' is not known (plain, twill_2_2, satin_5, or custom with weave_repeat)");
  return w;
}

WeavePattern customWeave(const std::vector<std::vector<int>>& matrix) {
  if (matrix.empty() || matrix.front().empty()) throw SimError("weave_repeat must have at least one row and one column");
  if (matrix.size() > kMaxWeaveRepeat || matrix.front().size() > kMaxWeaveRepeat)
    throw SimError("weave_repeat is " + std::to_string(matrix.size()) + " x " + std::to_string(matrix.front().size()) +
                   ", more than " + std::to_string(kMaxWeaveRepeat) + " rows or columns");
  WeavePattern w;
  w.name = "custom";
  for (std::size_t i = 0; i < matrix.size(); ++i) {
    if (matrix[i].size() != matrix.front().size())
      throw SimError("weave_repeat row " + std::to_string(i) + " has " + std::to_string(matrix[i].size()) +
                     " entries, row 0 has " + std::to_string(matrix.front().size()));
    std::vector<bool> row;
    for (std::size_t j = 0; j < matrix[i].size(); ++j) {
      if (matrix[i][j] != 0 && matrix[i][j] != 1)
        throw SimError("weave_repeat entry (" + std::to_string(i) + ", " + std::to_string(j) + ") is " +
                       std::to_string(matrix[i][j]) + ", must be 0 (weft on top) or 1 (warp on top)");
      row.push_back(matrix[i][j] == 1);
    }
    w.warp_on_top.push_back(std::move(row));
  }
  return w;
}

Real WovenFabric::stretchStiffness() const { return young_modulus_pa * M_PI * yarn_radius_m * yarn_radius_m; }

Real WovenFabric::bendingStiffness() const { return bending_modulus * M_PI * yarn_radius_m * yarn_radius_m; }

Real WovenFabric::jammingAngle() const {
  return 2 * std::asin(yarn_radius_m / std::min(warpSpacing(), weftSpacing()));
}

std::string wovenFabricErrors(const WovenFabric& f) {
  std::string e;
  auto bad = [&](const std::string& line) { e += (e.empty() ? "" : "\n") + line; };
  for (const auto& [key, v] : {std::pair<std::string, Real>{"warp_density_per_m", f.warp_density_per_m},
                               std::pair<std::string, Real>{"weft_density_per_m", f.weft_density_per_m}}) {
    if (!std::isfinite(v) || v <= 0)
      bad(key + " " + shortNumber(v) + " must be finite and > 0");
    else if (v > kMaxYarnDensityPerMetre)
      bad(key + " " + shortNumber(v) + " is above " + shortNumber(kMaxYarnDensityPerMetre) + " yarns per metre (10 per mm)");
  }
  for (const ScalarField& s : kScalarFields) {
    const std::string key = s.key;
    if (key == "warp_density_per_m" || key == "weft_density_per_m") continue;
    const Real v = f.*(s.member);
    const bool may_be_zero = key == "sliding_friction" || key == "damping_mass_per_s" || key == "damping_stiffness_s" ||
                             key == "bending_modulus" || key == "shear_modulus_pa";
    if (!std::isfinite(v) || v < 0 || (!may_be_zero && v == 0))
      bad(key + " " + shortNumber(v) + " must be finite and " + (may_be_zero ? ">= 0" : "> 0"));
  }
  if (std::isfinite(f.yarn_radius_m) && f.yarn_radius_m > 0)
    for (const auto& [name, density] : {std::pair<const char*, Real>{"warp", f.warp_density_per_m},
                                        std::pair<const char*, Real>{"weft", f.weft_density_per_m}})
      if (std::isfinite(density) && density > 0 && f.yarn_radius_m >= 0.5 / density)
        bad("yarn_radius_m " + shortNumber(f.yarn_radius_m) + " must be below half the " + name + " spacing " +
            shortNumber(1 / density) + " m (the jamming angle 2 asin(R / L) needs R < L / 2)");
  if (f.weave.warp_on_top.empty() || f.weave.warp_on_top.front().empty())
    bad("weave '" + f.weave.name + "' has an empty repeat");
  else
    for (const auto& row : f.weave.warp_on_top)
      if (row.size() != f.weave.warp_on_top.front().size()) {
        bad("weave '" + f.weave.name + "' has rows of different lengths");
        break;
      }
  return e;
}

void validateWovenFabric(const WovenFabric& fabric) {
  const std::string e = wovenFabricErrors(fabric);
  if (!e.empty()) throw SimError("woven fabric: " + e);
}

WovenFabric parseWovenFabricYaml(const std::string& text, const std::string& source) {
  auto fail = [&](const std::string& what) -> MaterialError { return MaterialError(source + ": " + what); };
  const std::string size_error = textSizeError("woven-fabric YAML", text.size(), kMaxYamlDocumentBytes);
  if (!size_error.empty()) throw fail(size_error);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& ex) {
    throw fail(std::string("not valid YAML: ") + ex.what());
  }
  if (!root.IsMap()) throw fail("a woven fabric is a YAML map (keys: " + knownKeys() + ")");
  const YAML::Node& doc = root;  // const: lookups never add keys
  for (const auto& kv : doc) {
    const std::string key = kv.first.IsScalar() ? kv.first.Scalar() : std::string("<non-scalar key>");
    bool known = key == "type" || key == "weave" || key == "weave_repeat";
    for (const ScalarField& s : kScalarFields) known = known || key == s.key;
    if (!known) throw fail("unknown key '" + key.substr(0, 64) + "' (known: " + knownKeys() + ")");
  }
  auto scalarText = [&](const char* key) {
    const YAML::Node n = doc[key];
    if (!n.IsScalar()) throw fail(std::string(key) + " must be a single value");
    return n.Scalar();
  };
  if (!doc["type"] || scalarText("type") != "woven_fabric") throw fail("type must be woven_fabric");
  WovenFabric f;
  try {
    const std::string weave = doc["weave"] ? scalarText("weave") : std::string("plain");
    if (weave == "custom") {
      const YAML::Node rep = doc["weave_repeat"];
      if (!rep || !rep.IsSequence()) throw fail("weave custom needs weave_repeat, a list of rows of 0 and 1");
      if (rep.size() > kMaxWeaveRepeat) throw fail("weave_repeat has more than " + std::to_string(kMaxWeaveRepeat) + " rows");
      std::vector<std::vector<int>> m;
      for (std::size_t i = 0; i < rep.size(); ++i) {
        if (!rep[i].IsSequence() || rep[i].size() > kMaxWeaveRepeat)
          throw fail("weave_repeat row " + std::to_string(i) + " must be a list of at most " +
                     std::to_string(kMaxWeaveRepeat) + " entries 0 or 1");
        std::vector<int> row;
        for (std::size_t j = 0; j < rep[i].size(); ++j) {
          int v = -1;
          try {
            v = rep[i][j].as<int>();
          } catch (const YAML::Exception&) {
            throw fail("weave_repeat entry (" + std::to_string(i) + ", " + std::to_string(j) + ") must be 0 or 1");
          }
          row.push_back(v);
        }
        m.push_back(std::move(row));
      }
      f.weave = customWeave(m);
    } else {
      if (doc["weave_repeat"]) throw fail("weave_repeat is only for weave: custom (weave is " + weave.substr(0, 64) + ")");
      f.weave = namedWeave(weave);
    }
  } catch (const SimError& e) {
    throw fail(e.what());
  }
  for (const ScalarField& s : kScalarFields) {
    if (!doc[s.key]) continue;
    const std::string t = scalarText(s.key);
    try {
      std::size_t used = 0;
      const double v = std::stod(t, &used);
      if (used != t.size()) throw std::invalid_argument(t);
      f.*(s.member) = v;
    } catch (const std::exception&) {
      throw fail(std::string(s.key) + " '" + t.substr(0, 64) + "' is not a number");
    }
  }
  const std::string e = wovenFabricErrors(f);
  if (!e.empty()) throw fail(e);
  return f;
}

WovenFabric loadWovenFabricYaml(const std::string& path) {
  std::string text, error;
  if (!readBoundedTextFile(path, kMaxYamlDocumentBytes, &text, &error)) throw MaterialError(path + ": " + error);
  return parseWovenFabricYaml(text, path);
}

std::string wovenFabricToYaml(const WovenFabric& f) {
  std::ostringstream y;
  y << "type: woven_fabric\nweave: " << f.weave.name << "\n";
  if (f.weave.name == "custom") {
    y << "weave_repeat:\n";
    for (const auto& row : f.weave.warp_on_top) {
      y << "  - [";
      for (std::size_t j = 0; j < row.size(); ++j) y << (j ? ", " : "") << (row[j] ? 1 : 0);
      y << "]\n";
    }
  }
  for (const ScalarField& s : kScalarFields) y << s.key << ": " << numberText(f.*(s.member)) << "\n";
  return y.str();
}

}  // namespace textile_handling
