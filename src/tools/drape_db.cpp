// drape_db: builds, inspects, queries and exports the hanging-drape database, and runs the thesis's
// recognition benchmark. See docs/database.md.
//
//   drape_db build  --db DB --textile NAME [--spacing D] [--lattice S | --grid NXxNY | --hold X,Y ...]
//                   [--material FILE] [--name NAME] [--threads N] [--sim-threads M] [simulation options]
//                   [--auto [--auto-spacings D,..] [--auto-tolerance M] [--auto-min-iou X] [--auto-samples N]
//                           [--auto-step-factors F,..|none] [--auto-members LIST|none] [--question Q]]
//                   [--mpi] [--claim-lease S] [--progress-records]
//   drape_db build  --db DB --job FILE [--mpi] [--threads N] [--sim-threads M] [--claim-lease S] [--progress-records]
//   drape_db list   --db DB [--simulations] [--textile NAME] [--check]
//   drape_db query  --db DB (--mask PNG | --image PNG) --hold-pixel U,V --metres-per-pixel M [--top K]
//                   [--second-mask PNG | --second-image PNG, --second-hold-pixel U,V, --second-metres-per-pixel M,
//                    --relative-view DEG] [--canonical] [--textile NAME]
//   drape_db export --db DB --simulation ID [--ply OUT.ply] [--obj OUT.obj] [--png-dir DIR]
//   drape_db bench  --out DIR [--quick] [--resume] [--threads N] [--pairs N] [--seed S] [--spacing D]
//                   [--heldout-spacing D] [--frame PX@METRES] [--shift DX_M,DY_M | --thesis-shift] [--no-bracket]
//                   [--cg-tolerance R] [--cg-cold-start]
//
// DB is an SQLite file path or a postgresql:// URL (docs/database.md, "Storage backends").
//
// Exit status: 0 success, 1 unexpected error, 2 usage or bad input, 3 database error (cannot open, unknown
// schema version, damaged data), 4 build finished but some simulations failed, 5 out of memory.
//
// Input limits (docs/database.md "Query limits"): checked before anything is read or allocated.
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "build_progress_printer.h"
#include "textile_handling/bench/thesis_benchmark.h"
#include "textile_handling/db/automatic_configuration.h"
#include "textile_handling/db/build_progress_records.h"
#include "textile_handling/db/drape_build_job.h"
#include "textile_handling/db/drape_build_members.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/db/drape_match_evaluation.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/farm/mpi_build_farm.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/text_input.h"
#include "textile_handling/sim/thread_limit.h"
#include "textile_handling/vision/image_header.h"
#include "textile_handling/vision/mask_cv.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

// Largest --grid side: 1000 x 1000 hold points already take days to simulate.
constexpr int kMaxGridSide = 1000;

constexpr int kExitOk = 0, kExitError = 1, kExitUsage = 2, kExitDatabase = 3, kExitFailedSims = 4, kExitNoMemory = 5;

// Query limits. A camera pixel covers 1 um .. 1 m at the textile (anything else is a typo, and a tiny
// scale makes the canonical window span astronomically many pixels); hold pixels lie within 10^6 px of
// the image; a shift search of more than 1 m is no alignment of a textile silhouette; 1000 candidates
// are more than any database has classes worth listing.
constexpr double kMinMetresPerPixel = 1e-6, kMaxMetresPerPixel = 1.0;
constexpr double kMaxHoldPixel = 1e6;
constexpr double kMaxQueryShiftMetres = 1.0;
constexpr int kMaxTop = 1000;
// Input files: images up to 25 MP (the recognizer's default max_image_pixels) and 256 MiB on disk; a
// material YAML is a few hundred bytes, 1 MiB bounds the parser's memory.
constexpr std::int64_t kMaxImagePixels = 25'000'000;
constexpr std::uintmax_t kMaxImageFileBytes = std::uintmax_t{256} << 20;
constexpr std::uintmax_t kMaxYamlFileBytes = std::uintmax_t{1} << 20;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

const char* kUsage =
    "usage: drape_db COMMAND [options]   (DB: an SQLite file or a postgresql://user@host:port/database URL)\n"
    "  build  --db DB --textile NAME [--spacing D=0.02] [--lattice S=0.08 | --grid NXxNY | --hold X,Y ...]\n"
    "         [--material FILE] [--name NAME] [--threads N] [--sim-threads M] [--no-symmetry] [--retry-failed]\n"
    "         [--rest-method dynamic|quasi_static] [--coarse-spacing D=0.02] [--no-coarse-finish]\n"
    "         [--views N] [--frame WxH@METRES] [--integrator semi_implicit|block_diagonal|rk4|backward_euler_newton]\n"
    "         [--policy error|thesis|fixed] [--linear-solver direct|cg] [--jacobian definite_fix|exact]\n"
    "         [--dt-max S] [--tolerance M] [--max-time S] [--settle-damping Z] [--cg-tolerance R] [--cg-cold-start]\n"
    "         [--model NAME] [--model-option KEY=VALUE]... [--allow-no-rest] [--quiet]\n"
    "         [--auto [--auto-spacings D,D,..] [--auto-tolerance M=0.03] [--auto-min-iou X=0.85]\n"
    "                 [--auto-samples N=3] [--auto-step-factors F,..|none=none] [--auto-members LIST|none=soft_light]\n"
    "                 [--question none|pull_out|sliding|tearing]]\n"
    "         [--bracket] [--self-collision] [--memory-budget-mb M] [--members LIST|standard]\n"
    "         [--mpi] [--claim-lease S=60] [--progress-records]\n"
    "  build  --db DB --job FILE [--mpi] [--threads N] [--sim-threads M] [--claim-lease S] [--quiet] [--progress-records]\n"
    "  list   --db DB [--simulations] [--textile NAME] [--check]\n"
    "  query  --db DB (--mask PNG | --image PNG [--background B,G,R] [--threshold T])\n"
    "         --hold-pixel U,V --metres-per-pixel M [--canonical] [--top K=5] [--textile NAME]\n"
    "         [--second-mask PNG | --second-image PNG] [--second-hold-pixel U,V] [--second-metres-per-pixel M]\n"
    "         [--relative-view DEG] [--shift DX_M,DY_M]\n"
    "  export --db DB --simulation ID [--ply OUT.ply] [--obj OUT.obj] [--png-dir DIR]\n"
    "  bench  --out DIR [--quick] [--resume] [--threads N] [--pairs N] [--seed S] [--spacing D]\n"
    "         [--heldout-spacing D] [--frame PX@METRES] [--shift DX_M,DY_M | --thesis-shift] [--no-bracket]\n"
    "         [--cg-tolerance R] [--cg-cold-start]\n"
    "exit status: 0 ok, 1 error, 2 usage/bad input, 3 database error, 4 some simulations failed, 5 out of memory\n";

// Minimal option parser: "--key value" pairs and "--flag" switches; repeated keys are kept in order.
class Args {
 public:
  Args(int argc, char** argv, int first, const std::vector<std::string>& flags) {
    for (int i = first; i < argc; ++i) {
      std::string a = argv[i];
      if (a.rfind("--", 0) != 0) throw UsageError("unexpected argument '" + a + "'");
      if (std::find(flags.begin(), flags.end(), a) != flags.end()) {
        values_[a].push_back("");
        continue;
      }
      if (i + 1 >= argc) throw UsageError("option " + a + " needs a value");
      values_[a].push_back(argv[++i]);
    }
  }
  bool has(const std::string& k) const { return values_.count(k) > 0; }
  std::string get(const std::string& k, const std::string& fallback = "") const {
    auto it = values_.find(k);
    return it == values_.end() ? fallback : it->second.back();
  }
  std::string require(const std::string& k) const {
    if (!has(k)) throw UsageError("missing option " + k);
    return get(k);
  }
  std::vector<std::string> all(const std::string& k) const {
    auto it = values_.find(k);
    return it == values_.end() ? std::vector<std::string>() : it->second;
  }
  void allowOnly(const std::vector<std::string>& known) const {
    for (const auto& [k, v] : values_)
      if (std::find(known.begin(), known.end(), k) == known.end()) throw UsageError("unknown option " + k);
  }

 private:
  std::map<std::string, std::vector<std::string>> values_;
};

double number(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || *end != '\0' || !std::isfinite(v)) throw UsageError(what + ": '" + text + "' is not a finite number");
  return v;
}

int integer(const std::string& text, const std::string& what) {
  const double v = number(text, what);
  if (v != std::floor(v) || std::abs(v) > 1e9) throw UsageError(what + ": '" + text + "' is not an integer");
  return static_cast<int>(v);
}

// A thread count: 1..kMaxRequestableThreads, lowered to maxUsefulThreads() with a note on stderr.
int threadCount(const std::string& text, const std::string& what) {
  int n = 0;
  std::string why;
  if (!parseThreadCount(text, &n, &why)) throw UsageError(what + ": " + why);
  if (n > maxUsefulThreads()) {
    std::cerr << "note: " << what << " " << n << " lowered to " << maxUsefulThreads() << " (twice the hardware threads)\n";
    n = maxUsefulThreads();
  }
  return n;
}

// Comma-separated numbers, each checked by number().
std::vector<double> numberList(const std::string& text, const std::string& what) {
  std::vector<double> out;
  std::stringstream ss(text);
  std::string part;
  while (std::getline(ss, part, ',')) out.push_back(number(part, what));
  return out;
}

std::vector<double> numbers(const std::string& text, std::size_t n, const std::string& what) {
  const std::vector<double> out = numberList(text, what);
  if (out.size() != n) throw UsageError(what + ": expected " + std::to_string(n) + " comma-separated numbers");
  return out;
}

double numberIn(const std::string& text, double lo, double hi, const std::string& what) {
  const double v = number(text, what);
  if (!(v >= lo && v <= hi))
    throw UsageError(what + ": " + text + " is out of range [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  return v;
}

// Refuses a missing or too large input file before it is parsed (`what` names the option).
void checkFileSize(const std::string& path, std::uintmax_t max_bytes, const std::string& what) {
  std::error_code ec;
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw UsageError(what + ": cannot read '" + path + "': " + ec.message());
  if (size > max_bytes)
    throw UsageError(what + ": '" + path + "' is " + std::to_string(size) + " bytes, more than the limit of " +
                     std::to_string(max_bytes));
}

// Reads an image with its size bounded: the file size, then the width and height from its header
// (PNG, JPEG, BMP, PNM), all before OpenCV decodes (and allocates) it.
cv::Mat readImage(const std::string& path, int flags, const std::string& what) {
  checkFileSize(path, kMaxImageFileBytes, what);
  vision::ImageDimensions d;
  try {
    d = vision::readImageDimensions(path);
  } catch (const std::invalid_argument& e) {
    throw UsageError(what + ": " + e.what());
  }
  if (d.width > kMaxImagePixels / d.height)
    throw UsageError(what + ": image '" + path + "' is " + std::to_string(d.width) + " x " + std::to_string(d.height) +
                     " px, more than the limit of " + std::to_string(kMaxImagePixels) + " pixels");
  const cv::Mat img = cv::imread(path, flags);
  if (img.empty()) throw UsageError(what + ": cannot decode image '" + path + "'");
  if (static_cast<std::int64_t>(img.cols) * img.rows > kMaxImagePixels)  // a header that lied
    throw UsageError(what + ": image '" + path + "' has more than " + std::to_string(kMaxImagePixels) + " pixels");
  return img;
}

std::string fixed(double v, int p) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(p) << v;
  return os.str();
}

// ---- build ------------------------------------------------------------------------------------

int printBuildReport(const HangingDrapeDatabase& db, const DrapeBuildConfig& c, const DrapeBuildReport& r,
                     bool records);

// What one `drape_db build` builds: a configuration and its database members.
struct BuildRequest {
  DrapeBuildConfig config;
  std::vector<DrapeMemberSpec> members;
};
int buildHere(const Args& a, BuildRequest request);
int buildOnFarm(const Args& a, const std::function<BuildRequest(const farm::MpiSession&)>& request);

// The progress printer of a build: machine-readable records (--progress-records) or the bar.
tools::BuildProgressPrinter progressPrinter(const Args& a) {
  return a.has("--progress-records") ? tools::BuildProgressPrinter::recordsOnStderr()
                                     : tools::BuildProgressPrinter::forStderr();
}

// `build --job FILE`: the build a TextileRegistry handed over (drape_build_job.h). The file holds the
// textile, material, members and every simulation setting; the command line adds only where and how it
// runs. On a farm, rank 0 reads the file and sends its text to the other ranks, so only rank 0's machine
// needs it.
int cmdBuildJob(const Args& a) {
  try {
    a.allowOnly({"--db", "--job", "--mpi", "--claim-lease", "--threads", "--sim-threads", "--quiet", "--progress-records"});
  } catch (const UsageError& e) {
    throw UsageError(std::string(e.what()) + " with --job (the job file holds the textile and every build setting)");
  }
  const auto fromJob = [&a](const DrapeBuildJob& job) {
    BuildRequest r{job.config, drapeMembersByName(job.members)};
    if (a.has("--threads")) r.config.workers = threadCount(a.get("--threads"), "--threads");
    if (a.has("--sim-threads")) r.config.threads_per_simulation = threadCount(a.get("--sim-threads"), "--sim-threads");
    if (a.has("--claim-lease")) r.config.claim_lease_s = numberIn(a.get("--claim-lease"), 3, 1e6, "--claim-lease");
    return r;
  };
  if (!a.has("--mpi")) return buildHere(a, fromJob(loadDrapeBuildJob(a.require("--job"))));
  return buildOnFarm(a, [&](const farm::MpiSession& session) {
    std::string text;
    if (session.rank() == 0) {
      std::string error;
      if (!readBoundedTextFile(a.require("--job"), kMaxBuildJobBytes, &text, &error))
        throw InvalidInputError("build job '" + a.get("--job") + "': " + error);
    }
    return fromJob(parseDrapeBuildJob(session.broadcastText(text)));
  });
}

// --auto: model, spacing, integrator, policy and step tolerance from the search on a spread sample of the build's
// hold points (automatic_configuration.h); the choice and its evidence are printed and go into the build's
// parameter text.
// With the members rule (--auto-members, soft_light unless none) the members it takes join `members`.
void chooseAutomatically(const Args& a, const TextileSymmetry& sym, DrapeBuildConfig& c, std::vector<DrapeMemberSpec>& members) {
  AutomaticChoiceOptions o;
  o.views = c.views;
  o.frame = c.frame;
  if (a.has("--auto-spacings")) o.spacings = numberList(a.get("--auto-spacings"), "--auto-spacings");
  if (a.has("--auto-tolerance")) o.named_point_tolerance_m = number(a.get("--auto-tolerance"), "--auto-tolerance");
  if (a.has("--auto-min-iou")) o.min_mean_iou = number(a.get("--auto-min-iou"), "--auto-min-iou");
  // Off unless asked: with 3 times the builder's 0.1 mm the towel build saved a quarter of its simulation time
  // but a third of its rest shapes fell into other equilibria (docs/automatic_configuration.md).
  const std::string factors = a.get("--auto-step-factors", "none");
  if (factors != "none") o.error_tolerance_factors = numberList(factors, "--auto-step-factors");
  const Real samples = number(a.get("--auto-samples", "3"), "--auto-samples");
  if (!(samples >= 1 && samples <= 20 && samples == std::floor(samples)))
    throw UsageError("--auto-samples must be a whole number in [1, 20]");
  try {
    o.question = yarnScaleQuestionFromString(a.get("--question", "none"));
    o.validate();
  } catch (const InvalidInputError& e) {
    throw UsageError(e.what());
  }
  // The build mirrors rest shapes only on a mirror-symmetric grid (a quarter of a towel's hold points are
  // simulated), so each candidate becomes the nearest finer spacing with such a grid.
  if (sym.any()) {
    std::vector<Real> snapped;
    for (Real d : o.spacings) snapped.push_back(mirrorSymmetricSpacing(c.textile, sym, d));
    snapped = distinctSpacingsCoarseFirst(snapped);
    if (snapped.size() < 2)
      throw UsageError("--auto-spacings: the candidates give fewer than two different mirror-symmetric grids");
    std::ostringstream line;
    for (Real d : snapped) line << (line.tellp() > 0 ? ", " : "") << d;
    std::cout << "automatic choice: candidate spacings on mirror-symmetric grids: " << line.str() << " m\n";
    o.spacings = snapped;
  }
  const std::vector<Vec2> candidates =
      c.hold_points.empty() ? fundamentalDomainLattice(c.textile, sym, c.lattice_spacing) : c.hold_points;
  std::vector<DrapeSceneSpec> scenes;
  const std::vector<Vec2> sample_points = spreadSample(candidates, static_cast<int>(samples));
  for (const Vec2& p : sample_points) scenes.push_back(DrapeDatabaseBuilder::sceneSpec(c, p));
  // Members the rule may add where no spacing converges (soft_light by default: of the members tried on the
  // towel it alone kept recognition level; docs/automatic_configuration.md). Members the build makes anyway
  // are not offered.
  std::vector<DrapeMemberSpec> offered;
  try {
    const std::string list = a.get("--auto-members", "soft_light");
    if (list != "none") offered = drapeMembersByName(list);
  } catch (const InvalidInputError& e) {
    throw UsageError(std::string("--auto-members: ") + e.what());
  }
  for (const DrapeMemberSpec& m : offered) {
    if (m.name == "base") throw UsageError("--auto-members: the base member is always built; list extra members only");
    if (std::any_of(members.begin(), members.end(), [&](const DrapeMemberSpec& b) { return b.name == m.name; })) continue;
    const DrapeBuildConfig member_config = memberBuildConfig(c, m);
    AutomaticChoiceOptions::MemberSamples ms{m.name, {}};
    for (const Vec2& p : sample_points) ms.scenes.push_back(DrapeDatabaseBuilder::sceneSpec(member_config, p));
    o.member_samples.push_back(ms);
  }
  if (!a.has("--quiet")) o.on_progress = [](const std::string& line) { std::cerr << "auto: " << line << "\n"; };
  const AutomaticChoice choice = chooseConfiguration(scenes, o);
  std::cout << "automatic choice (" << fixed(choice.search_wall_s, 1) << " s of search):\n" << choice.text();
  c.model = choice.model;
  c.spacing = choice.spacing;
  c.settings = choice.settings;
  c.automatic_choice = choice.text();
  for (const std::string& name : choice.members)
    for (const DrapeMemberSpec& m : offered)
      if (m.name == name) members.push_back(m);
}

int cmdBuild(const Args& a) {
  if (a.has("--job")) return cmdBuildJob(a);
  a.allowOnly({"--progress-records", "--db", "--textile", "--spacing", "--lattice", "--grid", "--hold", "--material", "--name", "--threads",
               "--sim-threads", "--no-symmetry", "--retry-failed", "--views", "--frame", "--integrator", "--policy",
               "--linear-solver", "--jacobian", "--dt-max", "--tolerance", "--max-time", "--settle-damping",
               "--cg-tolerance", "--cg-warm-start", "--cg-cold-start", "--model", "--model-option", "--allow-no-rest", "--quiet", "--bracket",
               "--self-collision", "--memory-budget-mb", "--rest-method", "--coarse-spacing", "--no-coarse-finish", "--members",
               "--auto", "--auto-spacings", "--auto-tolerance", "--auto-min-iou", "--auto-samples", "--auto-step-factors",
               "--auto-members", "--question", "--mpi", "--claim-lease"});
  if (a.has("--mpi") && a.has("--auto"))
    throw UsageError("--auto cannot run on a farm (--mpi): run it once without --mpi and pass its choice");
  if (a.has("--auto"))
    for (const char* fixed_by_auto : {"--spacing", "--model", "--integrator", "--policy"})
      if (a.has(fixed_by_auto))
        throw UsageError(std::string("--auto chooses the model, spacing, integrator and policy: drop ") + fixed_by_auto);
  for (const char* auto_only :
       {"--auto-spacings", "--auto-tolerance", "--auto-min-iou", "--auto-samples", "--auto-step-factors", "--auto-members",
        "--question"})
    if (a.has(auto_only) && !a.has("--auto")) throw UsageError(std::string(auto_only) + " needs --auto");
  DrapeBuildConfig c;
  try {
    c.textile = presetTextile(a.require("--textile"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (a.has("--name")) c.textile.name = a.get("--name");
  if (a.has("--material")) {
    checkFileSize(a.get("--material"), kMaxYamlFileBytes, "--material");
    try {
      c.material = loadMaterialYaml(a.get("--material"));
    } catch (const MaterialError& e) {
      throw UsageError(e.what());
    }
  }
  c.spacing = number(a.get("--spacing", "0.02"), "--spacing");
  c.lattice_spacing = number(a.get("--lattice", "0.08"), "--lattice");
  const TextileSymmetry sym = a.has("--no-symmetry") ? TextileSymmetry{} : detectSymmetry(c.textile);
  if (a.has("--grid")) {
    const std::string g = a.get("--grid");
    const auto x = g.find('x');
    if (x == std::string::npos) throw UsageError("--grid: expected NXxNY, e.g. 6x6");
    const int nx = integer(g.substr(0, x), "--grid"), ny = integer(g.substr(x + 1), "--grid");
    if (nx < 1 || ny < 1 || nx > kMaxGridSide || ny > kMaxGridSide)
      throw UsageError("--grid: each side must be 1.." + std::to_string(kMaxGridSide));
    c.hold_points = fundamentalDomainGrid(c.textile, sym, nx, ny);
  }
  for (const std::string& h : a.all("--hold")) {
    const auto v = numbers(h, 2, "--hold");
    c.hold_points.emplace_back(v[0], v[1]);
  }
  c.use_symmetry = !a.has("--no-symmetry");
  c.bracket_hold_points = a.has("--bracket");
  c.retry_failed = a.has("--retry-failed");
  if (a.has("--threads")) c.workers = threadCount(a.get("--threads"), "--threads");
  if (a.has("--sim-threads")) c.threads_per_simulation = threadCount(a.get("--sim-threads"), "--sim-threads");
  if (a.has("--memory-budget-mb")) {
    const double mb = number(a.get("--memory-budget-mb"), "--memory-budget-mb");
    if (!(mb > 0 && mb <= 1e12)) throw UsageError("--memory-budget-mb must be a positive number of MiB");
    c.settings.memory_budget_bytes = static_cast<std::size_t>(mb * 1024 * 1024);
  }
  if (a.has("--views")) {
    c.views.count = integer(a.get("--views"), "--views");
    if (c.views.count < 1) throw UsageError("--views must be >= 1");
    c.views.step_deg = 360.0 / c.views.count;
  }
  if (a.has("--frame")) {
    const std::string f = a.get("--frame");
    const auto x = f.find('x'), at = f.find('@');
    if (x == std::string::npos || at == std::string::npos || at < x) throw UsageError("--frame: expected WxH@METRES");
    const int w = integer(f.substr(0, x), "--frame"), h = integer(f.substr(x + 1, at - x - 1), "--frame");
    const double m = number(f.substr(at + 1), "--frame");
    if (w < 1 || h < 1 || !(m > 0)) throw UsageError("--frame: sizes must be positive");
    c.frame.width_px = w;
    c.frame.height_px = h;
    c.frame.metres_per_pixel = m / w;
  }
  try {
    if (a.has("--integrator")) c.settings.integrator = integratorFromString(a.get("--integrator"));
    if (a.has("--policy")) c.settings.policy = stepPolicyFromString(a.get("--policy"));
    if (a.has("--linear-solver")) c.settings.solver.kind = linearSolverFromString(a.get("--linear-solver"));
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
  if (a.has("--dt-max")) c.settings.dt_max = number(a.get("--dt-max"), "--dt-max");
  if (a.has("--tolerance")) c.settings.error_tolerance = number(a.get("--tolerance"), "--tolerance");
  if (a.has("--cg-tolerance")) {
    c.settings.solver.relative_tolerance = number(a.get("--cg-tolerance"), "--cg-tolerance");
    if (!(c.settings.solver.relative_tolerance > 0 && c.settings.solver.relative_tolerance < 1))
      throw UsageError("--cg-tolerance must be in (0, 1)");
  }
  if (a.has("--cg-warm-start") && a.has("--cg-cold-start")) throw UsageError("--cg-warm-start and --cg-cold-start exclude each other");
  if (a.has("--cg-warm-start")) c.settings.solver.warm_start = true;  // the default; kept for old scripts
  if (a.has("--cg-cold-start")) c.settings.solver.warm_start = false;
  if (a.has("--self-collision")) c.self_collision = true;
  if (a.has("--max-time")) c.settings.max_time = number(a.get("--max-time"), "--max-time");
  // The model and its options, checked through the model registry before the database file is opened
  // (and created): the build's defaults for the model, then --jacobian, --settle-damping and every
  // --model-option KEY=VALUE (a key of the scene file's model: section).
  try {
    if (a.has("--model")) c.model = DrapeBuildConfig::defaultModelSpec(a.get("--model"));
    if (a.has("--jacobian")) c.model.set("jacobian", a.get("--jacobian"));
    if (a.has("--settle-damping")) c.model.set("settle_damping_per_s", a.get("--settle-damping"));
    for (const std::string& kv : a.all("--model-option")) {
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) throw UsageError("--model-option: expected KEY=VALUE, got '" + kv + "'");
      c.model.set(kv.substr(0, eq), kv.substr(eq + 1));
    }
    ClothModelRegistry::instance().validate(c.model);
  } catch (const ClothModelError& e) {
    throw UsageError(std::string("--model: ") + e.what());
  }
  c.require_rest = !a.has("--allow-no-rest");
  try {
    if (a.has("--rest-method")) c.rest_shape.method = restShapeMethodFromString(a.get("--rest-method"));
  } catch (const SimError& e) {
    throw UsageError(std::string("--rest-method: ") + e.what());
  }
  if (a.has("--coarse-spacing")) {
    c.rest_shape.coarse_spacing = number(a.get("--coarse-spacing"), "--coarse-spacing");
    if (!(c.rest_shape.coarse_spacing >= 0 && c.rest_shape.coarse_spacing <= 1))
      throw UsageError("--coarse-spacing must be in [0, 1] m (0 = no coarse level)");
  }
  c.rest_shape.coarse_static_finish = !a.has("--no-coarse-finish");

  std::vector<DrapeMemberSpec> members;
  try {
    members = drapeMembersByName(a.get("--members", "base"));
  } catch (const InvalidInputError& e) {
    throw UsageError(std::string("--members: ") + e.what());
  }

  if (a.has("--auto")) chooseAutomatically(a, sym, c, members);

  if (a.has("--claim-lease")) c.claim_lease_s = numberIn(a.get("--claim-lease"), 3, 1e6, "--claim-lease");
  if (a.has("--mpi")) return buildOnFarm(a, [&](const farm::MpiSession&) { return BuildRequest{c, members}; });
  return buildHere(a, {c, members});
}

// A build in this process, member after member.
int buildHere(const Args& a, BuildRequest request) {
  DrapeBuildConfig& c = request.config;
  const std::vector<DrapeMemberSpec>& members = request.members;
  tools::BuildProgressPrinter progress = progressPrinter(a);
  if (!a.has("--quiet")) progress.attach(c);
  HangingDrapeDatabase db(a.require("--db"));
  int status = kExitOk;
  for (const DrapeMemberSpec& m : members) {
    if (members.size() > 1 || m.name != "base") std::cout << "member " << m.name << ": " << m.description << "\n";
    const DrapeBuildConfig mc = memberBuildConfig(c, m);
    DrapeDatabaseBuilder builder(db, mc);
    if (printBuildReport(db, mc, builder.build(), a.has("--progress-records")) != kExitOk) status = kExitFailedSims;
  }
  if (members.size() > 1) {
    std::cout << "finished rest shapes per member:";
    const auto t = db.findTextile(c.textile.name);
    if (t)
      for (const auto& [name, count] : storedMembers(db, t->id)) std::cout << " " << name << " " << count;
    std::cout << "\n";
  }
  return status;
}

// `build --mpi`: the same build on every rank of the MPI job (docs/build_farm.md). Rank 0 prints; a
// fatal error on any rank ends the whole job.
int buildOnFarm(const Args& a, const std::function<BuildRequest(const farm::MpiSession&)>& request) {
  farm::MpiSession session(nullptr, nullptr);
  farm::FarmBuildInput in;
  in.database = a.require("--db");
  std::vector<DrapeMemberSpec> members;
  tools::BuildProgressPrinter progress = progressPrinter(a);
  in.on_member_start = [&](std::size_t k, DrapeBuildConfig& mc) {
    if (members.size() > 1 || members[k].name != "base")
      std::cout << "member " << members[k].name << ": " << members[k].description << "\n";
    if (!a.has("--quiet")) progress.attach(mc);
  };
  farm::FarmBuildResult r;
  try {
    const BuildRequest req = request(session);
    members = req.members;
    for (const DrapeMemberSpec& m : members) {
      DrapeBuildConfig mc = memberBuildConfig(req.config, m);
      // A rank runs one simulation at a time unless --threads says otherwise (PostgreSQL: every rank builds).
      if (!a.has("--threads")) mc.workers = 1;
      if (!a.has("--sim-threads")) mc.threads_per_simulation = 1;
      in.members.push_back(mc);
    }
    r = farm::runFarmBuild(session, in);
  } catch (const std::exception& e) {
    std::cerr << "drape_db build (rank " << session.rank() << " of " << session.size() << "): " << e.what()
              << "; ending the farm job (run the same command again to resume)\n";
    std::cerr.flush();
    session.abort(dynamic_cast<const DrapeDatabaseError*>(&e) && !dynamic_cast<const InvalidInputError*>(&e)
                      ? kExitDatabase
                      : kExitUsage);
  }
  if (session.rank() != 0) return kExitOk;
  std::cout << "farm: " << r.ranks << " ranks, "
            << (r.shared_database ? "every rank a builder of the shared PostgreSQL database"
                                  : "rank 0 writes the SQLite file, every rank simulates")
            << "\n";
  HangingDrapeDatabase db(in.database, [] {
    DatabaseOpenOptions o;
    o.read_only = true;
    return o;
  }());
  int status = kExitOk;
  for (std::size_t k = 0; k < r.reports.size(); ++k)
    if (printBuildReport(db, in.members[k], r.reports[k], a.has("--progress-records")) != kExitOk)
      status = kExitFailedSims;
  return status;
}

// The summary of one build (one member) on stdout; kExitFailedSims if rows of these settings failed.
// With `records`, first the machine-readable report line on stderr (build_progress_records.h).
int printBuildReport(const HangingDrapeDatabase& db, const DrapeBuildConfig& c, const DrapeBuildReport& r,
                     bool records) {
  if (records) {  // one write, so that no other output (or mpirun's forwarding) splits the line
    std::cout.flush();
    std::cerr << reportRecord(r) << std::flush;
  }
  std::cout << "textile '" << c.textile.name << "' (id " << r.textile_id << "), symmetry " << r.symmetry
            << (r.symmetric_grid ? "" : " (grid not symmetric: every hold point simulated)") << "\n"
            << "hold points: " << r.planned << " (" << r.to_simulate << " simulated, " << r.planned - r.to_simulate
            << " mirrored)\n"
            << "this build: " << r.simulated_now << " simulations done, " << r.failed_now << " failed, "
            << r.derived_now << " mirrored entries derived, " << r.already_done << " were already done"
            << (r.done_elsewhere ? ", " + std::to_string(r.done_elsewhere) + " run by other builders" : std::string()) << "; "
            << fixed(r.wall_seconds, 1) << " s wall, " << fixed(r.simulation_seconds, 1) << " s simulation time\n";
  for (const auto& f : r.failures) std::cout << "failed: " << f << "\n";
  // Rows of this plan (these settings) that are failed, whether now or in an earlier build.
  const std::vector<std::string> params = DrapeDatabaseBuilder::parameterTexts(c);
  int plan_done = 0, plan_failed = 0;
  for (const SimulationRecord& s : db.simulations(r.textile_id)) {
    // This build's generation only (a rebuild into a staged generation has the active one's settings).
    if (s.generation != r.generation || std::find(params.begin(), params.end(), s.parameters) == params.end()) continue;
    plan_done += s.status == SimulationStatus::kDone;
    plan_failed += s.status == SimulationStatus::kFailed;
  }
  const DatabaseCounts n = db.counts(r.textile_id);
  std::cout << "these settings: " << plan_done << " of " << r.planned << " hold points done, " << plan_failed
            << " failed" << (plan_failed ? " (--retry-failed runs them again)" : "") << "\n"
            << "textile in the database: " << n.done << " done, " << n.pending << " pending, " << n.failed
            << " failed, " << n.views << " views\n";
  return plan_failed > 0 ? kExitFailedSims : kExitOk;
}

// ---- list -------------------------------------------------------------------------------------

int cmdList(const Args& a) {
  a.allowOnly({"--db", "--simulations", "--textile", "--check"});
  DatabaseOpenOptions o;
  o.read_only = true;  // listing and checking never write
  o.create = false;
  HangingDrapeDatabase db(a.require("--db"), o);
  std::cout << "database " << db.path() << " (schema version " << db.schemaVersion() << ")\n";
  std::int64_t only = 0;
  if (a.has("--textile")) {
    const auto t = db.findTextile(a.get("--textile"));
    if (!t) throw NotFoundError("no textile named '" + a.get("--textile") + "'");
    only = t->id;
  }
  for (const TextileRecord& t : db.textiles()) {
    if (only && t.id != only) continue;
    const DatabaseCounts n = db.counts(t.id);
    std::cout << "textile " << t.id << " '" << t.outline.name << "': material " << t.material.name << ", symmetry "
              << t.symmetry.name() << ", " << t.outline.named_points.size() << " grasp points; simulations: " << n.done
              << " done, " << n.pending << " pending, " << n.failed << " failed (" << n.derived << " mirrored); "
              << n.views << " views\n";
    const std::map<std::string, int> members = storedMembers(db, t.id);
    if (members.size() > 1 || (members.size() == 1 && members.begin()->first != "base")) {
      std::cout << "  finished rest shapes per member:";
      for (const auto& [name, count] : members) std::cout << " " << name << " " << count;
      std::cout << "\n";
    }
    if (!a.has("--simulations")) continue;
    std::cout << "  id  status   source     hold_x_m  hold_y_m  lattice  d_m     rest  sim_s  wall_s  steps  views  "
                 "depth_m  note\n";
    for (const SimulationRecord& s : db.simulations(t.id)) {
      std::cout << "  " << std::setw(3) << s.id << " " << std::left << std::setw(8) << toString(s.status) << " "
                << std::setw(10) << toString(s.source) << std::right << " " << std::setw(8) << fixed(s.hold.x(), 4) << "  "
                << std::setw(8) << fixed(s.hold.y(), 4) << "  " << std::setw(3) << s.lattice_i << "," << std::left
                << std::setw(3) << s.lattice_j << std::right << "  " << fixed(s.spacing, 4) << "  "
                << (s.status == SimulationStatus::kDone ? (s.rest_reached ? "yes " : "no  ") : "-   ") << " "
                << std::setw(5) << fixed(s.sim_time_s, 2) << "  " << std::setw(6) << fixed(s.wall_time_s, 2) << "  "
                << std::setw(5) << s.steps << "  " << std::setw(5) << s.view_count << "  " << std::setw(7)
                << fixed(s.hanging_depth_m, 3) << "  "
                << (s.status == SimulationStatus::kFailed
                        ? s.failure_reason
                        : (s.source != MirrorKind::kIdentity ? "from " + std::to_string(s.source_simulation_id) : ""))
                << "\n";
    }
  }
  if (a.has("--check")) {
    const std::string ic = db.integrityCheck();
    const auto problems = db.consistencyProblems();
    std::cout << "integrity_check: " << ic << "\n";
    for (const auto& p : problems) std::cout << "inconsistent: " << p << "\n";
    // Decode every blob once.
    long blobs = 0;
    for (const SimulationRecord& s : db.simulations(0, SimulationStatus::kDone)) {
      db.positions(s.id);
      blobs += 1 + static_cast<long>(db.views(s.id).size());
    }
    std::cout << "blobs decoded: " << blobs << "\n";
    if (ic != "ok" || !problems.empty()) return kExitDatabase;
    std::cout << "consistent\n";
  }
  return kExitOk;
}

// ---- query ------------------------------------------------------------------------------------

vision::BitMask loadQueryMask(const Args& a, const std::string& prefix, const vision::CanonicalFrame& frame) {
  const std::string mask_key = prefix + "mask", image_key = prefix + "image";
  if (a.has(mask_key) == a.has(image_key)) throw UsageError("give exactly one of " + mask_key + " and " + image_key);
  cv::Mat mask;
  // Scale and hold pixel are checked before an image is read.
  std::vector<double> hp;
  double mpp = 0;
  if (!a.has("--canonical")) {
    hp = numbers(a.require(prefix + "hold-pixel"), 2, prefix + "hold-pixel");
    for (double v : hp)
      if (!(std::abs(v) <= kMaxHoldPixel))
        throw UsageError(prefix + "hold-pixel: " + std::to_string(v) + " is more than " +
                         std::to_string(static_cast<long>(kMaxHoldPixel)) + " px from the image");
    mpp = numberIn(a.require(prefix + "metres-per-pixel"), kMinMetresPerPixel, kMaxMetresPerPixel,
                   prefix + "metres-per-pixel");
  }
  if (a.has(mask_key)) {
    mask = readImage(a.get(mask_key), cv::IMREAD_GRAYSCALE, mask_key);
    cv::threshold(mask, mask, 127, 255, cv::THRESH_BINARY);
  } else {
    const cv::Mat img = readImage(a.get(image_key), cv::IMREAD_COLOR, image_key);
    SegmentationOptions so;
    if (a.has("--background")) {
      const auto v = numbers(a.get("--background"), 3, "--background");
      for (int k = 0; k < 3; ++k) so.background_bgr[static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(std::clamp(v[static_cast<std::size_t>(k)], 0.0, 255.0));
    }
    if (a.has("--threshold")) so.threshold = numberIn(a.get("--threshold"), 0.0, 1000.0, "--threshold");
    mask = segmentAgainstBackground(img, so);
  }
  if (a.has("--canonical")) {
    if (mask.cols != frame.width_px || mask.rows != frame.height_px)
      throw UsageError("--canonical: the mask is " + std::to_string(mask.cols) + "x" + std::to_string(mask.rows) +
                       " px, the database frame is " + std::to_string(frame.width_px) + "x" +
                       std::to_string(frame.height_px));
    return vision::fromMat(mask);
  }
  return vision::canonicaliseCameraMask(mask, Vec2(hp[0], hp[1]), Vec2(mpp, mpp), frame);
}

int cmdQuery(const Args& a) {
  a.allowOnly({"--db", "--mask", "--image", "--background", "--threshold", "--hold-pixel", "--metres-per-pixel",
               "--canonical", "--top", "--textile", "--second-mask", "--second-image", "--second-hold-pixel",
               "--second-metres-per-pixel", "--relative-view", "--shift"});
  const bool fused = a.has("--second-mask") || a.has("--second-image");
  if (!fused)
    for (const char* k : {"--second-hold-pixel", "--second-metres-per-pixel", "--relative-view"})
      if (a.has(k)) throw UsageError(std::string(k) + " needs --second-mask or --second-image");
  DatabaseOpenOptions o;
  o.read_only = true;
  o.create = false;
  // Every number is checked before the database is opened.
  const int top_k = integer(a.get("--top", "5"), "--top");
  if (top_k < 1 || top_k > kMaxTop) throw UsageError("--top must be in 1.." + std::to_string(kMaxTop));
  // Shift range in metres (default: the thesis's +-30 / +-5 px at 64 px per metre), in pixels of the
  // database's frame.
  double sx = kThesisShiftXMetres, sy = kThesisShiftYMetres;
  if (a.has("--shift")) {
    const auto v = numbers(a.get("--shift"), 2, "--shift");
    if (!(v[0] >= 0 && v[1] >= 0 && v[0] <= kMaxQueryShiftMetres && v[1] <= kMaxQueryShiftMetres))
      throw UsageError("--shift: ranges must lie in [0, " + fixed(kMaxQueryShiftMetres, 1) + "] m");
    sx = v[0];
    sy = v[1];
  }
  const double relative_view = fused ? number(a.require("--relative-view"), "--relative-view") : 0.0;
  HangingDrapeDatabase db(a.require("--db"), o);
  MatchIndexOptions mio;
  mio.textile = a.get("--textile");
  const DrapeMatchIndex index = loadDrapeMatchIndex(db, mio);
  for (const auto& sv : index.skipped_views)
    std::cerr << "warning: damaged view " << sv.view_id << " (simulation " << sv.simulation_id << ", textile '"
              << sv.textile << "') skipped: " << sv.reason << "\n";
  const vision::MatchOptions mo = metricShiftOptions(index.frame, sx, sy, top_k);
  const vision::BitMask q = loadQueryMask(a, "--", index.frame);
  if (q.count() == 0) throw UsageError("the query mask is empty after canonicalisation (wrong hold pixel or scale?)");
  DrapeQueryResult r;
  if (fused) {
    std::vector<vision::FusionImage> imgs(2);
    imgs[0].mask = q;
    imgs[1].mask = loadQueryMask(a, "--second-", index.frame);
    imgs[1].relative_view_deg = relative_view;
    r = queryDrapeFused(index, imgs, mo);
  } else {
    r = queryDrape(index, q, mo);
  }
  std::cout << "database: " << index.matcher.size() << " silhouettes, " << index.classes.size()
            << " hold-point classes; query " << (fused ? "two images (fused)" : "one image") << ", " << q.count()
            << " px\n";
  std::cout << "rank  score   margin  textile      hold_x_m  hold_y_m   sim  view_deg  shift  equivalent hold points [m]\n";
  for (std::size_t rank = 1; rank <= r.matches.size(); ++rank) {
    const DrapeMatch& m = r.matches[rank - 1];
    std::string eq;
    std::vector<std::string> listed;  // a hold point has several rows (bracket corners, other builds)
    if (m.class_index != kForeignClass)
      for (std::size_t h : index.classes[m.class_index].members) {
        const Vec2 p = index.hold_points[h].hold;
        const std::string text = "(" + fixed(p.x(), 3) + "," + fixed(p.y(), 3) + ")";
        if (std::find(listed.begin(), listed.end(), text) != listed.end()) continue;
        listed.push_back(text);
        if (!eq.empty()) eq += " ";
        eq += text;
      }
    const std::string shift = std::to_string(m.dx) + "," + std::to_string(m.dy);
    std::cout << std::setw(4) << rank << "  " << fixed(m.score, 4) << "  " << fixed(m.margin, 4) << "  " << std::left
              << std::setw(12) << m.textile << std::right << " " << std::setw(8) << fixed(m.canonical_hold.x(), 4)
              << "  " << std::setw(8) << fixed(m.canonical_hold.y(), 4) << "  " << std::setw(4) << m.simulation_id
              << "  " << std::setw(8) << fixed(m.view_angle_deg, 1) << "  " << std::left << std::setw(5) << shift
              << std::right << "  " << eq << "\n";
  }
  if (r.matches.empty()) std::cout << "no match with a positive score\n";
  return kExitOk;
}

// ---- export -----------------------------------------------------------------------------------

int cmdExport(const Args& a) {
  a.allowOnly({"--db", "--simulation", "--ply", "--obj", "--png-dir"});
  if (!a.has("--ply") && !a.has("--obj") && !a.has("--png-dir")) throw UsageError("export needs --ply, --obj or --png-dir");
  DatabaseOpenOptions o;
  o.read_only = true;
  o.create = false;
  HangingDrapeDatabase db(a.require("--db"), o);
  const std::int64_t id = integer(a.require("--simulation"), "--simulation");
  if (a.has("--ply") || a.has("--obj")) {
    const StoredDrapeMesh m = loadDrapeMesh(db, id);
    for (const char* key : {"--ply", "--obj"})
      if (a.has(key)) {
        const std::filesystem::path parent = std::filesystem::path(a.get(key)).parent_path();
        std::error_code ec;
        if (!parent.empty()) std::filesystem::create_directories(parent, ec);
      }
    if (a.has("--ply")) {
      writePly(a.get("--ply"), m.positions, m.triangles);
      std::cout << "wrote " << a.get("--ply") << " (" << m.positions.size() / 3 << " vertices, " << m.triangles.size()
                << " triangles)\n";
    }
    if (a.has("--obj")) {
      writeObj(a.get("--obj"), m.positions, m.triangles);
      std::cout << "wrote " << a.get("--obj") << "\n";
    }
  }
  if (a.has("--png-dir")) {
    const auto paths = exportViewPngs(db, id, a.get("--png-dir"));
    std::cout << "wrote " << paths.size() << " PNG files to " << a.get("--png-dir") << " (last: " << paths.back() << ")\n";
  }
  return kExitOk;
}

// ---- bench ------------------------------------------------------------------------------------

int cmdBench(const Args& a) {
  a.allowOnly({"--out", "--quick", "--resume", "--threads", "--pairs", "--seed", "--spacing", "--heldout-spacing",
               "--frame", "--shift", "--thesis-shift", "--no-bracket", "--cg-tolerance", "--cg-cold-start"});
  ThesisBenchmarkConfig c;
  c.out_dir = a.require("--out");
  c.quick = a.has("--quick");
  c.resume = a.has("--resume");
  if (a.has("--threads")) c.workers = threadCount(a.get("--threads"), "--threads");
  if (a.has("--pairs")) c.pairs_per_shape = integer(a.get("--pairs"), "--pairs");
  if (c.pairs_per_shape < 1) throw UsageError("--pairs must be >= 1");
  if (a.has("--seed")) c.seed = static_cast<std::uint64_t>(integer(a.get("--seed"), "--seed"));
  if (a.has("--spacing")) c.spacing = number(a.get("--spacing"), "--spacing");
  if (a.has("--heldout-spacing")) c.heldout_spacing = number(a.get("--heldout-spacing"), "--heldout-spacing");
  if (!(c.spacing > 0) || !(c.heldout_spacing > 0)) throw UsageError("--spacing and --heldout-spacing must be > 0");
  if (a.has("--frame")) {
    const std::string f = a.get("--frame");
    const auto at = f.find('@');
    if (at == std::string::npos) throw UsageError("--frame: expected PX@METRES, e.g. 128@1.0");
    c.frame_px = integer(f.substr(0, at), "--frame");
    c.frame_metres = number(f.substr(at + 1), "--frame");
    if (c.frame_px < 8 || c.frame_px > 1024 || !(c.frame_metres > 0))
      throw UsageError("--frame: 8..1024 px over a positive size");
  }
  if (a.has("--shift") && a.has("--thesis-shift")) throw UsageError("give --shift or --thesis-shift, not both");
  if (a.has("--shift")) {
    const auto v = numbers(a.get("--shift"), 2, "--shift");
    if (v[0] < 0 || v[1] < 0) throw UsageError("--shift: ranges must be >= 0 m");
    c.max_shift_x_m = v[0];
    c.max_shift_y_m = v[1];
  }
  if (a.has("--thesis-shift")) c.max_shift_x_m = c.max_shift_y_m = -1;
  if (a.has("--no-bracket")) c.bracket_hold_points = false;
  tools::BuildProgressPrinter progress = tools::BuildProgressPrinter::forStderr();
  // Solver settings of every simulation of the run (database and held-out shapes), to compare the
  // builder's defaults with tight solves on the same benchmark.
  std::optional<double> cg_tolerance;
  if (a.has("--cg-tolerance")) {
    cg_tolerance = number(a.get("--cg-tolerance"), "--cg-tolerance");
    if (!(*cg_tolerance > 0 && *cg_tolerance < 1)) throw UsageError("--cg-tolerance must be in (0, 1)");
  }
  const bool cold = a.has("--cg-cold-start");
  c.prepare_build = [&progress, cg_tolerance, cold](DrapeBuildConfig& build) {
    progress.attach(build);
    if (cg_tolerance) build.settings.solver.relative_tolerance = *cg_tolerance;
    if (cold) build.settings.solver.warm_start = false;
  };
  runThesisBenchmark(c);  // the benchmark library (bench/): drape_db only parses its options
  return kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    std::cerr << kUsage;
    return argc < 2 ? kExitUsage : kExitOk;
  }
  const std::string cmd = argv[1];
  try {
    if (cmd == "build")
      return cmdBuild(Args(argc, argv, 2, {"--no-symmetry", "--no-coarse-finish", "--auto", "--retry-failed", "--allow-no-rest", "--quiet", "--bracket", "--cg-warm-start", "--cg-cold-start",
                                             "--self-collision", "--mpi", "--progress-records"}));
    if (cmd == "list") return cmdList(Args(argc, argv, 2, {"--simulations", "--check"}));
    if (cmd == "query") return cmdQuery(Args(argc, argv, 2, {"--canonical"}));
    if (cmd == "export") return cmdExport(Args(argc, argv, 2, {}));
    if (cmd == "bench")
      return cmdBench(Args(argc, argv, 2, {"--quick", "--resume", "--thesis-shift", "--no-bracket", "--cg-cold-start"}));
    std::cerr << "drape_db: unknown command '" << cmd << "'\n" << kUsage;
    return kExitUsage;
  } catch (const UsageError& e) {
    std::cerr << "drape_db " << cmd << ": " << e.what() << " (drape_db --help shows the usage)\n";
    return kExitUsage;
  } catch (const InvalidInputError& e) {
    std::cerr << "drape_db " << cmd << ": invalid input: " << e.what() << "\n";
    return kExitUsage;
  } catch (const NotFoundError& e) {
    std::cerr << "drape_db " << cmd << ": " << e.what() << "\n";
    return kExitUsage;
  } catch (const DrapeDatabaseError& e) {
    std::cerr << "drape_db " << cmd << ": database error: " << e.what() << "\n";
    return kExitDatabase;
  } catch (const std::invalid_argument& e) {
    std::cerr << "drape_db " << cmd << ": invalid input: " << e.what() << "\n";
    return kExitUsage;
  } catch (const std::bad_alloc&) {
    std::cerr << "drape_db " << cmd << ": out of memory (an input larger than this machine can hold?)\n";
    return kExitNoMemory;
  } catch (const std::exception& e) {
    std::cerr << "drape_db " << cmd << ": error: " << e.what() << "\n";
    return kExitError;
  }
}
