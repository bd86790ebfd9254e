// The ordered parallel loops of src/sim/ordered_parallel.h: the row-range schedule lists every item
// in exactly the ranges of its rows, and the sums by row ranges are bitwise those of the serial loop.
#include <gtest/gtest.h>
#include <omp.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <set>
#include <vector>

#include "../../src/sim/ordered_parallel.h"
#include "../test_support.h"

using namespace textile_handling;

namespace {

constexpr Index kRows = 1000;

// Item i adds to three rows, the last one far away so that it can fall into a range that is not
// next to the others'.
std::array<Index, 3> rowsOfItem(std::size_t i) {
  const auto r = static_cast<Index>(i % kRows);
  return {r, static_cast<Index>((r + 1) % kRows), static_cast<Index>((r * 7 + 500) % kRows)};
}

auto visitRows = [](std::size_t i, auto&& visit) {
  for (Index r : rowsOfItem(i)) visit(r);
};

// Terms whose sum depends on the order in which they are added (1e16 + 1 - 1e16 != 1 - 1e16 + 1e16).
double termOf(std::size_t i, int k) { return (i % 3 == 0 ? 1e16 : 1.0) * (1 + k) * ((i / 3) % 2 ? -1 : 1); }

std::vector<double> sumsByRowRanges(int threads, std::size_t count, std::atomic<long>* computed = nullptr) {
  test_support::ThreadScope scope(threads);
  std::vector<double> rows(static_cast<std::size_t>(kRows), 0.0);
  RowRangeSchedule schedule;
  computeInParallelApplyByRowRanges<std::array<double, 3>>(
      schedule, count, kRows, visitRows,
      [&](std::size_t i, std::array<double, 3>& local) {
        if (computed) ++*computed;
        for (int k = 0; k < 3; ++k) local[static_cast<std::size_t>(k)] = termOf(i, k);
      },
      [&](std::size_t i, const std::array<double, 3>& local, const RowShare& share) {
        const std::array<Index, 3> r = rowsOfItem(i);
        for (int k = 0; k < 3; ++k)
          if (share.owns(r[static_cast<std::size_t>(k)])) rows[static_cast<std::size_t>(r[static_cast<std::size_t>(k)])] += local[static_cast<std::size_t>(k)];
      });
  return rows;
}

}  // namespace

TEST(RowRangeSchedule, ListsEveryItemInTheRangesOfItsRowsInIncreasingOrder) {
  for (int threads : {1, 2, 3, 5}) {
    RowRangeSchedule s;
    const std::size_t count = 2600;
    s.build(count, kRows, threads, visitRows);
    ASSERT_EQ(s.threads(), threads);
    EXPECT_EQ(s.share(0).begin, 0);
    EXPECT_EQ(s.share(threads - 1).end, kRows);
    for (int t = 0; t + 1 < threads; ++t) EXPECT_EQ(s.share(t).end, s.share(t + 1).begin);
    for (int t = 0; t < threads; ++t) {
      EXPECT_NEAR(s.share(t).end - s.share(t).begin, kRows / threads, 1);
      const std::vector<std::uint32_t>& items = s.items(t);
      EXPECT_TRUE(std::is_sorted(items.begin(), items.end()));
      EXPECT_EQ(std::set<std::uint32_t>(items.begin(), items.end()).size(), items.size()) << "listed twice";
      std::set<std::uint32_t> expected;
      for (std::size_t i = 0; i < count; ++i)
        for (Index r : rowsOfItem(i))
          if (s.share(t).owns(r)) expected.insert(static_cast<std::uint32_t>(i));
      EXPECT_EQ(std::set<std::uint32_t>(items.begin(), items.end()), expected) << threads << " threads, range " << t;
    }
  }
}

TEST(ComputeInParallelApplyByRowRanges, SumsAreBitwiseThoseOfTheSerialLoopOnAnyThreadCount) {
  const std::size_t count = 5000;  // above the serial threshold
  std::vector<double> serial(static_cast<std::size_t>(kRows), 0.0);
  for (std::size_t i = 0; i < count; ++i) {
    const std::array<Index, 3> r = rowsOfItem(i);
    for (int k = 0; k < 3; ++k) serial[static_cast<std::size_t>(r[static_cast<std::size_t>(k)])] += termOf(i, k);
  }
  // The terms' order matters: the same terms added backwards give other sums.
  std::vector<double> backwards(static_cast<std::size_t>(kRows), 0.0);
  for (std::size_t i = count; i-- > 0;) {
    const std::array<Index, 3> r = rowsOfItem(i);
    for (int k = 0; k < 3; ++k) backwards[static_cast<std::size_t>(r[static_cast<std::size_t>(k)])] += termOf(i, k);
  }
  ASSERT_NE(serial, backwards);
  for (int threads : {1, 2, 3, 4}) {
    std::atomic<long> computed{0};
    EXPECT_EQ(sumsByRowRanges(threads, count, &computed), serial) << threads << " threads";
    // Every item is computed once per range it adds to, at most once per thread.
    EXPECT_GE(computed.load(), static_cast<long>(count));
    EXPECT_LE(computed.load(), static_cast<long>(count) * std::min(threads, 3));
  }
  EXPECT_EQ(sumsByRowRanges(2, 100), sumsByRowRanges(1, 100));  // below the threshold: serial
}
