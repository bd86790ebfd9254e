// material_lab: runs the virtual material lab (lab/material_lab.h) on one cloth model and material and
// writes the curves, the KES-style figures and the measured material.
//
//   material_lab [--model NAME] [--model-option KEY=VALUE]... [--material cotton|PATH] [--spacing M]
//                [--tests bending,shear,tensile,cantilever,drape] [--directions warp,weft] [--drape-spacing M]
//                [--shear-max-angle DEG] [--shear-pretension-strain E] [--bending-bias-deg DEG] [--fit MODEL[,MODEL]]
//                [--fit-model-option MODEL:KEY=VALUE]... [--fit-bending kes|cantilever] [--fit-spacing M] [--out DIR] [--threads N]
//
// Outputs in DIR (default out/material_lab), docs/material_lab.md: figures.csv (every figure with the value
// the material file implies where it has one), <test>_<direction>.csv (the curves), <test>.png (the curves
// of both directions), drape.csv (the drape coefficient run), lab_material.yaml (the measured curves as a
// material file) and, for every model of --fit, fitted_<model>.yaml (a material with which that model
// reproduces the tested model's B, G and strain at 5 gf/cm) and fit_<model>.csv (target and fitted figures).
// Exit status: 0 done, 2 bad input or usage, 3 a test could not be completed, 4 outputs cannot be written,
// 5 out of memory or another unexpected error.
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/lab/lab_material.h"
#include "textile_handling/lab/material_fit.h"
#include "textile_handling/lab/material_lab.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/thread_limit.h"
#include "tool_main.h"

using namespace textile_handling;
using namespace textile_handling::lab;

namespace {

constexpr int kExitBadInput = 2;
constexpr int kExitTestFailed = 3;
constexpr int kExitOutput = 4;

const char* kUsage =
    " [--model NAME] [--model-option KEY=VALUE]... [--material cotton|PATH] [--spacing M]\n"
    "       [--tests bending,shear,tensile,cantilever,drape] [--directions warp,weft] [--drape-spacing M]\n"
    "       [--shear-max-angle DEG] [--shear-pretension-strain E] [--bending-bias-deg DEG] [--fit MODEL[,MODEL]]\n"
    "       [--fit-model-option MODEL:KEY=VALUE]... [--fit-bending kes|cantilever] [--fit-spacing M] [--out DIR] [--threads N]\n";

int usage(const char* argv0, const std::string& problem = "") {
  if (!problem.empty()) std::cerr << "material_lab: " << problem << "\n";
  std::cerr << "usage: " << argv0 << kUsage;
  return kExitBadInput;
}

struct Options {
  LabSample sample;
  std::string material = "cotton";
  std::vector<std::string> tests = {"bending", "shear", "tensile", "cantilever", "drape"};
  DrapeCoefficientProtocol drape;
  KesShearProtocol shear;
  KesBendingProtocol bending;
  std::vector<std::string> fit_models;
  std::map<std::string, ClothModelSpec> fit_model_options;  // --fit-model-option, by model name
  MaterialFitOptions fit;
  double fit_spacing = 0;  // 0 = the sample's
  std::vector<YarnDirection> directions = {YarnDirection::kWarp, YarnDirection::kWeft};
  std::string out_dir = "out/material_lab";
  int threads = 0;
};

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

// A number in [lo, hi] with nothing after it; false otherwise.
bool parseNumberIn(const std::string& text, double lo, double hi, double* value) {
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || errno == ERANGE || !std::isfinite(v) || !(v >= lo) || !(v <= hi)) return false;
  *value = v;
  return true;
}

std::string parseArguments(int argc, char** argv, Options& o) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return "option " + a + " needs a value";
    const std::string value = argv[++i];
    if (a == "--model") {
      o.sample.model.name = value;
    } else if (a == "--model-option") {
      const auto eq = value.find('=');
      if (eq == std::string::npos || eq == 0) return "--model-option must be KEY=VALUE, got '" + value + "'";
      o.sample.model.set(value.substr(0, eq), value.substr(eq + 1));
    } else if (a == "--material") {
      o.material = value;
    } else if (a == "--spacing" || a == "--drape-spacing") {
      double d = 0;
      if (!parseNumberIn(value, 1e-4, 0.05, &d))
        return a + " must be a number of metres in [1e-4, 0.05], got '" + value + "'";
      (a == "--spacing" ? o.sample.spacing : o.drape.spacing_m) = d;
    } else if (a == "--tests") {
      o.tests = splitList(value);
      for (const auto& t : o.tests)
        if (t != "bending" && t != "shear" && t != "tensile" && t != "cantilever" && t != "drape")
          return "--tests: unknown test '" + t + "' (bending, shear, tensile, cantilever, drape)";
      if (o.tests.empty()) return "--tests is empty";
    } else if (a == "--directions") {
      o.directions.clear();
      for (const auto& t : splitList(value)) {
        if (t != "warp" && t != "weft") return "--directions: unknown direction '" + t + "' (warp, weft)";
        o.directions.push_back(yarnDirectionFromString(t));
      }
      if (o.directions.empty()) return "--directions is empty";
    } else if (a == "--shear-max-angle") {
      if (!parseNumberIn(value, 5, 45, &o.shear.max_angle_deg))
        return "--shear-max-angle must be a number of degrees in [5, 45] (shear.max_angle_deg), got '" + value + "'";
    } else if (a == "--shear-pretension-strain") {
      if (!parseNumberIn(value, 0, 0.2, &o.shear.pretension_strain))
        return "--shear-pretension-strain must be a strain in [0, 0.2] (shear.pretension_strain), got '" + value + "'";
    } else if (a == "--bending-bias-deg") {
      if (!parseNumberIn(value, 0, 90, &o.bending.bias_deg))
        return "--bending-bias-deg must be a number of degrees in [0, 90] (bending.bias_deg), got '" + value + "'";
    } else if (a == "--fit") {
      o.fit_models = splitList(value);
      if (o.fit_models.empty()) return "--fit is empty";
    } else if (a == "--fit-model-option") {
      const auto colon = value.find(':'), eq = value.find('=');
      if (colon == std::string::npos || colon == 0 || eq == std::string::npos || eq < colon + 2)
        return "--fit-model-option must be MODEL:KEY=VALUE, got '" + value + "'";
      const std::string model = value.substr(0, colon);
      o.fit_model_options.emplace(model, ClothModelSpec(model)).first->second.set(value.substr(colon + 1, eq - colon - 1),
                                                                                  value.substr(eq + 1));
    } else if (a == "--fit-bending") {
      if (value == "kes") o.fit.bending_figure = BendingFitFigure::kKesB;
      else if (value == "cantilever") o.fit.bending_figure = BendingFitFigure::kCantilever;
      else return "--fit-bending must be kes or cantilever (fit.bending_figure), got '" + value + "'";
    } else if (a == "--fit-spacing") {
      if (!parseNumberIn(value, 1e-4, 0.05, &o.fit_spacing))
        return "--fit-spacing must be a number of metres in [1e-4, 0.05], got '" + value + "'";
    } else if (a == "--out") {
      o.out_dir = value;
    } else if (a == "--threads") {
      std::string error;
      if (!parseThreadCount(value, &o.threads, &error)) return error;
    } else {
      return "unknown option " + a;
    }
  }
  for (const auto& entry : o.fit_model_options) {
    bool fitted = false;
    for (const auto& m : o.fit_models) fitted = fitted || m == entry.first;
    if (!fitted) return "--fit-model-option names " + entry.first + ", which --fit does not fit";
  }
  if (o.fit.bending_figure == BendingFitFigure::kCantilever) {
    bool has = false;
    for (const auto& t : o.tests) has = has || t == "cantilever";
    if (!has || o.directions.size() != 2) return "--fit-bending cantilever needs the cantilever test in both directions (--tests, --directions)";
  }
  if (!o.fit_models.empty() && (o.bending.bias_deg != 0 || o.shear.pretension_strain != 0 || o.shear.max_angle_deg != 8))
    return "--fit fits the standard KES figures; it cannot be combined with --bending-bias-deg, --shear-pretension-strain "
           "or --shear-max-angle";
  return "";
}

void writeCurve(const std::string& path, const char* header, const std::vector<CurvePoint>& c) {
  writeFileAtomically(path, [&](std::ostream& f) {
    f.precision(10);
    f << header << "\n";
    for (const auto& p : c) f << p.x << ',' << p.y << '\n';
  });
}

void chart(const std::string& path, const std::vector<std::pair<std::string, const std::vector<CurvePoint>*>>& series,
           Real x_scale, const std::string& x_label, const std::string& y_label, const std::string& title) {
  std::vector<ChartPoint> points;
  for (const auto& s : series)
    for (const auto& p : *s.second) points.push_back({p.x * x_scale, p.y, "", s.first});
  std::string error;
  if (!writeLineChart(path, points, x_label, y_label, title, &error)) throw OutputError(path + ": " + error);
}

// A model of --fit with its --fit-model-option settings.
ClothModelSpec fittedModel(const Options& o, const std::string& name) {
  const auto it = o.fit_model_options.find(name);
  return it != o.fit_model_options.end() ? it->second : ClothModelSpec(name);
}

// fitted_<model>.yaml and fit_<model>.csv of one fit into directory d (report: the tested model's run).
void writeFitOutputs(const std::string& d, const Options& o, const LabReport& report, const MaterialFitResult& fit) {
  const std::string model = fit.fitted.sample.model.name;
  writeFileAtomically(d + "/fitted_" + model + ".yaml", [&](std::ostream& f) {
    const LabSample& fitted = fit.fitted.sample;
    f << "# Fitted by material_lab: " << fitted.model.text() << " at d = " << fitted.spacing
      << " m with this material reproduces "
      << (o.fit.bending_figure == BendingFitFigure::kCantilever ? "the cantilever rigidity" : "B")
      << ", G and the tensile figure of " << report.sample.model.text() << " (" << report.sample.material.name << ") at d = "
      << report.sample.spacing << " m" << (fit.converged ? "" : " (NOT converged)") << "\n"
      << (fitted.model.options.empty() ? "" : "# Use it with the same model options; they are not part of the material file.\n")
      << materialToYaml(fit.material);
  });
  writeFileAtomically(d + "/fit_" + model + ".csv", [&](std::ostream& f) {
    f.precision(8);
    f << "figure,target,fitted,factor\n";
    for (const auto& g : fit.figures) f << g.name << ',' << g.target << ',' << g.fitted << ',' << g.factor << '\n';
    // Not fitted with --fit-bending cantilever: the KES B of both, which then differ.
    if (o.fit.bending_figure == BendingFitFigure::kCantilever)
      for (const auto& target_bending : report.bending)
        for (const auto& fitted_bending : fit.fitted.bending)
          if (fitted_bending.direction == target_bending.direction)
            f << "B_" << toString(target_bending.direction) << ',' << target_bending.B << ',' << fitted_bending.B << ",\n";
    // Not fitted: how the fitted model drapes the disc sample against the tested model.
    if (!report.drape.empty() && !fit.fitted.drape.empty())
      f << "DC," << report.drape.front().drape_coefficient << ',' << fit.fitted.drape.front().drape_coefficient << ",\n";
  });
}

int run(const Options& o) {
  std::string note;
  applyThreadLimit(o.threads, &note);
  if (!note.empty()) std::cout << "material_lab: note: " << note << "\n";
  LabSample sample = o.sample;
  try {
    sample.material = o.material == "cotton" ? Material::cotton() : loadMaterialYaml(o.material);
    ClothModelRegistry::instance().validate(sample.model);
    for (const auto& m : o.fit_models) ClothModelRegistry::instance().validate(fittedModel(o, m));
  } catch (const std::exception& e) {
    std::cerr << "material_lab: " << e.what() << "\n";
    return kExitBadInput;
  }
  try {
    createDirectories(o.out_dir, 0755);
    checkWritableDirectory(o.out_dir);
  } catch (const OutputError& e) {
    std::cerr << "material_lab: " << e.what() << "\n";
    return kExitOutput;
  }
  std::cout << "material lab: model " << sample.model.text() << ", material " << sample.material.name << ", d = "
            << sample.spacing << " m\n";
  LabReport report;
  report.sample = sample;
  // A test that cannot be completed is reported and the others still run; the exit status says so.
  int failed = 0;
  for (const auto& test : o.tests)
    for (const YarnDirection dir : o.directions) {
      // The drape coefficient has no direction: it runs once.
      if (test == "drape" && dir != o.directions.front()) continue;
      std::cout << "  " << test << (test == "drape" ? "" : " " + toString(dir)) << " ..." << std::flush;
      try {
        if (test == "drape") report.drape.push_back(runDrapeCoefficient(sample, o.drape));
        if (test == "bending") report.bending.push_back(runKesBending(sample, dir, o.bending));
        if (test == "shear") report.shear.push_back(runKesShear(sample, dir, o.shear));
        if (test == "tensile") report.tensile.push_back(runKesTensile(sample, dir));
        if (test == "cantilever") report.cantilever.push_back(runCantilever(sample, dir));
        std::cout << " done\n";
      } catch (const MaterialLabError& e) {
        std::cout << " FAILED\n";
        std::cerr << "material_lab: " << e.what() << "\n";
        ++failed;
      } catch (const std::invalid_argument& e) {
        std::cout << " FAILED\n";
        std::cerr << "material_lab: " << e.what() << "\n";
        return kExitBadInput;
      }
    }
  // Fits need bending in both directions, shear and tensile (checked by fitMaterial).
  std::vector<MaterialFitResult> fits;
  for (const auto& m : o.fit_models) {
    std::cout << "  fit " << m << " ..." << std::flush;
    try {
      fits.push_back(fitMaterial(report, fittedModel(o, m), o.fit_spacing > 0 ? o.fit_spacing : sample.spacing,
                                 sample.material.name + "_fit_" + m, o.fit));
      std::cout << (fits.back().converged ? " converged" : " NOT converged") << " after " << fits.back().iterations
                << " lab runs\n";
      if (!fits.back().converged) ++failed;
      // The fitted model drapes the lab's disc sample too, for comparison with the tested model's drape.
      if (!report.drape.empty()) {
        LabSample fitted = fits.back().fitted.sample;
        fits.back().fitted.drape.push_back(runDrapeCoefficient(fitted, o.drape));
      }
    } catch (const MaterialLabError& e) {
      std::cout << " FAILED\n";
      std::cerr << "material_lab: " << e.what() << "\n";
      ++failed;
    }
  }
  const std::vector<LabFigure> figures = labFigures(report);
  std::cout << "figure,direction,unit,lab,material_file\n";
  for (const auto& f : figures)
    std::cout << f.name << ',' << f.direction << ',' << f.unit << ',' << f.value << ','
              << (std::isnan(f.material_value) ? std::string("") : std::to_string(f.material_value)) << '\n';
  try {
    const std::string& d = o.out_dir;
    writeFileAtomically(d + "/figures.csv", [&](std::ostream& f) { writeFiguresCsv(f, figures); });
    std::vector<std::pair<std::string, const std::vector<CurvePoint>*>> b, s, t;
    for (const auto& r : report.bending) {
      writeCurve(d + "/bending_" + toString(r.direction) + ".csv", "curvature_per_cm,moment_gf_cm_per_cm", r.cycle);
      b.emplace_back(toString(r.direction), &r.cycle);
    }
    for (const auto& r : report.shear) {
      writeCurve(d + "/shear_" + toString(r.direction) + ".csv", "shear_angle_rad,force_gf_per_cm", r.cycle);
      s.emplace_back(toString(r.direction), &r.cycle);
    }
    for (const auto& r : report.tensile) {
      writeCurve(d + "/tensile_" + toString(r.direction) + ".csv", "strain,force_gf_per_cm", r.cycle);
      t.emplace_back(toString(r.direction), &r.cycle);
    }
    for (const auto& r : report.cantilever)
      writeFileAtomically(d + "/cantilever_" + toString(r.direction) + ".csv", [&](std::ostream& f) {
        f.precision(10);
        f << "overhang_m,tip_angle_deg,newton_iterations\n";
        for (const auto& p : r.samples) f << p.overhang_m << ',' << p.angle_deg << ',' << p.iterations << '\n';
      });
    for (const auto& r : report.drape)
      writeFileAtomically(d + "/drape.csv", [&](std::ostream& f) {
        f.precision(10);
        f << "drape_coefficient,shadow_area_m2,sample_area_m2,disc_area_m2,nodes,rest_reached,sim_time_s,steps,wall_time_s\n"
          << r.drape_coefficient << ',' << r.shadow_area_m2 << ',' << r.sample_area_m2 << ',' << r.disc_area_m2 << ','
          << r.nodes << ',' << (r.rest_reached ? "true" : "false") << ',' << r.sim_time_s << ',' << r.steps << ','
          << r.wall_time_s << '\n';
      });
    for (const MaterialFitResult& fit : fits) writeFitOutputs(d, o, report, fit);
    const std::string title = sample.model.name + ", " + sample.material.name;
    if (!b.empty()) chart(d + "/bending.png", b, 1, "curvature [1/cm]", "moment [gf cm/cm]", "KES-FB2 bending: " + title);
    if (!s.empty()) chart(d + "/shear.png", s, 180 / kPi, "shear angle [deg]", "force [gf/cm]", "KES-FB1 shear: " + title);
    if (!t.empty()) chart(d + "/tensile.png", t, 100, "strain [%]", "force [gf/cm]", "KES-FB1 tensile: " + title);
    if (!report.bending.empty() && !report.shear.empty())
      writeFileAtomically(d + "/lab_material.yaml", [&](std::ostream& f) {
        f << "# Measured by material_lab from " << sample.model.text() << " with material " << sample.material.name
          << " at d = " << sample.spacing << " m (docs/material_lab.md)\n"
          << materialToYaml(measuredMaterial(report, sample.material.name + "_lab"));
      });
  } catch (const OutputError& e) {
    std::cerr << "material_lab: cannot write outputs: " << e.what() << "\n";
    return kExitOutput;
  }
  std::cout << "outputs in " << o.out_dir << "/\n";
  if (failed > 0) {
    std::cerr << "material_lab: " << failed << " test(s) could not be completed\n";
    return kExitTestFailed;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options options;
  const std::string problem = parseArguments(argc, argv, options);
  if (!problem.empty()) return usage(argv[0], problem);
  return runGuarded("material_lab", "use a coarser --spacing", [&] { return run(options); });
}
