// Wall-clock durations for the timing fields of results and progress reports (steady clock, so
// immune to clock adjustments).
#pragma once

#include <chrono>

namespace textile_handling {

/// Milliseconds elapsed on the steady clock since `t0`.
inline double msSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// Seconds elapsed on the steady clock since `t0`.
inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace textile_handling
