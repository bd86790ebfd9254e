#include "textile_handling/sim/drape_simulation.h"

#include "textile_handling/sim/output_files.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/timing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace textile_handling {

std::string toString(StepPolicy p) {
  switch (p) {
    case StepPolicy::kFixed: return "fixed";
    case StepPolicy::kThesis: return "thesis";
    case StepPolicy::kErrorControlled: return "error";
  }
  return "unknown";
}

StepPolicy stepPolicyFromString(const std::string& s) {
  if (s == "fixed") return StepPolicy::kFixed;
  if (s == "thesis") return StepPolicy::kThesis;
  if (s == "error") return StepPolicy::kErrorControlled;
  throw SimError("unknown time-step policy '" + s + "' (expected fixed, thesis or error)");
}

namespace {
// Each bad setting gets its own message naming the field and what it must be.
void checkSettings(const SimulationSettings& s) {
  std::string bad;
  auto require = [&](bool ok, const char* field, Real value, const char* rule) {
    if (!ok) bad += std::string(bad.empty() ? "" : "; ") + field + " = " + std::to_string(value) + " must be " + rule;
  };
  require(s.dt > 0 && std::isfinite(s.dt), "dt", s.dt, "finite and > 0");
  require(s.dt_min > 0, "dt_min", s.dt_min, "> 0");
  require(s.dt_max >= s.dt_min, "dt_max", s.dt_max, ">= dt_min");
  require(s.max_time >= 0, "max_time", s.max_time, ">= 0");
  require(s.error_tolerance > 0, "error_tolerance", s.error_tolerance, "> 0");
  require(s.max_wall_time >= 0, "max_wall_time", s.max_wall_time, ">= 0 (0 = no cap)");
  require(s.solver.newton_max_iterations >= 1, "solver.newton_max_iterations", s.solver.newton_max_iterations, ">= 1");
  require(s.solver.newton_tolerance > 0 && std::isfinite(s.solver.newton_tolerance), "solver.newton_tolerance",
          s.solver.newton_tolerance, "finite and > 0");
  if (!bad.empty()) throw SimError("DrapeSimulation: " + bad);
}
}  // namespace

DrapeSimulation::DrapeSimulation(ClothModel& model, PinnedNodes pins, SimulationSettings settings, VecX x0,
                                 VecX v0)
    : model_(model),
      pins_(std::move(pins)),
      settings_(settings),
      integrator_(makeIntegrator(settings.integrator, settings.solver)),
      x_(std::move(x0)),
      v_(std::move(v0)),
      dt_(settings.dt) {
  if (x_.size() != model.numDofs() || v_.size() != model.numDofs())
    throw SimError("DrapeSimulation: state size does not match the model");
  checkSettings(settings);
  if (pins_.anchors.size() != pins_.nodes.size() || pins_.waypoint_times.size() != pins_.waypoint_offsets.size())
    throw SimError("DrapeSimulation: pinned node lists have different lengths");
  for (Index p : pins_.nodes)
    if (p < 0 || p >= model.numNodes()) throw SimError("DrapeSimulation: pinned node out of range");
  total_mass_ = model.totalMass();
  resetEnergyBudget();
}

void DrapeSimulation::resetEnergyBudget() {
  // With static pins every force but gravity and elasticity dissipates, so kinetic + potential energy
  // can only fall. Elastic energy is >= 0, hence kinetic + gravitational energy must stay below the
  // current total; more means the integrator created energy (an instability). The slack of 1 % of
  // M g (extent) absorbs integration error. Lifting pins do work, so the check is off for them.
  energy_check_ = pins_.waypoint_times.empty() && model_.dofsPerNode() >= 3;
  if (!energy_check_) return;
  const int b = model_.dofsPerNode();
  Real extent = 0;
  for (int c = 0; c < 3; ++c) {
    Real a = std::numeric_limits<Real>::infinity(), z = -a;
    for (Index i = 0; i < model_.numNodes(); ++i) {
      a = std::min(a, x_[i * b + c]);
      z = std::max(z, x_[i * b + c]);
    }
    extent += (z - a) * (z - a);
  }
  extent = std::sqrt(extent);
  energy_budget_ = kineticEnergy() + model_.potentialEnergy(x_) + 0.01 * total_mass_ * kGravity * std::max(extent, 1e-3);
  if (!std::isfinite(energy_budget_)) energy_check_ = false;
}

const VecX& DrapeSimulation::positions() const {
  if (model_.dofsPerNode() == 3) return x_;
  positions_view_ = model_.positionsOf(x_);
  return positions_view_;
}

Real DrapeSimulation::gravitationalEnergy(const VecX& x) const { return model_.gravitationalEnergy(x); }

Real DrapeSimulation::kineticEnergy() const { return model_.kineticEnergy(x_, v_); }

bool DrapeSimulation::checkDivergence(const VecX& x, const VecX& v, std::string* why) const {
  if (!x.allFinite() || !v.allFinite()) {
    *why = "non-finite positions or velocities";
    return true;
  }
  const Real stretch = model_.maxEdgeStretch(x);
  if (!(stretch <= settings_.max_edge_stretch)) {
    std::ostringstream s;
    s << "edge stretched to " << stretch << " times its rest length (bound " << settings_.max_edge_stretch << ")";
    *why = s.str();
    return true;
  }
  const Real ke = model_.kineticEnergy(x, v);
  if (energy_check_) {
    const Real e = ke + gravitationalEnergy(x);
    if (e > energy_budget_) {
      std::ostringstream s;
      s << "energy blow-up: kinetic + gravitational energy " << e << " J exceeds the available " << energy_budget_
        << " J";
      *why = s.str();
      return true;
    }
  }
  const Real rms = std::sqrt(2 * ke / std::max(total_mass_, 1e-300));
  if (!(rms <= settings_.max_speed)) {
    std::ostringstream s;
    s << "kinetic energy blow-up: RMS speed " << rms << " m/s (bound " << settings_.max_speed << ")";
    *why = s.str();
    return true;
  }
  return false;
}

void DrapeSimulation::adaptThesis(const VecX& x_old, Real h) {
  // Thesis rule (section 4.5) on N = sum of distances moved / h, i.e. normalised by the step so
  // that shrinking dt alone does not look like calming down. Decisions for its open points: the
  // reference growth is the previous step's growth; "divide by this factor" divides by 7 (the
  // measured ratio can be arbitrarily large and collapse dt); the increase needs 15 consecutive decreases; the new dt applies from the next step.
  const int b = model_.dofsPerNode();
  Real norm = 0;
  for (Index i = 0; i < model_.numNodes(); ++i) norm += (x_.segment<3>(i * b) - x_old.segment<3>(i * b)).norm();
  norm /= h;
  if (prev_norm_ >= 0) {
    const Real growth = norm - prev_norm_;
    const Real ratio = prev_growth_ > 0 ? growth / prev_growth_ : 0;
    if (norm > 1.2 * prev_norm_ || ratio > 7) {
      dt_ = h / 2;
      if (ratio >= 7) dt_ /= 7;  // "that factor" read as the constant 7: a measured ratio is unbounded
      decrease_count_ = 0;
    } else if (norm < prev_norm_) {
      if (++decrease_count_ >= 15) {
        dt_ = 1.5 * h;
        decrease_count_ = 0;
      }
    } else {
      decrease_count_ = 0;
    }
    prev_growth_ = growth;
  }
  prev_norm_ = norm;
  dt_ = std::clamp(dt_, settings_.dt_min, settings_.dt_max);
}

bool DrapeSimulation::stepOnce() {
  using Clock = std::chrono::steady_clock;
  for (;;) {
    const Real h = settings_.policy == StepPolicy::kFixed ? settings_.dt : std::min(dt_, settings_.dt_max);
    const auto t0 = Clock::now();
    StepOutcome out = integrator_->step(model_, pins_, x_, v_, t_, h, x_new_, v_new_);
    result_.step_ms += msSince(t0);
    result_.solver_iterations += out.solver_iterations;
    result_.newton_iterations += out.newton_iterations;
    result_.assembly_ms += out.assembly_ms;
    result_.solve_ms += out.solve_ms;
    result_.degenerate_terms = std::max(result_.degenerate_terms, out.degenerate_terms);
    result_.torn_segments = std::max(result_.torn_segments, out.torn_segments);
    std::string why;
    if (out.ok && checkDivergence(x_new_, v_new_, &why)) {
      out.ok = false;
      out.failure = why;
    }
    Real next_dt = dt_;
    if (out.ok && settings_.policy == StepPolicy::kErrorControlled) {
      const Real err = std::max(out.error_estimate, 1e-300);
      const Real factor = std::clamp(0.9 * std::pow(settings_.error_tolerance / err, 1.0 / out.error_order), 0.2, 2.0);
      if (err > settings_.error_tolerance) {
        out.ok = false;
        out.failure = "local error above tolerance";
        ++result_.rejected_steps;
        dt_ = h * factor;
        if (dt_ < settings_.dt_min) {
          result_.diverged = true;
          result_.divergence_reason = "step size fell below dt_min to meet the error tolerance";
          result_.divergence_time = t_;
          return false;
        }
        continue;
      }
      next_dt = std::min(settings_.dt_max, h * factor);
    }
    if (!out.ok) {
      if (settings_.policy == StepPolicy::kFixed) {
        result_.diverged = true;
        result_.divergence_reason = out.failure;
        result_.divergence_time = t_ + h;
        return false;
      }
      ++result_.rejected_steps;
      dt_ = h / 2;
      if (dt_ < settings_.dt_min) {
        result_.diverged = true;
        result_.divergence_reason = out.failure + " (step size fell below dt_min)";
        result_.divergence_time = t_ + h;
        return false;
      }
      continue;
    }
    // Accept.
    x_.swap(x_new_);  // x_new_ now holds the previous positions
    v_.swap(v_new_);
    t_ += h;
    ++result_.steps;
    if (post_) {
      const auto t1 = Clock::now();
      const long events = post_->apply(x_new_, x_, v_);
      result_.post_step_events += events;
      // A rollback of some particles strains edges (elastic energy the pass put in, not the
      // integrator): re-base the energy budget so it keeps measuring only integrator growth.
      if (events > 0 && energy_check_) {
        const Real budget_before = energy_budget_;
        resetEnergyBudget();
        energy_budget_ = std::max(energy_budget_, budget_before);
      }
      result_.post_step_ms += msSince(t1);
    }
    model_.acceptStep(x_, v_);
    if (settings_.policy == StepPolicy::kThesis) adaptThesis(x_new_, h);
    if (settings_.policy == StepPolicy::kErrorControlled) dt_ = std::max(next_dt, settings_.dt_min);
    if (settings_.trajectory_every > 0 && result_.steps % settings_.trajectory_every == 0)
      trajectory_.push_back({t_, x_});

    // Rest detection (pinned nodes included: a lifted textile is not at rest).
    const int b = model_.dofsPerNode();
    Real vmax = 0;
    for (Index i = 0; i < model_.numNodes(); ++i) vmax = std::max(vmax, v_.segment<3>(i * b).norm());
    const Real vmean = std::sqrt(2 * kineticEnergy() / std::max(total_mass_, 1e-300));
    if (vmax < settings_.rest_speed && vmean < settings_.rest_mean_speed) {
      if (rest_since_ < 0) rest_since_ = t_;
      if (t_ - rest_since_ >= settings_.rest_duration && t_ >= settings_.rest_min_time) result_.rest_reached = true;
    } else {
      rest_since_ = -1;
    }
    return true;
  }
}

RunResult DrapeSimulation::run(Real until) {
  const auto start = std::chrono::steady_clock::now();
  const Real stop = std::min(until, settings_.max_time);
  result_.wall_cap_reached = false;
  while (!result_.rest_reached && !result_.diverged && t_ < stop - 1e-12) {
    if (!stepOnce()) break;
    if (settings_.max_wall_time > 0 &&
        secondsSince(start) > settings_.max_wall_time) {
      result_.wall_cap_reached = true;
      break;
    }
  }
  result_.wall_time += secondsSince(start);
  result_.sim_time = t_;
  result_.kinetic_energy = kineticEnergy();
  result_.potential_energy = model_.potentialEnergy(x_);
  result_.mean_dt = result_.steps > 0 ? t_ / result_.steps : 0;
  return result_;
}

// ---- save / resume --------------------------------------------------------------------------------

namespace {
constexpr const char* kStateMagic = "textile_handling_drape_state";
constexpr int kStateVersion = 2;  // 2 added solver_state (CG warm start)

void writeVec(std::ostream& os, const char* key, const VecX& v) {
  os << key << ' ' << v.size();
  for (Index i = 0; i < v.size(); ++i) os << ' ' << v[i];
  os << '\n';
}

Real parseReal(std::istream& is, const std::string& what) {
  std::string tok;
  if (!(is >> tok)) throw std::runtime_error("drape state: missing value for " + what);
  char* end = nullptr;
  const Real r = std::strtod(tok.c_str(), &end);
  if (end == tok.c_str() || *end != '\0') throw std::runtime_error("drape state: bad number '" + tok + "' in " + what);
  return r;
}

// A non-negative integer count (checked before the conversion, which would be undefined for NaN).
long parseCount(std::istream& is, const std::string& what, Real max) {
  const Real r = parseReal(is, what);
  if (!(r >= 0 && r <= max) || r != std::floor(r))
    throw std::runtime_error("drape state: bad count in " + what + " (must be a non-negative integer)");
  return static_cast<long>(r);
}

void expectKey(std::istream& is, const std::string& key) {
  std::string tok;
  if (!(is >> tok) || tok != key) throw std::runtime_error("drape state: expected '" + key + "', found '" + tok + "'");
}

VecX readVec(std::istream& is, const std::string& key, Index expected) {
  expectKey(is, key);
  const Real n = parseReal(is, key + " size");
  if (n != expected) throw std::runtime_error("drape state: " + key + " has " + std::to_string(static_cast<long>(n)) +
                                              " values, the model needs " + std::to_string(expected));
  VecX v(expected);
  for (Index i = 0; i < expected; ++i) v[i] = parseReal(is, key);
  return v;
}
}  // namespace

void DrapeSimulation::save(const std::string& path) const {
  std::ostringstream os;
  os << std::hexfloat;
  os << kStateMagic << ' ' << kStateVersion << '\n';
  os << "model " << model_.name() << " nodes " << model_.numNodes() << " dofs_per_node " << model_.dofsPerNode() << '\n';
  os << "time " << t_ << "\ndt " << dt_ << '\n';
  os << "thesis_rule " << prev_norm_ << ' ' << prev_growth_ << ' ' << decrease_count_ << '\n';
  os << "rest_since " << rest_since_ << '\n';
  os << "counters " << result_.steps << ' ' << result_.rejected_steps << ' ' << result_.solver_iterations << ' '
     << result_.post_step_events << '\n';
  os << "pins " << pins_.nodes.size() << '\n';
  for (size_t k = 0; k < pins_.nodes.size(); ++k)
    os << pins_.nodes[k] << ' ' << pins_.anchors[k].x() << ' ' << pins_.anchors[k].y() << ' ' << pins_.anchors[k].z() << '\n';
  os << "waypoints " << pins_.waypoint_times.size() << '\n';
  for (size_t k = 0; k < pins_.waypoint_times.size(); ++k)
    os << pins_.waypoint_times[k] << ' ' << pins_.waypoint_offsets[k].x() << ' ' << pins_.waypoint_offsets[k].y()
       << ' ' << pins_.waypoint_offsets[k].z() << '\n';
  writeVec(os, "x", x_);
  writeVec(os, "v", v_);
  const std::vector<Real> internal = model_.internalState();
  writeVec(os, "model_state", Eigen::Map<const VecX>(internal.data(), static_cast<Index>(internal.size())));
  const std::vector<Real> solver = integrator_->solverState();
  writeVec(os, "solver_state", Eigen::Map<const VecX>(solver.data(), static_cast<Index>(solver.size())));
  os << "end\n";
  try {
    writeFileAtomically(path, [&](std::ostream& f) { f << os.str(); });
  } catch (const OutputError& e) {
    throw OutputError(std::string("drape state: ") + e.what());
  }
}

void DrapeSimulation::load(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw std::runtime_error("drape state: cannot open " + path);
  std::string magic;
  f >> magic;
  if (magic != kStateMagic) throw std::runtime_error("drape state: " + path + " is not a drape state file");
  const Real version = parseReal(f, "version");
  if (version != 1 && version != kStateVersion) throw std::runtime_error("drape state: unsupported version in " + path);
  std::string model_name;
  expectKey(f, "model");
  f >> model_name;
  if (model_name != model_.name())
    throw std::runtime_error("drape state: file is for model '" + model_name + "', not '" + model_.name() + "'");
  expectKey(f, "nodes");
  const Real file_nodes = parseReal(f, "nodes");
  if (file_nodes != model_.numNodes()) {
    std::ostringstream m;
    m << "drape state: node count mismatch (file " << file_nodes << ", model " << model_.numNodes() << ")";
    throw std::runtime_error(m.str());
  }
  expectKey(f, "dofs_per_node");
  if (parseReal(f, "dofs_per_node") != model_.dofsPerNode()) throw std::runtime_error("drape state: DOF mismatch");
  expectKey(f, "time");
  const Real t = parseReal(f, "time");
  expectKey(f, "dt");
  const Real dt = parseReal(f, "dt");
  expectKey(f, "thesis_rule");
  const Real pn = parseReal(f, "thesis_rule"), pg = parseReal(f, "thesis_rule");
  const int dc = static_cast<int>(parseCount(f, "thesis_rule", 1e9));
  expectKey(f, "rest_since");
  const Real rs = parseReal(f, "rest_since");
  expectKey(f, "counters");
  const long steps = parseCount(f, "counters", 1e18), rej = parseCount(f, "counters", 1e18);
  const long its = parseCount(f, "counters", 1e18), ev = parseCount(f, "counters", 1e18);
  expectKey(f, "pins");
  const Real npins = parseReal(f, "pins");
  if (!(npins >= 0 && npins <= model_.numNodes())) throw std::runtime_error("drape state: bad pin count");
  PinnedNodes pins;
  for (int k = 0; k < static_cast<int>(npins); ++k) {
    const Real node = parseReal(f, "pin node");
    if (!(node >= 0 && node < model_.numNodes())) throw std::runtime_error("drape state: pinned node out of range");
    pins.nodes.push_back(static_cast<Index>(node));
    Vec3 a;
    for (int c = 0; c < 3; ++c) a[c] = parseReal(f, "pin anchor");
    pins.anchors.push_back(a);
  }
  expectKey(f, "waypoints");
  const Real nw = parseReal(f, "waypoints");
  if (!(nw >= 0 && nw < 1e6)) throw std::runtime_error("drape state: bad waypoint count");
  for (int k = 0; k < static_cast<int>(nw); ++k) {
    pins.waypoint_times.push_back(parseReal(f, "waypoint time"));
    Vec3 o;
    for (int c = 0; c < 3; ++c) o[c] = parseReal(f, "waypoint offset");
    pins.waypoint_offsets.push_back(o);
  }
  VecX x = readVec(f, "x", model_.numDofs());
  VecX v = readVec(f, "v", model_.numDofs());
  expectKey(f, "model_state");
  const Real ns = parseReal(f, "model_state size");
  if (!(ns >= 0 && ns < 1e9)) throw std::runtime_error("drape state: bad model_state size");
  std::vector<Real> internal(static_cast<size_t>(ns));
  for (auto& r : internal) r = parseReal(f, "model_state");
  std::vector<Real> solver_state;
  if (version >= 2) {
    expectKey(f, "solver_state");
    const Real nss = parseReal(f, "solver_state size");
    if (!(nss >= 0 && nss < 1e9)) throw std::runtime_error("drape state: bad solver_state size");
    solver_state.resize(static_cast<size_t>(nss));
    for (auto& r : solver_state) r = parseReal(f, "solver_state");
    for (Real r : solver_state)
      if (!std::isfinite(r)) throw std::runtime_error("drape state: non-finite solver_state in " + path);
  }
  expectKey(f, "end");
  if (!x.allFinite() || !v.allFinite() || !std::isfinite(t) || !(dt > 0) || !std::isfinite(dt))
    throw std::runtime_error("drape state: non-finite values in " + path);
  // Pins and the step-controller memory are validated too: a NaN anchor would otherwise be
  // accepted and poison the next step.
  for (size_t k = 0; k < pins.anchors.size(); ++k)
    if (!pins.anchors[k].allFinite()) throw std::runtime_error("drape state: non-finite pin anchor in " + path);
  for (size_t k = 0; k < pins.waypoint_times.size(); ++k) {
    if (!std::isfinite(pins.waypoint_times[k]) || !pins.waypoint_offsets[k].allFinite())
      throw std::runtime_error("drape state: non-finite lift waypoint in " + path);
    if (k > 0 && !(pins.waypoint_times[k] > pins.waypoint_times[k - 1]))
      throw std::runtime_error("drape state: lift waypoint times do not increase in " + path);
  }
  if (!std::isfinite(pn) || !std::isfinite(pg) || !std::isfinite(rs))
    throw std::runtime_error("drape state: non-finite step-controller or rest-timer values in " + path);
  if (!model_.setInternalState(internal)) throw std::runtime_error("drape state: model rejected its internal state");
  if (!integrator_->setSolverState(solver_state))
    throw std::runtime_error("drape state: solver state does not fit this integrator/model");
  // Everything parsed: commit.
  t_ = t;
  dt_ = dt;
  prev_norm_ = pn;
  prev_growth_ = pg;
  decrease_count_ = dc;
  rest_since_ = rs;
  result_ = RunResult{};
  result_.steps = steps;
  result_.rejected_steps = rej;
  result_.solver_iterations = its;
  result_.post_step_events = ev;
  pins_ = std::move(pins);
  x_ = std::move(x);
  v_ = std::move(v);
  resetEnergyBudget();
}

}  // namespace textile_handling
