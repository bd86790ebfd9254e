#include "textile_handling/db/automatic_configuration.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <limits>
#include <map>
#include <new>
#include <sstream>

#include "textile_handling/db/drape_difference.h"
#include "textile_handling/sim/drape_simulation.h"

namespace textile_handling {
namespace db {
namespace {

using Clock = std::chrono::steady_clock;

/// One simulation of the search.
struct SearchRun {
  bool usable = false;   ///< at rest, not diverged
  bool diverged = false;
  std::string status;
  ParticleGrid grid;
  VecX positions;
  Real wall_s = 0;
};

SearchRun simulate(const DrapeSceneSpec& spec) {
  SearchRun out;
  const Clock::time_point t0 = Clock::now();
  try {
    const DrapeScene scene = buildDrapeScene(spec);
    DrapeSimulation sim(*scene.model, scene.pins, spec.settings, scene.x0, scene.v0);
    if (PostStepPass* pass = scene.postStepPass()) sim.setPostStepPass(pass);
    const RunResult r = sim.run();
    out.diverged = r.diverged;
    out.usable = r.rest_reached && !r.diverged;
    out.status = r.diverged ? "diverged: " + r.divergence_reason
                            : r.wall_cap_reached ? "wall-time cap" : r.rest_reached ? "rest" : "not at rest";
    out.grid = scene.grid;
    out.positions = sim.positions();
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    out.status = std::string("error: ") + e.what();
  }
  out.wall_s = std::chrono::duration<Real>(Clock::now() - t0).count();
  return out;
}

bool supportedScene(const DrapeSceneSpec& s) { return !s.pinned_regions.empty() || !s.obstacles.empty(); }

// Compares two usable runs of `sample` (a against the finer or tighter b) into e: named points, nodes and
// silhouettes, turned about the hold axis for a one-point hold.
void measureAgreement(const DrapeSceneSpec& sample, const SearchRun& a, const SearchRun& b, DrapeDifferenceOptions diff,
                      const AutomaticChoiceOptions& options, AutomaticChoiceEvidence& e) {
  for (const NamedPoint& p : sample.textile.named_points) diff.named_points.push_back(p.position);
  diff.align_yaw = sample.hold.size() == 1 && !supportedScene(sample);
  const DrapeDifference m = measureDrapeDifference({&a.grid, a.positions}, {&b.grid, b.positions}, sample.hold_position, diff);
  e.status = "compared";
  e.named_point_distance = m.max_named_point_distance;
  e.max_node_distance = m.max_node_distance;
  e.mean_iou = m.mean_iou;
  e.agrees = m.max_named_point_distance <= options.named_point_tolerance_m && m.mean_iou >= options.min_mean_iou;
}

std::string number(Real v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3g", v);
  return buf;
}

}  // namespace

std::string toString(YarnScaleQuestion q) {
  switch (q) {
    case YarnScaleQuestion::kNone: return "none";
    case YarnScaleQuestion::kPullOut: return "pull_out";
    case YarnScaleQuestion::kSliding: return "sliding";
    case YarnScaleQuestion::kTearing: return "tearing";
  }
  return "none";
}

YarnScaleQuestion yarnScaleQuestionFromString(const std::string& s) {
  for (YarnScaleQuestion q : {YarnScaleQuestion::kNone, YarnScaleQuestion::kPullOut, YarnScaleQuestion::kSliding,
                              YarnScaleQuestion::kTearing})
    if (toString(q) == s) return q;
  throw InvalidInputError("yarn-scale question '" + s + "' unknown; known: none, pull_out, sliding, tearing");
}

void AutomaticChoiceOptions::validate() const {
  if (spacings.size() < 2) throw InvalidInputError("automatic choice: spacings needs at least two candidates");
  for (Real d : spacings)
    if (!(std::isfinite(d) && d > 0)) throw InvalidInputError("automatic choice: spacings must be finite and > 0");
  if (!(std::isfinite(named_point_tolerance_m) && named_point_tolerance_m > 0))
    throw InvalidInputError("automatic choice: named_point_tolerance_m must be finite and > 0");
  if (!(min_mean_iou >= 0 && min_mean_iou <= 1))
    throw InvalidInputError("automatic choice: min_mean_iou must be in [0, 1]");
  for (Real f : error_tolerance_factors)
    if (!(std::isfinite(f) && f > 1 && f <= 1000))
      throw InvalidInputError("automatic choice: error_tolerance_factors must each be finite and in (1, 1000]");
}

std::string AutomaticChoice::text() const {
  std::ostringstream t;
  t << "model " << model.name << " (" << model_reason << "), spacing " << number(spacing) << " m, integrator "
    << toString(settings.integrator) << ", policy " << toString(settings.policy) << " (step error tolerance "
    << number(settings.error_tolerance) << " m)"
    << (converged ? "" : " (no candidate agreed with every finer one: the finest that completes was taken)") << "\n";
  for (const AutomaticChoiceEvidence& e : evidence) {
    t << "evidence " << e.model << " hold " << e.hold << " d " << number(e.spacing);
    if (e.error_tolerance != e.reference_error_tolerance)
      t << " step tolerance " << number(e.error_tolerance) << " vs " << number(e.reference_error_tolerance) << ": ";
    else
      t << " vs " << number(e.finer_spacing) << ": ";
    if (e.status == "compared")
      t << "named points " << number(e.named_point_distance) << " m, nodes " << number(e.max_node_distance)
        << " m, IoU " << number(e.mean_iou) << (e.agrees ? " agrees" : " differs");
    else
      t << e.status;
    t << "\n";
  }
  return t.str();
}

void AutomaticChoice::applyTo(DrapeSceneSpec& spec) const {
  spec.model = model;
  spec.spacing = spacing;
  spec.settings = settings;
}

std::vector<Real> distinctSpacingsCoarseFirst(std::vector<Real> spacings) {
  std::sort(spacings.begin(), spacings.end(), std::greater<Real>());
  spacings.erase(std::unique(spacings.begin(), spacings.end(), [](Real x, Real y) { return std::abs(x - y) <= 1e-9 * x; }),
                 spacings.end());
  return spacings;
}

std::vector<Vec2> spreadSample(const std::vector<Vec2>& candidates, int count) {
  std::vector<Vec2> out;
  if (candidates.empty() || count <= 0) return out;
  std::vector<Real> dist(candidates.size(), std::numeric_limits<Real>::infinity());
  std::size_t next = 0;
  while (static_cast<int>(out.size()) < count && out.size() < candidates.size()) {
    out.push_back(candidates[next]);
    std::size_t best = 0;
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      dist[i] = std::min(dist[i], (candidates[i] - candidates[next]).norm());
      if (dist[i] > dist[best]) best = i;
    }
    if (!(dist[best] > 0)) break;
    next = best;
  }
  return out;
}

AutomaticChoice chooseConfiguration(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options) {
  options.validate();
  if (samples.empty()) throw InvalidInputError("automatic choice: no sample scenes");
  const Clock::time_point t0 = Clock::now();
  const std::vector<Real> d = distinctSpacingsCoarseFirst(options.spacings);
  if (d.size() < 2) throw InvalidInputError("automatic choice: spacings needs at least two different candidates");

  AutomaticChoice choice;
  choice.settings = samples.front().settings;
  choice.settings.integrator = IntegratorType::kSemiImplicitEuler;
  choice.settings.policy = StepPolicy::kErrorControlled;
  std::string model_name;
  if (options.question != YarnScaleQuestion::kNone) {
    model_name = "yarn_woven";
    choice.model_reason = "yarn-scale question: " + toString(options.question);
  } else if (supportedScene(samples.front())) {
    model_name = "choi_ko";
    choice.model_reason = "supported scene (pinned regions or obstacles): compression and buckling";
  } else {
    model_name = "particle_kes";
    choice.model_reason = "hanging scene";
  }

  DrapeDifferenceOptions diff;
  diff.views = options.views;
  diff.frame = options.frame;
  for (;;) {
    // The settling options of a build (settle damping, definite-fix Jacobian) under the sample's own keys
    // when it already names this model (a yarn fabric's weave, say).
    ClothModelSpec model = settlingModelSpec(model_name, 4.0);
    if (samples.front().model.name == model_name)
      for (const auto& kv : samples.front().model.options) model.options[kv.first] = kv.second;
    // Sample i at spacing d (and the search's settings, or another step error tolerance), simulated once.
    auto simulateSample = [&](std::size_t i, Real spacing, Real error_tolerance) {
      DrapeSceneSpec spec = samples[i];
      spec.model = model;
      spec.spacing = spacing;
      spec.settings = choice.settings;
      spec.settings.error_tolerance = error_tolerance;
      SearchRun r = simulate(spec);
      if (options.on_progress)
        options.on_progress(model_name + " hold " + (spec.hold.empty() ? std::string("regions") : spec.hold.front().label()) +
                            " d " + number(spacing) + " m" +
                            (error_tolerance != choice.settings.error_tolerance ? " step tolerance " + number(error_tolerance) + " m" : "") +
                            ": " + r.status + " in " + number(r.wall_s) + " s");
      return r;
    };
    std::map<std::pair<std::size_t, std::size_t>, SearchRun> runs;  // (sample, spacing index)
    auto run = [&](std::size_t i, std::size_t k) -> const SearchRun& {
      auto it = runs.find({i, k});
      if (it != runs.end()) return it->second;
      return runs.emplace(std::make_pair(i, k), simulateSample(i, d[k], choice.settings.error_tolerance)).first->second;
    };
    bool particle_failed = false;
    // Run a of sample i against run b (finer spacing or tighter steps), recorded as evidence `e`, whose
    // status says what failed when one of the runs is not usable.
    auto record = [&](std::size_t i, const SearchRun& a, const SearchRun& b, AutomaticChoiceEvidence e) -> bool {
      e.hold = samples[i].hold.empty() ? "regions" : samples[i].hold.front().label();
      e.model = model_name;
      e.wall_s = a.wall_s + b.wall_s;
      if (a.usable && b.usable) measureAgreement(samples[i], a, b, diff, options, e);
      choice.evidence.push_back(e);
      return e.agrees;
    };
    // Sample i at spacing d[k] against d[j] (j finer).
    auto compare = [&](std::size_t i, std::size_t k, std::size_t j) -> bool {
      const SearchRun& a = run(i, k);
      const SearchRun& b = run(i, j);
      if (model_name == "particle_kes" && (a.diverged || b.diverged)) particle_failed = true;
      AutomaticChoiceEvidence e;
      e.spacing = d[k];
      e.finer_spacing = d[j];
      e.error_tolerance = e.reference_error_tolerance = choice.settings.error_tolerance;
      e.status = "d " + number(a.usable ? d[j] : d[k]) + ": " + (a.usable ? b.status : a.status);
      return record(i, a, b, e);
    };
    // A spacing is taken only when it agrees with every finer candidate: agreeing with the next one alone
    // can be two coarse drapes that fold alike and far from the fine one (the table drape at 2 and 1.5 cm).
    bool chosen = false;
    std::size_t chosen_k = 0;
    for (std::size_t k = 0; k + 1 < d.size() && !chosen && !particle_failed; ++k) {
      bool all_agree = true;
      for (std::size_t j = k + 1; j < d.size() && all_agree && !particle_failed; ++j)
        for (std::size_t i = 0; i < samples.size() && all_agree && !particle_failed; ++i) all_agree = compare(i, k, j);
      if (all_agree && !particle_failed) {
        choice.spacing = d[k];
        chosen_k = k;
        choice.converged = true;
        chosen = true;
      }
    }
    if (particle_failed) {
      model_name = "choi_ko";
      choice.model_reason = "the particle model failed at the chosen settings";
      continue;
    }
    if (!chosen) {
      // The finest candidate that completes on every sample: a choice must never be a failing run.
      choice.converged = false;
      std::string why;
      for (std::size_t k = d.size(); k-- > 0 && !chosen;) {
        bool usable = true;
        for (std::size_t i = 0; i < samples.size() && usable; ++i) {
          const SearchRun& r = run(i, k);
          if (!r.usable) why += "\n  d " + number(d[k]) + ": " + r.status;
          usable = r.usable;
        }
        if (usable) {
          choice.spacing = d[k];
          chosen_k = k;
          chosen = true;
        }
      }
      if (!chosen)
        throw InvalidInputError("automatic choice (" + model_name + "): no candidate spacing completes on every sample:" + why);
    }
    // The step tolerance, loosest candidate first: taken when its drape agrees with the samples' own
    // tolerance's on every sample (a run that fails or does not come to rest disagrees).
    std::vector<Real> factors = options.error_tolerance_factors;
    std::sort(factors.begin(), factors.end(), std::greater<Real>());
    const Real own_tolerance = choice.settings.error_tolerance;
    for (Real f : factors) {
      bool all_agree = true;
      for (std::size_t i = 0; i < samples.size() && all_agree; ++i) {
        const SearchRun& own = run(i, chosen_k);
        AutomaticChoiceEvidence e;
        e.spacing = e.finer_spacing = d[chosen_k];
        e.error_tolerance = f * own_tolerance;
        e.reference_error_tolerance = own_tolerance;
        const SearchRun loose = simulateSample(i, d[chosen_k], f * own_tolerance);
        e.status = loose.usable ? "reference: " + own.status : loose.status;
        all_agree = record(i, loose, own, e);
      }
      if (all_agree) {
        choice.settings.error_tolerance = f * own_tolerance;
        break;
      }
    }
    choice.model = model;
    break;
  }
  choice.search_wall_s = std::chrono::duration<Real>(Clock::now() - t0).count();
  return choice;
}

}  // namespace db
}  // namespace textile_handling
