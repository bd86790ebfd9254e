// Internal to sim_core: a loop whose expensive part runs on all OpenMP threads while its results are
// added up in a fixed order, so that the sums are bitwise the same for every thread count (and equal
// to the plain serial loop's).
#pragma once

#include <omp.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// The rows one thread adds to in computeInParallelApplyByRowRanges(): one contiguous range [begin, end).
struct RowShare {
  Index begin = 0;
  Index end = 0;
  bool owns(Index row) const { return row >= begin && row < end; }
};

/// The split of rows [0, rows) into one contiguous range per thread (equal sizes), and per range the
/// items that add to a row in it, in increasing order. An item whose rows lie in two ranges is listed
/// in both: both threads compute it and each adds its own rows.
class RowRangeSchedule {
 public:
  int threads() const { return static_cast<int>(shares_.size()); }
  std::size_t itemCount() const { return count_; }
  Index rowCount() const { return rows_; }
  const RowShare& share(int thread) const { return shares_[static_cast<std::size_t>(thread)]; }
  const std::vector<std::uint32_t>& items(int thread) const { return items_[static_cast<std::size_t>(thread)]; }

  /// rows_of(i, visit) calls visit(row) for every row item i adds to (each row in [0, rows)).
  template <class RowsOf>
  void build(std::size_t count, Index rows, int threads, RowsOf&& rows_of) {
    count_ = count;
    rows_ = rows;
    shares_.assign(static_cast<std::size_t>(threads), RowShare{});
    items_.assign(static_cast<std::size_t>(threads), {});
    for (int t = 0; t < threads; ++t)
      shares_[static_cast<std::size_t>(t)] = {static_cast<Index>(std::int64_t{rows} * t / threads),
                                              static_cast<Index>(std::int64_t{rows} * (t + 1) / threads)};
    std::vector<std::size_t> last(static_cast<std::size_t>(threads), count);  // per range: the last item listed
    for (std::size_t i = 0; i < count; ++i)
      rows_of(i, [&](Index row) {
        // A first guess, then the range that really holds the row.
        auto r = static_cast<std::size_t>(std::min<std::int64_t>(threads - 1, std::int64_t{row} * threads / std::max<Index>(rows, 1)));
        while (r > 0 && row < shares_[r].begin) --r;
        while (r + 1 < shares_.size() && row >= shares_[r].end) ++r;
        if (last[r] != i) {
          items_[r].push_back(static_cast<std::uint32_t>(i));
          last[r] = i;
        }
      });
  }

 private:
  std::size_t count_ = 0;
  Index rows_ = 0;
  std::vector<RowShare> shares_;
  std::vector<std::vector<std::uint32_t>> items_;
};

/// For i = 0 .. count - 1, compute(i, local) fills `local` (a default-constructed Local) and
/// apply(i, local, share) adds it, on all threads: thread t walks the items that add to its range of
/// rows (RowRangeSchedule) in increasing order, computing and adding each, and apply must add only the
/// entries of rows share.owns(). Each entry still receives its terms in item order, so the sums are
/// those of the serial loop (for i: compute, apply) on any thread count. compute must not write
/// shared state. `schedule` is rebuilt here (outside the parallel region) when the
/// item count, the row count or the thread count has changed; rows_of as in RowRangeSchedule::build.
/// Below `serial_below` items the loop runs serially on the calling thread.
template <class Local, class RowsOf, class Compute, class ApplyRows>
void computeInParallelApplyByRowRanges(RowRangeSchedule& schedule, std::size_t count, Index rows, RowsOf&& rows_of,
                                       Compute&& compute, ApplyRows&& apply, std::size_t serial_below = 256) {
  auto run = [&](const std::uint32_t* items, std::size_t n, const RowShare& share) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = items ? items[k] : k;
      Local local;
      compute(i, local);
      apply(i, static_cast<const Local&>(local), share);
    }
  };
  const int threads = omp_get_max_threads();
  if (count < serial_below || threads == 1 || omp_in_parallel()) {
    run(nullptr, count, RowShare{0, rows});
    return;
  }
  if (schedule.threads() != threads || schedule.itemCount() != count || schedule.rowCount() != rows)
    schedule.build(count, rows, threads, rows_of);
#pragma omp parallel
  {
    const int t = omp_get_thread_num();
    if (omp_get_num_threads() == schedule.threads()) {
      const std::vector<std::uint32_t>& items = schedule.items(t);
      run(items.data(), items.size(), schedule.share(t));
    } else if (t == 0) {  // a smaller team than asked for: all items, all rows, on one thread
      run(nullptr, count, RowShare{0, rows});
    }
  }
}

}  // namespace textile_handling
