// OpenMP helpers of the self-collision pass (private to src/sim): per-thread lists, their
// deterministic merge, thread count / id without OpenMP, and the size below which a loop stays
// serial. In an anonymous namespace like the rest of the pass's internal helpers (see
// collision_primitives.h).
#pragma once

#include <algorithm>
#include <chrono>
#include <vector>

#include "textile_handling/sim/self_collision_pass.h"
#include "textile_handling/sim/types.h"

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {

namespace {

using Clock = std::chrono::steady_clock;
// Below this many work items a loop runs on one thread: the parallel region would cost more than it
// saves (and far more on an oversubscribed machine).
constexpr Index kParallelMin = 2048;

template <class T>
void resetThreadLists(std::vector<ThreadList<T>>& local, int threads) {
  local.resize(static_cast<size_t>(threads));
  for (auto& l : local) l.items.clear();
}

// The per-thread lists one after the other, in thread order.
template <class T>
void concatenate(const std::vector<ThreadList<T>>& local, std::vector<T>& out) {
  size_t total = 0;
  for (const auto& l : local) total += l.items.size();
  out.clear();
  out.reserve(total);
  for (const auto& l : local) out.insert(out.end(), l.items.begin(), l.items.end());
}

// Merges per-thread hit lists into one sorted, duplicate-free list (independent of thread count).
template <class HitT>
void mergeSorted(std::vector<ThreadList<HitT>>& local, std::vector<HitT>& out) {
  concatenate(local, out);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

inline int threadCount() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}
inline int threadId() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

}  // namespace

}  // namespace textile_handling
