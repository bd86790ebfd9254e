// Search kernels of the silhouette matcher (private to src/vision): the projection-bound sums
// (SSE2 when available) and the exact shift search of one database entry against a query, with
// per-shift pruning by the row / column projection bounds. Masks are 1-bit rows of 64-bit words
// (bit_mask.h); counts are pixels, shifts are pixels (dx right, dy down).
#pragma once

#include <cstdint>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "textile_handling/vision/bit_mask.h"

namespace textile_handling {
namespace vision {
namespace matcher_detail {

inline int roundUp8(int n) { return (n + 7) & ~7; }

// sum_i min(a[i], b[i]) over n int16 values (n a multiple of 8, values >= 0).
inline int sumMin16(const std::int16_t* a, const std::int16_t* b, int n) {
#if defined(__SSE2__)
  __m128i acc = _mm_setzero_si128();
  const __m128i ones = _mm_set1_epi16(1);
  for (int i = 0; i < n; i += 8) {
    const __m128i m = _mm_min_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i)),
                                    _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i)));
    acc = _mm_add_epi32(acc, _mm_madd_epi16(m, ones));
  }
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, _MM_SHUFFLE(1, 0, 3, 2)));
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(acc);
#else
  int s = 0;
  for (int i = 0; i < n; ++i) s += std::min(a[i], b[i]);
  return s;
#endif
}

// sum_i min(a[i], b[i]) over n uint8 values (n a multiple of 16).
inline int sumMin8(const std::uint8_t* a, const std::uint8_t* b, int n) {
#if defined(__SSE2__)
  __m128i acc = _mm_setzero_si128();
  const __m128i zero = _mm_setzero_si128();
  for (int i = 0; i < n; i += 16) {
    const __m128i m = _mm_min_epu8(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i)),
                                   _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i)));
    acc = _mm_add_epi64(acc, _mm_sad_epu8(m, zero));
  }
  return _mm_cvtsi128_si32(acc) + _mm_cvtsi128_si32(_mm_unpackhi_epi64(acc, acc));
#else
  int s = 0;
  for (int i = 0; i < n; ++i) s += std::min(a[i], b[i]);
  return s;
#endif
}

inline int roundUp16(int n) { return (n + 15) & ~15; }

// ---------------------------------------------------------------------------------------------
// Exact shift search of one entry, with per-shift pruning by the row / column projection bounds.

struct ShiftSearch {
  // inputs
  const std::uint64_t* qa = nullptr;  // query words
  const std::uint64_t* eb = nullptr;  // entry words
  int nw = 1;
  int ay0 = 0, ay1 = 0, by0 = 0, by1 = 0;  // row supports [y0, y1)
  std::int64_t a = 0, b = 0;               // areas
  const std::int16_t* arows = nullptr;     // query row counts, arows[y] valid for y in [ay0, ay1)
  const std::int16_t* brows = nullptr;     // entry row counts, brows[y] valid for y in [by0, by1)
  const int* rbound = nullptr;             // indexed dy + Dy
  const int* cbound = nullptr;             // indexed dx + Dx
  const int* dy_order = nullptr;           // dy values, row bound descending
  const int* dx_order = nullptr;           // dx values whose column bound passes the floor, descending
  int ndy = 0, ndx = 0, Dx = 0, Dy = 0;
  double floor = 0;                        // only results with score >= floor (and > 0) matter
  int* suffix = nullptr;                   // scratch, >= H + 1 ints
  // outputs
  bool found = false;
  double score = 0;
  int dx = 0, dy = 0;
  std::uint64_t evaluated = 0;
};

/// Runs the search described by `s` (inputs) and fills its outputs: the best shift with score >= floor
/// (and > 0), whether one was found, and the number of shifts evaluated. Uses a POPCNT clone of the
/// kernel when the CPU has one (same results).
void runShiftSearch(ShiftSearch& s);

}  // namespace matcher_detail
}  // namespace vision
}  // namespace textile_handling
