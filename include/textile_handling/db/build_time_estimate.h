// Remaining wall time of a database build pass, from the simulations it has finished so far.
//
// Simulation times of one build vary widely: most hold points take about the median, a few take 4-5x
// as long (the cloth swings longer before it comes to rest). A mean-based estimate ("elapsed / finished
// x remaining") is pulled up by those few for the rest of the build and ignores the simulations still
// running, so it is 30-80 % too long in the second half of a build. This one takes the median finished
// simulation time as the expected time of every simulation not yet finished, credits the running ones
// with the time they have already run, and schedules the queue on the pool's workers (a worker takes the
// next simulation when it is free). docs/database.md ("Build progress") has the measured errors.
#pragma once

#include <cstdint>
#include <map>
#include <vector>

namespace textile_handling {
namespace db {

class BuildTimeEstimate {
 public:
  /// `workers` simulations run at once; `to_run` simulations are in the pass. Both are clamped to >= 1
  /// and >= 0.
  BuildTimeEstimate(int workers, int to_run);

  /// Simulation `id` started at time `t_s` (seconds on any monotonic clock, the same for every call).
  void started(std::int64_t id, double t_s);
  /// Simulation `id` finished (done or failed) at `t_s`; an id that was not started is ignored.
  void finished(std::int64_t id, double t_s);

  /// Estimated wall time from `now_s` until the last simulation of the pass finishes [s]; 0 when all
  /// have finished, -1 while no simulation has finished (nothing to estimate from).
  double remainingSeconds(double now_s) const;

  int finishedCount() const { return static_cast<int>(durations_.size()); }
  int runningCount() const { return static_cast<int>(running_.size()); }

 private:
  int workers_;
  int to_run_;
  std::map<std::int64_t, double> running_;  ///< id -> start time
  std::vector<double> durations_;           ///< finished simulations' wall times [s]
};

}  // namespace db
}  // namespace textile_handling
