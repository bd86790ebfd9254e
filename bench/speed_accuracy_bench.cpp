// speed_accuracy_bench: wall time against error of every cloth model x integrator x resolution on the same
// scenes (docs/speed_accuracy.md).
//
//   speed_accuracy_bench [--out DIR] [--scenes S,..] [--models M,..] [--integrators I,..] [--spacings D,..]
//                        [--reference-spacing D] [--reference-model M] [--model-option M:KEY=VALUE]...
//                        [--material M=PATH]... [--bending-scales M=F,..] [--align-mirror] [--repeats N]
//                        [--max-wall S] [--reference-max-wall S] [--max-sim-time S]
//                        [--auto [--auto-tolerance M] [--auto-min-iou X]] [--threads N]
//
// For each scene: one reference run per model (its finest, most accurate settings at --reference-spacing;
// with --reference-model, only that model's, and every run is compared with it), then every configuration,
// --repeats rounds interleaved (round 1 runs every configuration, later rounds the ones that did not fail);
// a configuration that hit the wall cap skips the finer spacings of its model and integrator. Errors come
// from round 1 (the runs are deterministic); wall times are given as min/median/max over the rounds and as
// ratios to the scene's baseline run of the same round (the first configuration, in the order models x
// integrators x spacings coarse to fine, that did not fail in round 1), which is how timings compare across
// machines and hours.
// Writes DIR/runs.csv (one row per run, written as it finishes), DIR/speed_accuracy.csv (one row per
// configuration) and DIR/speed_accuracy_<scene>.png (median wall-time ratio against the largest node
// distance, log-log; failed configurations drawn at the top edge). Timings are never asserted.
// --auto: before the configurations of a drape scene, the automatic choice (chooseConfiguration(), candidates
// = --spacings, the scene's semi_implicit settings) runs on the scene's own hold; its row is marked auto_choice
// and drawn as its own series, its search is written to DIR/automatic_choice.txt, and front_margin says how
// far it lies from the front (0 = on it). on_front marks the front of each scene (median ratio, largest node
// distance).
// --bending-scales M=F,..: model M runs once per factor F with both bending curves of its material times F
// (labels "M bend xF"), the way a material is tuned to another model's drape. --align-mirror: a drape held at
// one point may also match its reference mirrored (DrapeDifferenceOptions::align_mirror; column mirrored).
// --max-sim-time S: the drape scenes' simulated-time cap instead of their 8 s.
//
// Exit status: 0 done, 2 bad input or usage, 4 outputs cannot be written, 5 another unexpected error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <new>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/bench/speed_accuracy.h"
#include "textile_handling/db/automatic_configuration.h"
#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/thread_limit.h"
#include "tool_main.h"

using namespace textile_handling;

namespace {

constexpr int kExitBadInput = 2;
constexpr int kExitOutput = 4;

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ','))
    if (!item.empty()) out.push_back(item);
  if (out.empty()) throw std::invalid_argument("empty list '" + s + "'");
  return out;
}

Real parsePositive(const std::string& text, const std::string& option) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (end == text.c_str() || *end != '\0' || !std::isfinite(v) || !(v > 0))
    throw std::invalid_argument(option + " must be a positive number, got '" + text + "'");
  return v;
}

struct Options {
  std::string out = "speed_accuracy_out";
  std::vector<AccuracyScene> scenes = {AccuracyScene::kTowelCorner, AccuracyScene::kTowelEdge,
                                       AccuracyScene::kTableDrape, AccuracyScene::kPushedEdges};
  std::vector<AccuracyModel> models;
  std::vector<IntegratorType> integrators = {IntegratorType::kSemiImplicitEuler, IntegratorType::kBackwardEulerNewton,
                                             IntegratorType::kRK4, IntegratorType::kBlockDiagonalEuler};
  std::vector<Real> spacings = {0.02, 0.015, 0.01, 0.0075};
  Real reference_spacing = 0.005;
  std::string reference_model;  // empty: each model against its own reference
  int repeats = 3;
  AccuracyRunLimits limits;
  bool automatic = false;  // --auto: run the automatic choice per drape scene and mark it
  bool align_mirror = false;  // --align-mirror: one-point holds also compared mirrored
  db::AutomaticChoiceOptions auto_options;
};

AccuracyModel* findModel(Options& o, const std::string& name) {
  for (AccuracyModel& m : o.models)
    if (m.label == name) return &m;
  throw std::invalid_argument("model '" + name + "' is not in --models");
}

Options parseOptions(int argc, char** argv) {
  Options o;
  std::vector<std::string> model_names = {"particle_kes", "choi_ko", "yarn_woven"};
  std::vector<std::pair<std::string, std::string>> model_options, materials;
  std::vector<std::pair<std::string, std::vector<Real>>> bending_scales;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw std::invalid_argument(a + " needs a value");
      return argv[++i];
    };
    if (a == "--out") o.out = value();
    else if (a == "--scenes") {
      o.scenes.clear();
      for (const auto& s : splitList(value())) o.scenes.push_back(accuracySceneFromString(s));
    } else if (a == "--models") model_names = splitList(value());
    else if (a == "--integrators") {
      o.integrators.clear();
      for (const auto& s : splitList(value())) o.integrators.push_back(integratorFromString(s));
    } else if (a == "--spacings") {
      o.spacings.clear();
      for (const auto& s : splitList(value())) o.spacings.push_back(parsePositive(s, "--spacings"));
    } else if (a == "--reference-spacing") o.reference_spacing = parsePositive(value(), a);
    else if (a == "--reference-model") o.reference_model = value();
    else if (a == "--model-option") {
      const std::string v = value();
      const auto colon = v.find(':');
      if (colon == std::string::npos) throw std::invalid_argument("--model-option needs MODEL:KEY=VALUE, got '" + v + "'");
      model_options.emplace_back(v.substr(0, colon), v.substr(colon + 1));
    } else if (a == "--material") {
      const std::string v = value();
      const auto eq = v.find('=');
      if (eq == std::string::npos) throw std::invalid_argument("--material needs MODEL=PATH, got '" + v + "'");
      materials.emplace_back(v.substr(0, eq), v.substr(eq + 1));
    } else if (a == "--repeats") o.repeats = static_cast<int>(parsePositive(value(), a));
    else if (a == "--max-wall") o.limits.max_wall_s = parsePositive(value(), a);
    else if (a == "--reference-max-wall") o.limits.reference_max_wall_s = parsePositive(value(), a);
    else if (a == "--max-sim-time") o.limits.max_sim_time_s = parsePositive(value(), a);
    else if (a == "--auto") o.automatic = true;
    else if (a == "--align-mirror") o.align_mirror = true;
    else if (a == "--bending-scales") {
      const std::string v = value();
      const auto eq = v.find('=');
      if (eq == std::string::npos) throw std::invalid_argument("--bending-scales needs MODEL=F,.., got '" + v + "'");
      std::vector<Real> factors;
      for (const auto& f : splitList(v.substr(eq + 1))) factors.push_back(parsePositive(f, a));
      bending_scales.emplace_back(v.substr(0, eq), factors);
    }
    else if (a == "--auto-tolerance") o.auto_options.named_point_tolerance_m = parsePositive(value(), a);
    else if (a == "--auto-min-iou") o.auto_options.min_mean_iou = parsePositive(value(), a);
    else if (a == "--threads") {
      int threads = 0;
      std::string error, note;
      if (!parseThreadCount(value(), &threads, &error)) throw std::invalid_argument("--threads: " + error);
      applyThreadLimit(threads, &note);
    } else {
      throw std::invalid_argument("unknown option '" + a +
                                  "'; usage: speed_accuracy_bench [--out DIR] [--scenes S,..] [--models M,..] "
                                  "[--integrators I,..] [--spacings D,..] [--reference-spacing D] [--reference-model M] "
                                  "[--model-option M:KEY=VALUE]... [--material M=PATH]... [--bending-scales M=F,..] "
                                  "[--align-mirror] [--repeats N] [--max-wall S] [--max-sim-time S] "
                                  "[--reference-max-wall S] [--auto [--auto-tolerance M] [--auto-min-iou X]] [--threads N]");
    }
  }
  for (const std::string& n : model_names) {
    ClothModelRegistry::instance().find(n);  // throws naming the registered models
    AccuracyModel m;
    m.label = n;
    m.spec = ClothModelSpec(n);
    o.models.push_back(m);
  }
  for (const auto& mo : model_options) {
    const auto eq = mo.second.find('=');
    if (eq == std::string::npos) throw std::invalid_argument("--model-option needs MODEL:KEY=VALUE");
    findModel(o, mo.first)->spec.set(mo.second.substr(0, eq), mo.second.substr(eq + 1));
  }
  for (const AccuracyModel& m : o.models) ClothModelRegistry::instance().validate(m.spec);
  for (const auto& mat : materials) findModel(o, mat.first)->material = loadMaterialYaml(mat.second);
  for (const auto& [name, factors] : bending_scales) {
    const AccuracyModel base = *findModel(o, name);
    if (o.reference_model == name) throw std::invalid_argument("--bending-scales: " + name + " is the --reference-model");
    std::vector<AccuracyModel> variants;
    for (const Real f : factors) {
      AccuracyModel m = base;
      std::ostringstream label;
      label << name << " bend x" << f;
      m.label = label.str();
      m.material = scaledMaterial(base.material, f, 1, 1, base.material.name + "_" + label.str());
      variants.push_back(m);
    }
    auto at = std::find_if(o.models.begin(), o.models.end(), [&](const AccuracyModel& m) { return m.label == name; });
    at = o.models.erase(at);
    o.models.insert(at, variants.begin(), variants.end());
  }
  if (!o.reference_model.empty()) findModel(o, o.reference_model);
  std::sort(o.spacings.begin(), o.spacings.end(), std::greater<Real>());
  o.auto_options.spacings = o.spacings;
  if (o.automatic) o.auto_options.validate();
  return o;
}

struct ConfigResult {
  AccuracyScene scene;
  AccuracyConfig config;
  std::string reference;  // "model@spacing"
  AccuracyRun first;      // round 1
  db::DrapeDifference diff;
  bool compared = false;
  std::vector<Real> walls, ratios;
  bool skipped = false;
  bool baseline = false;  // the scene's timing baseline
  bool auto_choice = false;
  bool on_front = false;
  Real front_margin = std::nan("");
};

Real quantile(std::vector<Real> v, double q) {
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(std::lround(q * static_cast<double>(v.size() - 1)))];
}

std::string csvText(std::string s) {
  std::replace(s.begin(), s.end(), ',', ';');
  std::replace(s.begin(), s.end(), '"', '\'');
  std::replace(s.begin(), s.end(), '\n', ' ');
  return "\"" + s + "\"";
}

// One scene: the automatic choice (--auto), the references, the configurations in interleaved rounds, the
// front. Every run is appended to `runs` as it finishes.
std::vector<ConfigResult> runScene(AccuracyScene scene, const Options& o, std::ostream& runs, std::ostream& auto_report) {
  std::optional<db::AutomaticChoice> choice;
  if (o.automatic && scene != AccuracyScene::kPushedEdges) {
    const DrapeSceneSpec sample = accuracyDrapeSpec(
        scene, AccuracyConfig{o.models.front(), IntegratorType::kSemiImplicitEuler, o.spacings.front()});
    db::AutomaticChoiceOptions ao = o.auto_options;
    ao.on_progress = [&](const std::string& line) { std::cout << toString(scene) << " auto: " << line << "\n" << std::flush; };
    choice = db::chooseConfiguration({sample}, ao);
    auto_report << "scene " << toString(scene) << " (" << choice->search_wall_s << " s of search)\n"
                << choice->text() << "\n"
                << std::flush;
  }
  // References.
  std::map<std::string, AccuracyRun> refs;
  for (const AccuracyModel& m : o.models) {
    if (!o.reference_model.empty() && m.label != o.reference_model) continue;
    AccuracyConfig rc{m, IntegratorType::kSemiImplicitEuler, o.reference_spacing};
    std::cout << toString(scene) << ": reference " << m.label << " at d = " << o.reference_spacing << " m ... "
              << std::flush;
    AccuracyRun r = runAccuracyScene(scene, rc, o.limits, true);
    std::cout << r.status << " in " << r.wall_s << " s" << (r.note.empty() ? "" : " (" + r.note + ")") << "\n";
    runs << toString(scene) << ',' << m.label << ",reference," << o.reference_spacing << ",0," << r.status << ','
         << r.wall_s << ',' << r.steps << ',' << r.sim_time << ',' << r.nodes << ',' << csvText(r.note) << '\n'
         << std::flush;
    refs[m.label] = std::move(r);
  }
  std::vector<ConfigResult> rows;
  for (const AccuracyModel& m : o.models)
    for (IntegratorType t : o.integrators)
      for (Real d : o.spacings) {
        ConfigResult c;
        c.scene = scene;
        c.config = AccuracyConfig{m, t, d};
        rows.push_back(c);
      }
  std::size_t baseline_row = rows.size();  // the first configuration that does not fail in round 1
  for (int round = 1; round <= o.repeats; ++round) {
    Real baseline = std::nan("");
    for (std::size_t k = 0; k < rows.size(); ++k) {
      ConfigResult& c = rows[k];
      if (c.skipped || (round > 1 && c.first.failed())) continue;
      if (round == 1) {
        // A coarser spacing of the same model and integrator hit the wall cap: finer ones would too.
        for (std::size_t j = 0; j < k; ++j)
          if (rows[j].config.model.label == c.config.model.label && rows[j].config.integrator == c.config.integrator &&
              (rows[j].skipped || rows[j].first.status == "wall_cap"))
            c.skipped = true;
        if (c.skipped) continue;
      }
      AccuracyRun r = runAccuracyScene(scene, c.config, o.limits);
      std::cout << toString(scene) << " round " << round << ": " << c.config.model.label << " "
                << toString(c.config.integrator) << " d = " << c.config.spacing << ": " << r.status << " in "
                << r.wall_s << " s\n"
                << std::flush;
      runs << toString(scene) << ',' << c.config.model.label << ',' << toString(c.config.integrator) << ','
           << c.config.spacing << ',' << round << ',' << r.status << ',' << r.wall_s << ',' << r.steps << ','
           << r.sim_time << ',' << r.nodes << ',' << csvText(r.note) << '\n'
           << std::flush;
      if (round == 1 && baseline_row == rows.size() && !r.failed()) baseline_row = k;
      if (k == baseline_row && !r.failed()) baseline = r.wall_s;
      if (!r.failed()) {
        c.walls.push_back(r.wall_s);
        if (std::isfinite(baseline)) c.ratios.push_back(r.wall_s / baseline);
      }
      if (round == 1) {
        const std::string ref_label = o.reference_model.empty() ? c.config.model.label : o.reference_model;
        const AccuracyRun& ref = refs.at(ref_label);
        std::ostringstream rl;
        rl << ref_label << '@' << o.reference_spacing;
        c.reference = rl.str();
        if (!r.failed() && !ref.failed()) {
          db::DrapeDifferenceOptions diff_options = ref.differenceOptions();
          diff_options.align_mirror = o.align_mirror && ref.held_at_one_point;
          c.diff = db::measureDrapeDifference({&r.grid, r.positions}, {&ref.grid, ref.positions}, ref.view_centre,
                                              diff_options);
          c.compared = true;
        }
        r.positions.resize(0);  // keep only what the rows need
        c.first = std::move(r);
      }
    }
  }
  if (baseline_row < rows.size()) rows[baseline_row].baseline = true;
  {
    std::vector<Real> x, y;
    for (const ConfigResult& c : rows) {
      const bool usable = c.compared && !c.ratios.empty();
      x.push_back(usable ? quantile(c.ratios, 0.5) : std::nan(""));
      y.push_back(usable ? c.diff.max_node_distance : std::nan(""));
    }
    const std::vector<bool> front = speedAccuracyFront(x, y);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      rows[k].on_front = front[k];
      if (choice && rows[k].config.model.spec.name == choice->model.name &&
          rows[k].config.integrator == choice->settings.integrator &&
          std::abs(rows[k].config.spacing - choice->spacing) < 1e-12) {
        rows[k].auto_choice = true;
        if (std::isfinite(x[k]) && std::isfinite(y[k])) rows[k].front_margin = frontMargin(x, y, k);
        std::cout << toString(scene) << ": automatic choice " << choice->model.name << " d = " << choice->spacing
                  << ": " << (rows[k].first.failed() ? "failed" : "completed") << ", front margin "
                  << rows[k].front_margin << "\n";
      }
    }
  }
  return rows;
}

// The scene's chart: median wall-time ratio against the largest node distance; failed runs above the rest.
void writeSceneChart(const Options& o, AccuracyScene scene, const std::vector<ConfigResult>& rows) {
  std::vector<ChartPoint> pts;
  Real worst = 0;
  for (const ConfigResult& c : rows)
    if (c.compared) worst = std::max(worst, c.diff.max_node_distance);
  for (const ConfigResult& c : rows) {
    if (c.skipped) continue;
    const Real x = quantile(c.ratios, 0.5);
    std::ostringstream label;
    label << c.config.spacing * 100;
    ChartPoint p;
    p.x = std::isfinite(x) ? x : quantile(std::vector<Real>{c.first.wall_s}, 0.5);
    if (c.compared && c.diff.max_node_distance > 0) {
      p.y = c.diff.max_node_distance;
      p.series = c.auto_choice ? "automatic choice" : c.config.model.label + " " + toString(c.config.integrator);
      p.label = label.str();
    } else {
      p.y = std::max(worst, 1e-3) * 2;  // failed: drawn above every finished run
      p.series = "failed";
      p.label = c.config.model.label.substr(0, 2) + " " + toString(c.config.integrator).substr(0, 2) + " " + label.str();
    }
    if (p.x > 0 && p.y > 0) pts.push_back(p);
  }
  std::string error;
  if (!writeLogLogChart(o.out + "/speed_accuracy_" + toString(scene) + ".png", pts,
                        "wall time / baseline run (median of rounds)", "largest node distance to reference [m]",
                        toString(scene) + ": labels = spacing [cm]", &error))
    std::cerr << "speed_accuracy_bench: chart of " << toString(scene) << ": " << error << "\n";
}

void writeSummaryCsv(const Options& o, const std::vector<ConfigResult>& all) {
  std::ofstream csv(o.out + "/speed_accuracy.csv");
  if (!csv) throw OutputError("cannot write " + o.out + "/speed_accuracy.csv");
  csv << "scene,model,integrator,spacing_m,nodes,status,failed,reference,max_node_distance_m,mean_node_distance_m,"
         "max_named_point_distance_m,mean_iou,min_iou,yaw_deg,mirrored,rounds,wall_s_min,wall_s_median,wall_s_max,ratio_min,"
         "ratio_median,ratio_max,baseline,on_front,auto_choice,front_margin,steps,sim_time_s,note\n";
  for (const ConfigResult& c : all) {
    csv << toString(c.scene) << ',' << c.config.model.label << ',' << toString(c.config.integrator) << ','
        << c.config.spacing << ',' << c.first.nodes << ',' << (c.skipped ? "skipped" : c.first.status) << ','
        << (c.skipped || c.first.failed() ? 1 : 0) << ',' << c.reference << ',';
    if (c.compared)
      csv << c.diff.max_node_distance << ',' << c.diff.mean_node_distance << ',' << c.diff.max_named_point_distance
          << ',' << c.diff.mean_iou << ',' << c.diff.min_iou << ',' << c.diff.yaw_deg << ',' << (c.diff.mirrored ? 1 : 0)
          << ',';
    else
      csv << "nan,nan,nan,nan,nan,nan,nan,";
    csv << c.walls.size() << ',' << quantile(c.walls, 0) << ',' << quantile(c.walls, 0.5) << ','
        << quantile(c.walls, 1) << ',' << quantile(c.ratios, 0) << ',' << quantile(c.ratios, 0.5) << ','
        << quantile(c.ratios, 1) << ',' << (c.baseline ? 1 : 0) << ',' << (c.on_front ? 1 : 0) << ','
        << (c.auto_choice ? 1 : 0) << ',' << c.front_margin << ',' << c.first.steps << ',' << c.first.sim_time << ','
        << csvText(c.skipped ? "a coarser spacing hit the wall cap" : c.first.note) << '\n';
  }
  if (!csv) throw OutputError("cannot write " + o.out + "/speed_accuracy.csv");
  std::cout << "wrote " << o.out << "/speed_accuracy.csv\n";
}

int benchMain(int argc, char** argv) {
  const Options o = parseOptions(argc, argv);
  std::error_code ec;
  std::filesystem::create_directories(o.out, ec);
  if (ec) throw OutputError("cannot create " + o.out + ": " + ec.message());
  std::ofstream runs(o.out + "/runs.csv");
  if (!runs) throw OutputError("cannot write " + o.out + "/runs.csv");
  runs << "scene,model,integrator,spacing_m,round,status,wall_s,steps,sim_time_s,nodes,note\n";
  std::vector<ConfigResult> all;
  std::ofstream auto_report;
  if (o.automatic) {
    auto_report.open(o.out + "/automatic_choice.txt");
    if (!auto_report) throw OutputError("cannot write " + o.out + "/automatic_choice.txt");
  }
  for (AccuracyScene scene : o.scenes) {
    const std::vector<ConfigResult> rows = runScene(scene, o, runs, auto_report);
    writeSceneChart(o, scene, rows);
    all.insert(all.end(), rows.begin(), rows.end());
  }
  writeSummaryCsv(o, all);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  return runGuarded("speed_accuracy_bench", "use coarser --spacings", [&] {
    try {
      return benchMain(argc, argv);
    } catch (const OutputError& e) {
      std::cerr << "speed_accuracy_bench: cannot write outputs: " << e.what() << "\n";
      return kExitOutput;
    } catch (const std::invalid_argument& e) {
      std::cerr << "speed_accuracy_bench: " << e.what() << "\n";
      return kExitBadInput;
    }
  });
}
