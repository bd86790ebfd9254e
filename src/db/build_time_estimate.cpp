#include "textile_handling/db/build_time_estimate.h"

#include <algorithm>
#include <functional>
#include <queue>

namespace textile_handling {
namespace db {

BuildTimeEstimate::BuildTimeEstimate(int workers, int to_run)
    : workers_(std::max(1, workers)), to_run_(std::max(0, to_run)) {}

void BuildTimeEstimate::started(std::int64_t id, double t_s) { running_[id] = t_s; }

void BuildTimeEstimate::finished(std::int64_t id, double t_s) {
  const auto it = running_.find(id);
  if (it == running_.end()) return;
  durations_.push_back(std::max(0.0, t_s - it->second));
  running_.erase(it);
}

double BuildTimeEstimate::remainingSeconds(double now_s) const {
  const int finished = finishedCount();
  if (finished >= to_run_) return 0.0;
  if (finished == 0) return -1.0;
  std::vector<double> d = durations_;
  const std::size_t mid = d.size() / 2;
  std::nth_element(d.begin(), d.begin() + mid, d.end());
  double typical = d[mid];
  if (d.size() % 2 == 0) typical = 0.5 * (typical + *std::max_element(d.begin(), d.begin() + mid));
  // Each worker's time until it is free: a running simulation is expected to take `typical` in all,
  // but at least a tenth of it more (it has not finished, so it is not done yet).
  std::priority_queue<double, std::vector<double>, std::greater<double>> free_at;
  for (const auto& r : running_) free_at.push(std::max(typical - (now_s - r.second), 0.1 * typical));
  while (static_cast<int>(free_at.size()) < workers_) free_at.push(0.0);
  const int queued = std::max(0, to_run_ - finished - runningCount());
  for (int k = 0; k < queued; ++k) {
    const double t = free_at.top();
    free_at.pop();
    free_at.push(t + typical);
  }
  double last = 0.0;
  while (!free_at.empty()) {
    last = std::max(last, free_at.top());
    free_at.pop();
  }
  return last;
}

}  // namespace db
}  // namespace textile_handling
