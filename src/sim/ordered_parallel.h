// Internal to sim_core: a loop whose expensive part runs on all OpenMP threads while its results are
// added up in a fixed order, so that the sums are bitwise the same for every thread count (and equal
// to the plain serial loop's).
#pragma once

#include <omp.h>

#include <algorithm>
#include <cstddef>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// The rows one thread adds to in computeInParallelApplyByRows(): blocks of 64 consecutive rows dealt
/// round-robin to the threads, so that the rows of any stretch of neighbouring stencils are shared
/// among all threads (contiguous halves would leave one thread idle while a chunk touches the other's).
struct RowShare {
  Index thread = 0;
  Index threads = 1;
  bool owns(Index row) const { return threads == 1 || (row >> 6) % threads == thread; }
};

namespace ordered_parallel_detail {

/// Splits [0, count) into chunks of `chunk` items; for each chunk, compute(i, local) fills the chunk's
/// buffer in parallel and then apply_chunk(start, n, buffer) consumes it.
template <class Local, class Compute, class ApplyChunk>
void forEachComputedChunk(std::size_t count, std::size_t chunk, Compute& compute, ApplyChunk&& apply_chunk) {
  if (count == 0) return;
  std::vector<Local> buffer(std::min(count, chunk));
  for (std::size_t start = 0; start < count; start += chunk) {
    const std::ptrdiff_t n = static_cast<std::ptrdiff_t>(std::min(chunk, count - start));
#pragma omp parallel for schedule(static) if (n > 64)
    for (std::ptrdiff_t k = 0; k < n; ++k) compute(start + static_cast<std::size_t>(k), buffer[static_cast<std::size_t>(k)]);
    apply_chunk(start, n, buffer);
  }
}

}  // namespace ordered_parallel_detail

/// For i = 0 .. count - 1: compute(i, local) fills `local` (a default-constructed Local) in parallel,
/// then apply(i, local) runs serially in increasing i. Works in chunks of `chunk` items so the buffer
/// stays small (chunk Locals). compute must not write shared state; apply may.
template <class Local, class Compute, class Apply>
void computeInParallelApplyInOrder(std::size_t count, Compute&& compute, Apply&& apply, std::size_t chunk = 2048) {
  ordered_parallel_detail::forEachComputedChunk<Local>(
      count, chunk, compute, [&](std::size_t start, std::ptrdiff_t n, const std::vector<Local>& buffer) {
        for (std::ptrdiff_t k = 0; k < n; ++k) apply(start + static_cast<std::size_t>(k), buffer[static_cast<std::size_t>(k)]);
      });
}

/// As computeInParallelApplyInOrder(), but the adding is parallel too: every thread owns a share of
/// the rows (RowShare) and calls apply(i, local, share) for every i in increasing order, which must
/// add only the entries of rows the share owns. Each entry still receives its terms in item order,
/// so the sums are those of the serial loop on any thread count.
template <class Local, class Compute, class ApplyRows>
void computeInParallelApplyByRows(std::size_t count, Compute&& compute, ApplyRows&& apply, std::size_t chunk = 2048) {
  ordered_parallel_detail::forEachComputedChunk<Local>(
      count, chunk, compute, [&](std::size_t start, std::ptrdiff_t n, const std::vector<Local>& buffer) {
#pragma omp parallel if (n > 64)
        {
          const RowShare share{omp_get_thread_num(), omp_get_num_threads()};
          for (std::ptrdiff_t k = 0; k < n; ++k)
            apply(start + static_cast<std::size_t>(k), buffer[static_cast<std::size_t>(k)], share);
        }
      });
}

}  // namespace textile_handling
