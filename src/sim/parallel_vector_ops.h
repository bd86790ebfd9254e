// Internal to sim_core: element-wise vector updates of the iterative solvers on all OpenMP threads.
// Each entry is computed exactly as in the serial expression, so results are bitwise the same for any
// thread count; below parallelWorthIt()'s size the loop stays on one thread.
#pragma once

#include "parallel_size.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Calls f(start, length) for 64 contiguous pieces covering [0, n), in parallel when worth it.
template <class F>
void forEachVectorPiece(Index n, F&& f) {
  constexpr Index kPieces = 64;
#pragma omp parallel for schedule(static) if (parallelWorthIt(n, 1))
  for (Index c = 0; c < kPieces; ++c) {
    const Index lo = n * c / kPieces, hi = n * (c + 1) / kPieces;
    if (hi > lo) f(lo, hi - lo);
  }
}

/// y += a x.
inline void addScaled(VecX& y, Real a, const VecX& x) {
  forEachVectorPiece(y.size(), [&](Index lo, Index len) { y.segment(lo, len) += a * x.segment(lo, len); });
}

/// y = x + a y.
inline void scaleAndAdd(VecX& y, Real a, const VecX& x) {
  forEachVectorPiece(y.size(), [&](Index lo, Index len) { y.segment(lo, len) = x.segment(lo, len) + a * y.segment(lo, len); });
}

/// y = x - y.
inline void subtractFrom(VecX& y, const VecX& x) {
  forEachVectorPiece(y.size(), [&](Index lo, Index len) { y.segment(lo, len) = x.segment(lo, len) - y.segment(lo, len); });
}

}  // namespace textile_handling
