// Thread counts of the command-line tools: parsed strictly and capped, so that a typo or a hostile
// argument (--threads 100000) can neither crash the OpenMP runtime nor swamp the machine.
#pragma once

#include <string>

namespace textile_handling {

/// Requests above this are refused as mistakes rather than clamped (docs/simulation.md).
constexpr int kMaxRequestableThreads = 1024;

/// The most OpenMP threads a tool uses: twice the hardware threads (at least 1). More only adds
/// contention on a shared machine.
int maxUsefulThreads();

/// Parses a --threads argument: a whole decimal integer in 1..kMaxRequestableThreads. Returns false
/// with a reason in `*error` otherwise.
bool parseThreadCount(const std::string& text, int* threads, std::string* error);

/// Sets the OpenMP thread count to min(requested, maxUsefulThreads()); requested <= 0 means "keep the
/// runtime's default" (OMP_NUM_THREADS or the core count), which is capped too. Returns the count set
/// and, if it was lowered, a note saying so in `*note` (else `*note` is cleared).
int applyThreadLimit(int requested, std::string* note);

}  // namespace textile_handling
