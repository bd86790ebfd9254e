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
#include <tuple>

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
  Real work = 0;  ///< searchRunWork() of the run (0 when it did not start)
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
    out.work = searchRunWork(static_cast<Index>(out.positions.size() / 3), r.steps, r.rejected_steps, r.solver_iterations);
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
    << (converged ? "" : members.empty() ? " (no candidate agreed with every finer one: the finest that completes was taken)"
                                         : " (no candidate agreed with every finer one: a coarser one with members was taken)")
    << "\n";
  if (!members_reason.empty()) {
    t << "members base";
    for (const std::string& m : members) t << ", " << m;
    t << ": " << members_reason << "\n";
  }
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

Real searchRunWork(Index nodes, long steps, long rejected_steps, long solver_iterations) {
  return static_cast<Real>(nodes) * static_cast<Real>(steps + rejected_steps + solver_iterations);
}

namespace {

/// The runs and comparisons of one model's search: every run simulated once and reused, every comparison
/// recorded once as evidence of `choice`.
class ModelSearch {
 public:
  ModelSearch(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options, const std::vector<Real>& d,
              const std::string& model_name, AutomaticChoice& choice)
      : samples_(samples), options_(options), d_(d), model_name_(model_name), choice_(choice) {
    // The settling options of a build (settle damping, definite-fix Jacobian) under the sample's own keys
    // when it already names this model (a yarn fabric's weave, say).
    model_ = settlingModelSpec(model_name, 4.0);
    if (samples.front().model.name == model_name)
      for (const auto& kv : samples.front().model.options) model_.options[kv.first] = kv.second;
    diff_.views = options.views;
    diff_.frame = options.frame;
  }
  const ClothModelSpec& model() const { return model_; }
  bool particleFailed() const { return particle_failed_; }

  /// `scene` with the search's model and settings at `spacing` and step tolerance `error_tolerance`.
  SearchRun simulateScene(DrapeSceneSpec spec, Real spacing, Real error_tolerance, const std::string& member = "") const {
    spec.model = model_;
    spec.spacing = spacing;
    spec.settings = choice_.settings;
    spec.settings.error_tolerance = error_tolerance;
    SearchRun r = simulate(spec);
    if (options_.on_progress)
      options_.on_progress(model_name_ + (member.empty() ? "" : " member " + member) + " hold " + holdLabel(spec) + " d " +
                           number(spacing) + " m" +
                           (error_tolerance != choice_.settings.error_tolerance ? " step tolerance " + number(error_tolerance) + " m" : "") +
                           ": " + r.status + " in " + number(r.wall_s) + " s");
    return r;
  }
  /// Sample i at spacing d[k] with the search's step tolerance.
  const SearchRun& run(std::size_t i, std::size_t k) {
    auto it = runs_.find({i, k});
    if (it != runs_.end()) return it->second;
    return runs_.emplace(std::make_pair(i, k), simulateScene(samples_[i], d_[k], choice_.settings.error_tolerance)).first->second;
  }
  /// Run a of sample i against run b (finer spacing or tighter steps), recorded as evidence `e`, whose
  /// status says what failed when one of the runs is not usable. Returns the evidence recorded.
  const AutomaticChoiceEvidence& record(std::size_t i, const SearchRun& a, const SearchRun& b, AutomaticChoiceEvidence e) {
    e.hold = holdLabel(samples_[i]);
    e.model = model_name_;
    e.wall_s = a.wall_s + b.wall_s;
    if (a.usable && b.usable) measureAgreement(samples_[i], a, b, diff_, options_, e);
    choice_.evidence.push_back(e);
    return choice_.evidence.back();
  }
  /// Sample i at spacing d[k] against d[j] (j finer), compared once.
  AutomaticChoiceEvidence compare(std::size_t i, std::size_t k, std::size_t j) {
    const auto key = std::make_tuple(i, k, j);
    auto it = compared_.find(key);
    if (it != compared_.end()) return it->second;
    const SearchRun& a = run(i, k);
    const SearchRun& b = run(i, j);
    if (model_name_ == "particle_kes" && (a.diverged || b.diverged)) particle_failed_ = true;
    AutomaticChoiceEvidence e;
    e.spacing = d_[k];
    e.finer_spacing = d_[j];
    e.error_tolerance = e.reference_error_tolerance = choice_.settings.error_tolerance;
    e.status = "d " + number(a.usable ? d_[j] : d_[k]) + ": " + (a.usable ? b.status : a.status);
    return compared_.emplace(key, record(i, a, b, e)).first->second;
  }

 private:
  static std::string holdLabel(const DrapeSceneSpec& s) { return s.hold.empty() ? std::string("regions") : s.hold.front().label(); }

  const std::vector<DrapeSceneSpec>& samples_;
  const AutomaticChoiceOptions& options_;
  const std::vector<Real>& d_;
  std::string model_name_;
  AutomaticChoice& choice_;
  ClothModelSpec model_;
  DrapeDifferenceOptions diff_;
  std::map<std::pair<std::size_t, std::size_t>, SearchRun> runs_;  // (sample, spacing index)
  std::map<std::tuple<std::size_t, std::size_t, std::size_t>, AutomaticChoiceEvidence> compared_;
  bool particle_failed_ = false;
};

// The members rule (chooseConfiguration's doc comment): where nothing converged on a hanging scene, the next
// coarser spacing than d[finest] with members, when its silhouettes agree with the finest's on every sample
// and the work of the coarser base and the members stays below the finest's. Sets choice.spacing and
// choice.members and returns the index of the spacing taken (finest when the rule does not apply).
std::size_t coverWithMembers(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options,
                             const std::vector<Real>& d, std::size_t finest, ModelSearch& search, AutomaticChoice& choice) {
  if (options.member_samples.empty() || finest == 0) return finest;
  const std::size_t coarser = finest - 1;
  Real finest_work = 0, work = 0, lowest_iou = 1;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const AutomaticChoiceEvidence e = search.compare(i, coarser, finest);
    if (e.status != "compared" || e.mean_iou < options.min_mean_iou) {
      choice.members_reason = "no members: d " + number(d[coarser]) + " on hold " + e.hold +
                              (e.status != "compared" ? ": " + e.status : ": silhouette IoU " + number(e.mean_iou) + " against d " + number(d[finest]));
      return finest;
    }
    lowest_iou = std::min(lowest_iou, e.mean_iou);
    finest_work += search.run(i, finest).work;
    work += search.run(i, coarser).work;
  }
  choice.work_finest = finest_work;
  std::ostringstream why;
  why << "d " << number(d[coarser]) << " silhouettes agree with d " << number(d[finest]) << " on every sample (IoU >= "
      << number(lowest_iou) << "); work on the samples: d " << number(d[finest]) << " " << number(finest_work) << ", d "
      << number(d[coarser]) << " base " << number(work);
  std::vector<std::string> taken;
  for (const AutomaticChoiceOptions::MemberSamples& m : options.member_samples) {
    Real member_work = 0;
    std::string failure;
    for (std::size_t i = 0; i < m.scenes.size() && failure.empty(); ++i) {  // a failing sample settles it
      const SearchRun r = search.simulateScene(m.scenes[i], d[coarser], choice.settings.error_tolerance, m.name);
      member_work += r.work;
      if (!r.usable) failure = r.status;
    }
    if (!failure.empty()) {
      why << ", " << m.name << " " << failure << " (stop)";
      break;
    }
    if (!(work + member_work < finest_work)) {
      why << ", + " << m.name << " " << number(member_work) << " (over the finest's: stop)";
      break;
    }
    work += member_work;
    taken.push_back(m.name);
    why << ", + " << m.name << " " << number(member_work);
  }
  choice.work_with_members = work;
  if (taken.empty()) {
    choice.members_reason = "no members: " + why.str();
    return finest;
  }
  choice.members = taken;
  choice.members_reason = why.str() + " (node-iterations)";
  choice.spacing = d[coarser];
  return coarser;
}

}  // namespace

AutomaticChoice chooseConfiguration(const std::vector<DrapeSceneSpec>& samples, const AutomaticChoiceOptions& options) {
  options.validate();
  if (samples.empty()) throw InvalidInputError("automatic choice: no sample scenes");
  for (const AutomaticChoiceOptions::MemberSamples& m : options.member_samples)
    if (m.name.empty() || m.scenes.size() != samples.size())
      throw InvalidInputError("automatic choice: member_samples '" + m.name + "' needs a name and one scene per sample (" +
                              std::to_string(samples.size()) + "), got " + std::to_string(m.scenes.size()));
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

  for (;;) {
    ModelSearch search(samples, options, d, model_name, choice);
    // A spacing is taken only when it agrees with every finer candidate: agreeing with the next one alone
    // can be two coarse drapes that fold alike and far from the fine one (the table drape at 2 and 1.5 cm).
    bool chosen = false;
    std::size_t chosen_k = 0;
    for (std::size_t k = 0; k + 1 < d.size() && !chosen && !search.particleFailed(); ++k) {
      bool all_agree = true;
      for (std::size_t j = k + 1; j < d.size() && all_agree && !search.particleFailed(); ++j)
        for (std::size_t i = 0; i < samples.size() && all_agree && !search.particleFailed(); ++i)
          all_agree = search.compare(i, k, j).agrees;
      if (all_agree && !search.particleFailed()) {
        choice.spacing = d[k];
        chosen_k = k;
        choice.converged = true;
        chosen = true;
      }
    }
    if (search.particleFailed()) {
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
          const SearchRun& r = search.run(i, k);
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
      if (model_name == "particle_kes") chosen_k = coverWithMembers(samples, options, d, chosen_k, search, choice);
    }
    // The step tolerance, loosest candidate first: taken when its drape agrees with the samples' own
    // tolerance's on every sample (a run that fails or does not come to rest disagrees).
    std::vector<Real> factors = options.error_tolerance_factors;
    std::sort(factors.begin(), factors.end(), std::greater<Real>());
    const Real own_tolerance = choice.settings.error_tolerance;
    for (Real f : factors) {
      bool all_agree = true;
      for (std::size_t i = 0; i < samples.size() && all_agree; ++i) {
        const SearchRun& own = search.run(i, chosen_k);
        AutomaticChoiceEvidence e;
        e.spacing = e.finer_spacing = d[chosen_k];
        e.error_tolerance = f * own_tolerance;
        e.reference_error_tolerance = own_tolerance;
        const SearchRun loose = search.simulateScene(samples[i], d[chosen_k], f * own_tolerance);
        e.status = loose.usable ? "reference: " + own.status : loose.status;
        all_agree = search.record(i, loose, own, e).agrees;
      }
      if (all_agree) {
        choice.settings.error_tolerance = f * own_tolerance;
        break;
      }
    }
    choice.model = search.model();
    break;
  }
  choice.search_wall_s = std::chrono::duration<Real>(Clock::now() - t0).count();
  return choice;
}

}  // namespace db
}  // namespace textile_handling
