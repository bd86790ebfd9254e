// Exact shift search of one silhouette entry: pruned by the needed intersection and the row / column
// projection bounds, with a run-time choice of a POPCNT clone. See docs/vision.md.
#include "silhouette_shift_search.h"

#include <algorithm>
#include <cstdint>

namespace textile_handling {
namespace vision {
namespace matcher_detail {

namespace {

#if defined(__GNUC__)
#define TH_VISION_ALWAYS_INLINE inline __attribute__((always_inline))
#else
#define TH_VISION_ALWAYS_INLINE inline
#endif

// Smallest intersection I >= 1 with iouFromCounts(I, a, b) >= fl (exact: checked with the same
// division the scores use); a + b + 1 if none.
inline std::int64_t neededIntersection(double fl, std::int64_t a, std::int64_t b) {
  const std::int64_t cap = std::min(a, b);
  if (!(fl > 0)) return 1;
  std::int64_t i = static_cast<std::int64_t>(fl * static_cast<double>(a + b) / (1.0 + fl));
  i = std::max<std::int64_t>(1, std::min(i, cap));
  while (i > 1 && iouFromCounts(i - 1, a, b) >= fl) --i;
  while (i <= cap && iouFromCounts(i, a, b) < fl) ++i;
  return i;
}

// |A and shift(B, dx, dy)| over rows [ys, ye), or -1 as soon as the count plus the row-projection bound
// of the remaining rows (suffix[y], indexed from ys) falls below `need`.
template <bool kOneWord>
TH_VISION_ALWAYS_INLINE std::int64_t intersectionAt(const ShiftSearch& s, int dx, int dy, int ys, int ye,
                                                    std::int64_t need) {
  std::int64_t n = 0;
  constexpr int kChunk = 8;
  if (kOneWord) {
    const std::uint64_t* qa = s.qa;
    const std::uint64_t* eb = s.eb;
    for (int y0 = ys; y0 < ye; y0 += kChunk) {
      const int y1 = std::min(ye, y0 + kChunk);
      if (dx >= 0) {
        for (int y = y0; y < y1; ++y) n += __builtin_popcountll(qa[y] & (eb[y - dy] << dx));
      } else {
        const int r = -dx;
        for (int y = y0; y < y1; ++y) n += __builtin_popcountll(qa[y] & (eb[y - dy] >> r));
      }
      if (n + s.suffix[y1 - ys] < need) return -1;
    }
  } else {
    const int nw = s.nw;
    for (int y = ys; y < ye; ++y) {
      const std::uint64_t* ar = s.qa + static_cast<std::size_t>(y) * nw;
      const std::uint64_t* br = s.eb + static_cast<std::size_t>(y - dy) * nw;
      for (int k = 0; k < nw; ++k) n += __builtin_popcountll(ar[k] & detail::shiftedWord(br, nw, k, dx));
      if (((y - ys) & 7) == 7 && n + s.suffix[y + 1 - ys] < need) return -1;
    }
  }
  return n;
}

template <bool kOneWord>
TH_VISION_ALWAYS_INLINE void searchBody(ShiftSearch& s) {
  bool have = false;
  double best = 0;
  int bdx = 0, bdy = 0;
  std::uint64_t evaluated = 0;
  for (int i = 0; i < s.ndy; ++i) {
    const int dy = s.dy_order[i];
    const int rb = s.rbound[dy + s.Dy];
    const double fl = have ? std::max(s.floor, best) : s.floor;
    if (rb == 0 || iouFromCounts(rb, s.a, s.b) < fl) break;
    // Rows where both masks can overlap at this dy, and the suffix sums of the per-row bound.
    const int ys = std::max(s.ay0, s.by0 + dy), ye = std::min(s.ay1, s.by1 + dy);
    if (ys >= ye) continue;
    s.suffix[ye - ys] = 0;
    for (int y = ye - 1; y >= ys; --y) s.suffix[y - ys] = s.suffix[y + 1 - ys] + std::min(s.arows[y], s.brows[y - dy]);
    double need_fl = -1;
    std::int64_t need = 1;
    for (int j = 0; j < s.ndx; ++j) {
      const int dx = s.dx_order[j];
      const int cb = s.cbound[dx + s.Dx];
      const double fl2 = have ? std::max(s.floor, best) : s.floor;
      if (iouFromCounts(cb, s.a, s.b) < fl2) break;
      const double ub = iouFromCounts(std::min(rb, cb), s.a, s.b);
      if (ub < s.floor) continue;
      if (have && (ub < best || (ub == best && !shiftBefore(dx, dy, bdx, bdy)))) continue;
      if (fl2 != need_fl) {
        need = neededIntersection(fl2, s.a, s.b);
        need_fl = fl2;
      }
      const std::int64_t inter = intersectionAt<kOneWord>(s, dx, dy, ys, ye, need);
      ++evaluated;
      if (inter <= 0) continue;
      const double sc = iouFromCounts(inter, s.a, s.b);
      if (sc < s.floor) continue;
      if (!have || sc > best || (sc == best && shiftBefore(dx, dy, bdx, bdy))) {
        have = true;
        best = sc;
        bdx = dx;
        bdy = dy;
      }
    }
  }
  s.found = have;
  s.score = best;
  s.dx = bdx;
  s.dy = bdy;
  s.evaluated += evaluated;
}

void searchPortable(ShiftSearch& s) {
  if (s.nw == 1)
    searchBody<true>(s);
  else
    searchBody<false>(s);
}

// Hardware POPCNT without requiring -mpopcnt: a clone compiled for the popcnt target, picked at run
// time if the CPU has it (every x86-64 CPU since ~2008; the generic build keeps working without).
#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__) && !defined(__POPCNT__) && \
    !defined(TH_VISION_NO_POPCNT_DISPATCH)
#define TH_VISION_POPCNT_DISPATCH 1
__attribute__((target("popcnt"))) void searchPopcnt(ShiftSearch& s) {
  if (s.nw == 1)
    searchBody<true>(s);
  else
    searchBody<false>(s);
}
#endif

using SearchFn = void (*)(ShiftSearch&);

SearchFn selectSearch() {
#ifdef TH_VISION_POPCNT_DISPATCH
  __builtin_cpu_init();
  if (__builtin_cpu_supports("popcnt")) return &searchPopcnt;
#endif
  return &searchPortable;
}

const SearchFn kSearch = selectSearch();

}  // namespace

void runShiftSearch(ShiftSearch& s) { kSearch(s); }

}  // namespace matcher_detail
}  // namespace vision
}  // namespace textile_handling
