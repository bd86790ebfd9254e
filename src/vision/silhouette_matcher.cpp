#include "textile_handling/vision/silhouette_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace textile_handling {
namespace vision {

namespace {

constexpr int kMaxSide = 8192;

int roundUp8(int n) { return (n + 7) & ~7; }

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

int roundUp16(int n) { return (n + 15) & ~15; }

double normaliseAngle(double a) {
  double r = std::fmod(a, 360.0);
  if (r < 0) r += 360.0;
  if (r >= 360.0) r -= 360.0;
  return r;
}

double circularDistance(double a, double b) {
  const double d = std::abs(normaliseAngle(a) - normaliseAngle(b));
  return std::min(d, 360.0 - d);
}

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

// ---------------------------------------------------------------------------------------------
// Per-query preparation and per-entry bounds.

struct QueryPrep {
  const std::uint64_t* words = nullptr;
  std::int64_t area = 0;
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  std::vector<std::int16_t> rowpad, colpad;  // query counts at [off + i], zero elsewhere
  std::vector<std::uint8_t> colpad8;         // same as colpad as bytes, counts at [coff8 + i]
  int roff = 0, coff = 0, coff8 = 0;
};

struct Scratch {
  std::vector<int> rbound, cbound, dy_order, dx_order, suffix;
};

struct EntryOutcome {
  enum Kind { kAreaPruned, kProjectionPruned, kBelowFloor, kFound } kind = kAreaPruned;
  double score = 0;
  int dx = 0, dy = 0;
};

}  // namespace

// Friend of SilhouetteMatcher: the search machinery that needs the packed store.
struct MatcherAccess {
  const SilhouetteMatcher& m;
  int Dx = 0, Dy = 0;

  MatcherAccess(const SilhouetteMatcher& matcher, const MatchOptions& o)
      : m(matcher), Dx(std::min(o.max_dx, matcher.width_ - 1)), Dy(std::min(o.max_dy, matcher.height_ - 1)) {}

  void validateQuery(const BitMask& q, const char* what) const {
    if (m.meta_.empty()) throw InvalidArgumentError(what, "matcher", "the silhouette database is empty");
    if (q.empty()) throw InvalidArgumentError(what, "mask", "query mask is empty (0 pixels wide or high)");
    if (q.width() != m.width_ || q.height() != m.height_) {
      std::ostringstream os;
      os << "query mask is " << q.width() << "x" << q.height() << " but the database holds " << m.width_ << "x"
         << m.height_ << " silhouettes";
      throw InvalidArgumentError(what, "mask", os.str());
    }
  }

  QueryPrep prepare(const BitMask& q) const {
    QueryPrep p;
    p.words = q.words().data();
    p.area = q.count();
    q.boundingBox(&p.x0, &p.y0, &p.x1, &p.y1);
    p.roff = m.rows_padded_;
    p.coff = m.cols_padded_;
    p.rowpad.assign(static_cast<std::size_t>(3 * m.rows_padded_), 0);
    p.colpad.assign(static_cast<std::size_t>(3 * m.cols_padded_), 0);
    const std::vector<int> rc = q.rowCounts(), cc = q.colCounts();
    for (int y = 0; y < m.height_; ++y) p.rowpad[static_cast<std::size_t>(p.roff + y)] = static_cast<std::int16_t>(rc[static_cast<std::size_t>(y)]);
    for (int x = 0; x < m.width_; ++x) p.colpad[static_cast<std::size_t>(p.coff + x)] = static_cast<std::int16_t>(cc[static_cast<std::size_t>(x)]);
    if (m.bytes_) {
      p.coff8 = m.cols_padded16_;
      p.colpad8.assign(static_cast<std::size_t>(3 * m.cols_padded16_), 0);
      for (int x = 0; x < m.width_; ++x)
        p.colpad8[static_cast<std::size_t>(p.coff8 + x)] = static_cast<std::uint8_t>(cc[static_cast<std::size_t>(x)]);
    }
    return p;
  }

  double areaBound(const QueryPrep& q, std::size_t e) const {
    const std::int64_t b = m.area_[e];
    return iouFromCounts(std::min(q.area, b), q.area, b);
  }

  // Largest row / column projection bound over the shift range (fills the scratch bound arrays).
  // Returns min(max row bound, max column bound), an upper bound on the intersection at any shift;
  // stops early (returning the row maximum) if the row bound alone is below `floor`.
  int projectionBound(const QueryPrep& q, std::size_t e, double floor, Scratch& s) const {
    const std::int16_t* bb = &m.bbox_[4 * e];
    const int bx0 = bb[0], by0 = bb[1], bx1 = bb[2], by1 = bb[3];
    const std::int64_t b = m.area_[e];
    s.rbound.resize(static_cast<std::size_t>(2 * Dy + 1));
    s.cbound.resize(static_cast<std::size_t>(2 * Dx + 1));
    const std::int16_t* rb = &m.row_counts_[e * static_cast<std::size_t>(m.rows_padded_)];
    const int r0 = by0 & ~7, r1 = roundUp8(by1);
    int rmax = 0;
    for (int dy = -Dy; dy <= Dy; ++dy) {
      const int v = sumMin16(rb + r0, q.rowpad.data() + q.roff + r0 + dy, r1 - r0);
      s.rbound[static_cast<std::size_t>(dy + Dy)] = v;
      rmax = std::max(rmax, v);
    }
    if (rmax == 0 || iouFromCounts(rmax, q.area, b) < floor) return rmax;
    int cmax = 0;
    if (m.bytes_) {
      const std::uint8_t* cb = &m.col_counts8_[e * static_cast<std::size_t>(m.cols_padded16_)];
      const int c0 = bx0 & ~15, c1 = roundUp16(bx1);
      for (int dx = -Dx; dx <= Dx; ++dx) {
        const int v = sumMin8(cb + c0, q.colpad8.data() + q.coff8 + c0 + dx, c1 - c0);
        s.cbound[static_cast<std::size_t>(dx + Dx)] = v;
        cmax = std::max(cmax, v);
      }
    } else {
      const std::int16_t* cb = &m.col_counts_[e * static_cast<std::size_t>(m.cols_padded_)];
      const int c0 = bx0 & ~7, c1 = roundUp8(bx1);
      for (int dx = -Dx; dx <= Dx; ++dx) {
        const int v = sumMin16(cb + c0, q.colpad.data() + q.coff + c0 + dx, c1 - c0);
        s.cbound[static_cast<std::size_t>(dx + Dx)] = v;
        cmax = std::max(cmax, v);
      }
    }
    return std::min(rmax, cmax);
  }

  // Exact best shift of entry e among results with score >= floor (and > 0), bounds in `s` already
  // computed by projectionBound().
  void exactSearch(const QueryPrep& q, std::size_t e, double floor, Scratch& s, EntryOutcome& out,
                   MatchStats& stats) const {
    const std::int16_t* bb = &m.bbox_[4 * e];
    const std::int64_t b = m.area_[e];
    const int* rbp = s.rbound.data();
    const int* cbp = s.cbound.data();
    const int dyo = Dy, dxo = Dx;
    // All dy (few) by row bound; only the dx whose column bound can reach the floor, by column bound.
    s.dy_order.resize(static_cast<std::size_t>(2 * Dy + 1));
    std::iota(s.dy_order.begin(), s.dy_order.end(), -Dy);
    std::sort(s.dy_order.begin(), s.dy_order.end(), [rbp, dyo](int u, int v) {
      const int bu = rbp[u + dyo], bv = rbp[v + dyo];
      return bu != bv ? bu > bv : std::abs(u) < std::abs(v);
    });
    s.dx_order.clear();
    for (int dx = -Dx; dx <= Dx; ++dx) {
      const int cb = cbp[dx + Dx];
      if (cb > 0 && iouFromCounts(cb, q.area, b) >= floor) s.dx_order.push_back(dx);
    }
    std::sort(s.dx_order.begin(), s.dx_order.end(), [cbp, dxo](int u, int v) {
      const int bu = cbp[u + dxo], bv = cbp[v + dxo];
      return bu != bv ? bu > bv : std::abs(u) < std::abs(v);
    });
    s.suffix.resize(static_cast<std::size_t>(m.height_) + 1);
    ShiftSearch ss;
    ss.qa = q.words;
    ss.eb = &m.words_[e * static_cast<std::size_t>(m.height_) * m.words_per_row_];
    ss.nw = m.words_per_row_;
    ss.ay0 = q.y0;
    ss.ay1 = q.y1;
    ss.by0 = bb[1];
    ss.by1 = bb[3];
    ss.a = q.area;
    ss.b = b;
    ss.arows = q.rowpad.data() + q.roff;
    ss.brows = &m.row_counts_[e * static_cast<std::size_t>(m.rows_padded_)];
    ss.rbound = rbp;
    ss.cbound = cbp;
    ss.dy_order = s.dy_order.data();
    ss.dx_order = s.dx_order.data();
    ss.ndy = 2 * Dy + 1;
    ss.ndx = static_cast<int>(s.dx_order.size());
    ss.suffix = s.suffix.data();
    ss.Dx = Dx;
    ss.Dy = Dy;
    ss.floor = floor;
    kSearch(ss);
    stats.shifts_evaluated += ss.evaluated;
    ++stats.evaluated;
    if (ss.found) {
      out.kind = EntryOutcome::kFound;
      out.score = ss.score;
      out.dx = ss.dx;
      out.dy = ss.dy;
    } else {
      out.kind = EntryOutcome::kBelowFloor;
    }
  }

  // Full pipeline for one entry with a floor: area bound, projection bound, exact search.
  EntryOutcome evaluate(const QueryPrep& q, std::size_t e, double floor, Scratch& s, MatchStats& stats) const {
    EntryOutcome out;
    const std::int64_t b = m.area_[e];
    if (b == 0 || areaBound(q, e) < floor) {
      out.kind = EntryOutcome::kAreaPruned;
      ++stats.pruned_area;
      return out;
    }
    const int pb = projectionBound(q, e, floor, s);
    if (pb == 0 || iouFromCounts(pb, q.area, b) < floor) {
      out.kind = EntryOutcome::kProjectionPruned;
      ++stats.pruned_projection;
      return out;
    }
    exactSearch(q, e, floor, s, out, stats);
    return out;
  }
};

namespace {

struct GroupBest {
  double score = -1;  // < 0: none yet
  std::uint32_t entry = 0;
  int dx = 0, dy = 0;
};

bool betterEntry(double s1, std::uint32_t e1, double s2, std::uint32_t e2) {
  return s1 > s2 || (s1 == s2 && e1 < e2);
}

void validateOptions(const MatchOptions& o, const char* what) {
  if (o.max_dx < 0 || o.max_dy < 0)
    throw InvalidArgumentError(what, "max_dx/max_dy", "max_dx and max_dy must be >= 0");
  if (o.top_k < 1) throw InvalidArgumentError(what, "top_k", "top_k must be >= 1");
}

}  // namespace

// ---------------------------------------------------------------------------------------------

std::size_t SilhouetteMatcher::add(const SilhouetteEntry& entry) {
  const BitMask& mk = entry.mask;
  if (mk.empty()) throw InvalidArgumentError("SilhouetteMatcher::add", "mask", "mask is empty (0 pixels wide or high)");
  if (mk.width() > kMaxSide || mk.height() > kMaxSide)
    throw LimitExceededError("SilhouetteMatcher::add", "mask", "masks larger than 8192 px per side are not supported");
  if (!std::isfinite(entry.view_angle_deg))
    throw InvalidArgumentError("SilhouetteMatcher::add", "view_angle_deg", "view angle is not finite");
  if (meta_.empty()) {
    width_ = mk.width();
    height_ = mk.height();
    words_per_row_ = mk.wordsPerRow();
    rows_padded_ = roundUp8(height_);
    cols_padded_ = roundUp8(width_);
    bytes_ = height_ <= 255;
    cols_padded16_ = roundUp16(width_);
  } else if (mk.width() != width_ || mk.height() != height_) {
    std::ostringstream os;
    os << "mask is " << mk.width() << "x" << mk.height() << " but the database holds "
       << width_ << "x" << height_ << " silhouettes";
    throw InvalidArgumentError("SilhouetteMatcher::add", "mask", os.str());
  }
  const std::size_t idx = meta_.size();
  const auto key = std::make_pair(entry.textile_id, entry.hold_point_id);
  auto it = group_index_.find(key);
  int g;
  if (it == group_index_.end()) {
    g = static_cast<int>(groups_.size());
    group_index_.emplace(key, g);
    groups_.push_back(Group{entry.textile_id, entry.hold_point_id, {}});
  } else {
    g = it->second;
  }
  groups_[static_cast<std::size_t>(g)].entries.push_back(static_cast<std::uint32_t>(idx));
  meta_.push_back(Meta{entry.textile_id, entry.hold_point_id, entry.view_angle_deg, g});
  words_.insert(words_.end(), mk.words().begin(), mk.words().end());
  const std::int64_t area = mk.count();
  area_.push_back(static_cast<std::int32_t>(area));
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  mk.boundingBox(&x0, &y0, &x1, &y1);
  for (int v : {x0, y0, x1, y1}) bbox_.push_back(static_cast<std::int16_t>(v));
  const std::vector<int> rc = mk.rowCounts(), cc = mk.colCounts();
  const std::size_t r0 = row_counts_.size(), c0 = col_counts_.size();
  row_counts_.resize(r0 + static_cast<std::size_t>(rows_padded_), 0);
  col_counts_.resize(c0 + static_cast<std::size_t>(cols_padded_), 0);
  for (int y = 0; y < height_; ++y) row_counts_[r0 + static_cast<std::size_t>(y)] = static_cast<std::int16_t>(rc[static_cast<std::size_t>(y)]);
  for (int x = 0; x < width_; ++x) col_counts_[c0 + static_cast<std::size_t>(x)] = static_cast<std::int16_t>(cc[static_cast<std::size_t>(x)]);
  if (bytes_) {
    const std::size_t c8 = col_counts8_.size();
    col_counts8_.resize(c8 + static_cast<std::size_t>(cols_padded16_), 0);
    for (int x = 0; x < width_; ++x) col_counts8_[c8 + static_cast<std::size_t>(x)] = static_cast<std::uint8_t>(cc[static_cast<std::size_t>(x)]);
  }
  // Keep by_area_ sorted by (area, index); new entries have the largest index.
  const auto pos = std::upper_bound(by_area_.begin(), by_area_.end(), area,
                                    [this](std::int64_t a, std::uint32_t e) { return a < area_[e]; });
  by_area_.insert(pos, static_cast<std::uint32_t>(idx));
  return idx;
}

void SilhouetteMatcher::reserve(std::size_t n) {
  meta_.reserve(n);
  area_.reserve(n);
  by_area_.reserve(n);
  bbox_.reserve(4 * n);
  if (width_ > 0) {
    words_.reserve(n * static_cast<std::size_t>(height_) * words_per_row_);
    row_counts_.reserve(n * static_cast<std::size_t>(rows_padded_));
    col_counts_.reserve(n * static_cast<std::size_t>(cols_padded_));
    if (bytes_) col_counts8_.reserve(n * static_cast<std::size_t>(cols_padded16_));
  }
}

void SilhouetteMatcher::clear() { *this = SilhouetteMatcher(); }

SilhouetteEntry SilhouetteMatcher::entry(std::size_t i) const {
  if (i >= meta_.size()) throw IndexOutOfRangeError("SilhouetteMatcher::entry: index out of range");
  SilhouetteEntry e;
  e.textile_id = meta_[i].textile_id;
  e.hold_point_id = meta_[i].hold_point_id;
  e.view_angle_deg = meta_[i].view_angle_deg;
  e.mask = BitMask(width_, height_);
  const std::size_t n = static_cast<std::size_t>(height_) * words_per_row_;
  for (int y = 0; y < height_; ++y)
    std::copy_n(&words_[i * n + static_cast<std::size_t>(y) * words_per_row_], words_per_row_, e.mask.row(y));
  return e;
}

QueryResult SilhouetteMatcher::query(const BitMask& mask, const MatchOptions& options) const {
  validateOptions(options, "SilhouetteMatcher::query");
  MatcherAccess acc(*this, options);
  acc.validateQuery(mask, "SilhouetteMatcher::query");
  const std::int64_t qa = mask.count();
  if (qa == 0) throw InvalidArgumentError("SilhouetteMatcher::query", "mask", "query mask has no foreground pixels");

  // Aggregation groups: (textile, hold point) by default, or the caller's coarser grouping.
  const std::vector<std::uint32_t>* custom = options.group_of_entry;
  std::size_t num_groups = groups_.size();
  if (custom) {
    if (custom->size() != meta_.size())
      throw InvalidArgumentError("SilhouetteMatcher::query", "group_of_entry", "group_of_entry has " + std::to_string(custom->size()) +
                                  " values for " + std::to_string(meta_.size()) + " entries");
    num_groups = 0;
    for (std::uint32_t g : *custom) num_groups = std::max<std::size_t>(num_groups, static_cast<std::size_t>(g) + 1);
  }
  auto groupOfEntry = [&](std::size_t e) {
    return custom ? static_cast<int>((*custom)[e]) : meta_[e].group;
  };

  QueryResult result;
  result.stats.entries = meta_.size();
  std::vector<GroupBest> best(num_groups);
  const std::size_t K = static_cast<std::size_t>(std::max(options.top_k, 2));
  std::vector<int> top;  // group ids, best first, at most K (exhaustive: all)

  auto groupBefore = [&best](int g1, int g2) {
    return betterEntry(best[static_cast<std::size_t>(g1)].score, best[static_cast<std::size_t>(g1)].entry,
                       best[static_cast<std::size_t>(g2)].score, best[static_cast<std::size_t>(g2)].entry);
  };

  if (options.exhaustive) {
    for (std::size_t e = 0; e < meta_.size(); ++e) {
      const SilhouetteEntry en = entry(e);
      const ShiftedIou r = bestShiftIou(mask, en.mask, options.max_dx, options.max_dy);
      ++result.stats.evaluated;
      result.stats.shifts_evaluated += static_cast<std::uint64_t>(2 * options.max_dx + 1) * (2 * options.max_dy + 1);
      if (!(r.score > 0)) continue;
      GroupBest& gb = best[static_cast<std::size_t>(groupOfEntry(e))];
      if (gb.score < 0 || betterEntry(r.score, static_cast<std::uint32_t>(e), gb.score, gb.entry))
        gb = GroupBest{r.score, static_cast<std::uint32_t>(e), r.dx, r.dy};
    }
    for (std::size_t g = 0; g < num_groups; ++g)
      if (best[g].score > 0) top.push_back(static_cast<int>(g));
    std::sort(top.begin(), top.end(), groupBefore);
  } else {
    const QueryPrep q = acc.prepare(mask);
    Scratch scratch;
    auto threshold = [&]() { return top.size() < K ? 0.0 : best[static_cast<std::size_t>(top.back())].score; };
    auto offer = [&](int g, double score, std::uint32_t e, int dx, int dy) {
      GroupBest& gb = best[static_cast<std::size_t>(g)];
      if (gb.score >= 0 && !betterEntry(score, e, gb.score, gb.entry)) return;
      gb = GroupBest{score, e, dx, dy};
      if (std::find(top.begin(), top.end(), g) == top.end()) {
        if (top.size() >= K && !groupBefore(g, top.back())) return;
        top.push_back(g);
      }
      std::sort(top.begin(), top.end(), groupBefore);
      if (top.size() > K) top.pop_back();
    };

    // Visit entries in decreasing order of the area bound min(a, b) / max(a, b): expand from the
    // query's area in the area-sorted index, always taking the side with the larger bound.
    const std::size_t n = by_area_.size();
    std::size_t right = static_cast<std::size_t>(
        std::lower_bound(by_area_.begin(), by_area_.end(), qa,
                         [this](std::uint32_t e, std::int64_t a) { return area_[e] < a; }) -
        by_area_.begin());
    std::ptrdiff_t left = static_cast<std::ptrdiff_t>(right) - 1;
    std::size_t visited = 0;
    while (left >= 0 || right < n) {
      const double bl = left >= 0 ? acc.areaBound(q, by_area_[static_cast<std::size_t>(left)]) : -1.0;
      const double br = right < n ? acc.areaBound(q, by_area_[right]) : -1.0;
      const bool take_right = br >= bl;
      const std::size_t e = take_right ? by_area_[right] : by_area_[static_cast<std::size_t>(left)];
      const double bound = take_right ? br : bl;
      const double t = threshold();
      if (bound < t || bound <= 0) break;  // every remaining entry has a smaller bound
      if (take_right)
        ++right;
      else
        --left;
      ++visited;
      const int g = groupOfEntry(e);
      const double floor = std::max(t, best[static_cast<std::size_t>(g)].score);
      const EntryOutcome o = acc.evaluate(q, e, floor, scratch, result.stats);
      if (o.kind == EntryOutcome::kFound) offer(g, o.score, static_cast<std::uint32_t>(e), o.dx, o.dy);
    }
    result.stats.pruned_area += n - visited;
  }

  const std::size_t k = std::min(top.size(), static_cast<std::size_t>(options.top_k));
  const double s0 = top.empty() ? 0.0 : best[static_cast<std::size_t>(top[0])].score;
  const double s1 = top.size() > 1 ? best[static_cast<std::size_t>(top[1])].score : 0.0;
  for (std::size_t i = 0; i < k; ++i) {
    const GroupBest& gb = best[static_cast<std::size_t>(top[i])];
    const Meta& mt = meta_[gb.entry];
    MatchResult r;
    r.textile_id = mt.textile_id;
    r.hold_point_id = mt.hold_point_id;
    r.view_angle_deg = mt.view_angle_deg;
    r.dx = gb.dx;
    r.dy = gb.dy;
    r.score = gb.score;
    r.margin = gb.score - (i == 0 ? s1 : s0);
    r.entry = gb.entry;
    result.matches.push_back(std::move(r));
  }
  result.margin = s0 - s1;
  return result;
}

// ---------------------------------------------------------------------------------------------
// Multi-image fusion.

FusedQueryResult SilhouetteMatcher::queryFused(const std::vector<FusionImage>& images,
                                               const MatchOptions& options) const {
  validateOptions(options, "SilhouetteMatcher::queryFused");
  if (images.empty()) throw InvalidArgumentError("SilhouetteMatcher::queryFused", "images", "no images");
  MatcherAccess acc(*this, options);
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::string what = "SilhouetteMatcher::queryFused (image " + std::to_string(i) + ")";
    acc.validateQuery(images[i].mask, what.c_str());
    if (images[i].mask.count() == 0) throw InvalidArgumentError(what, "mask", "mask has no foreground pixels");
    if (!std::isfinite(images[i].relative_view_deg)) throw InvalidArgumentError(what, "relative_view_deg", "relative view angle is not finite");
  }
  const std::size_t m = images.size();
  const std::size_t n = meta_.size();
  FusedQueryResult result;
  result.stats.entries = m * n;

  // Distinct stored views of every group, ascending in [0, 360).
  struct View {
    double angle;
    std::vector<std::uint32_t> entries;
  };
  std::vector<std::vector<View>> views(groups_.size());
  for (std::size_t g = 0; g < groups_.size(); ++g) {
    std::vector<std::uint32_t> es = groups_[g].entries;
    std::sort(es.begin(), es.end(), [this](std::uint32_t a, std::uint32_t b) {
      const double x = normaliseAngle(meta_[a].view_angle_deg), y = normaliseAngle(meta_[b].view_angle_deg);
      return x != y ? x < y : a < b;
    });
    for (std::uint32_t e : es) {
      const double a = normaliseAngle(meta_[e].view_angle_deg);
      if (views[g].empty() || std::abs(views[g].back().angle - a) > 1e-9)
        views[g].push_back(View{a, {e}});
      else
        views[g].back().entries.push_back(e);
    }
  }
  auto nearestView = [&views](std::size_t g, double target) {
    const auto& vs = views[g];
    std::size_t best = 0;
    double bd = std::numeric_limits<double>::infinity();
    for (std::size_t v = 0; v < vs.size(); ++v) {
      const double d = circularDistance(vs[v].angle, target);
      if (d < bd - 1e-9) {
        bd = d;
        best = v;
      }
    }
    return best;
  };

  // Per (image, entry) state: 0 = area bound, 1 = projection bound, 2 = exact.
  struct PairState {
    std::uint8_t level = 0;
    double ub = 0;  // upper bound, or the exact score at level 2
    int dx = 0, dy = 0;
  };
  std::vector<PairState> st(m * n);
  std::vector<QueryPrep> preps;
  preps.reserve(m);
  for (std::size_t i = 0; i < m; ++i) preps.push_back(acc.prepare(images[i].mask));
  Scratch scratch;

  auto exactPair = [&](std::size_t i, std::size_t e) {
    PairState& ps = st[i * n + e];
    if (ps.level == 2) return;
    if (options.exhaustive) {
      const SilhouetteEntry en = entry(e);
      const ShiftedIou r = bestShiftIou(images[i].mask, en.mask, options.max_dx, options.max_dy);
      ++result.stats.evaluated;
      result.stats.shifts_evaluated += static_cast<std::uint64_t>(2 * options.max_dx + 1) * (2 * options.max_dy + 1);
      ps = PairState{2, r.score, r.score > 0 ? r.dx : 0, r.score > 0 ? r.dy : 0};
      return;
    }
    EntryOutcome o;
    if (area_[e] == 0) {
      o.kind = EntryOutcome::kAreaPruned;
    } else {
      const int pb = acc.projectionBound(preps[i], e, 0.0, scratch);
      if (pb == 0) {
        o.kind = EntryOutcome::kProjectionPruned;
      } else {
        acc.exactSearch(preps[i], e, 0.0, scratch, o, result.stats);
      }
    }
    if (o.kind == EntryOutcome::kFound)
      ps = PairState{2, o.score, o.dx, o.dy};
    else
      ps = PairState{2, 0.0, 0, 0};
  };
  auto projectionPair = [&](std::size_t i, std::size_t e) {
    PairState& ps = st[i * n + e];
    if (ps.level >= 1) return;
    const int pb = area_[e] == 0 ? 0 : acc.projectionBound(preps[i], e, -1.0, scratch);
    ps.level = 1;
    ps.ub = std::min(ps.ub, iouFromCounts(pb, preps[i].area, area_[e]));
  };
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t e = 0; e < n; ++e) st[i * n + e].ub = acc.areaBound(preps[i], e);

  // Candidates (group, base view) with their nearest views per image.
  struct Candidate {
    int g;
    int v;
    double bound;
    std::vector<int> near;  // view index per image
  };
  std::vector<Candidate> cands;
  for (std::size_t g = 0; g < groups_.size(); ++g)
    for (std::size_t v = 0; v < views[g].size(); ++v) {
      Candidate c{static_cast<int>(g), static_cast<int>(v), 0.0, std::vector<int>(m)};
      for (std::size_t i = 0; i < m; ++i)
        c.near[i] = static_cast<int>(nearestView(g, views[g][v].angle + images[i].relative_view_deg));
      cands.push_back(std::move(c));
    }
  // Fused value of a candidate from the current per-pair values (bounds or exact scores); also the
  // per-image best entries when all are exact.
  auto fusedValue = [&](const Candidate& c, std::vector<std::uint32_t>* pick) {
    double sum = 0;
    for (std::size_t i = 0; i < m; ++i) {
      const View& vw = views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])];
      double bi = -1;
      std::uint32_t be = 0;
      for (std::uint32_t e : vw.entries) {
        const double u = st[i * n + e].ub;
        if (u > bi) {
          bi = u;
          be = e;
        }
      }
      if (pick) (*pick)[i] = be;
      sum += bi;
    }
    return sum / static_cast<double>(m);
  };
  for (auto& c : cands) c.bound = fusedValue(c, nullptr);
  std::vector<std::size_t> order(cands.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&cands](std::size_t a, std::size_t b) { return cands[a].bound > cands[b].bound; });

  // Ranking groups: the member groups themselves, or the caller's coarser groups (group_of_entry). A
  // candidate is always one member group at one base view (the images are compared with that member's
  // views, which keeps what the known relative turn reveals); a coarse group scores its best member.
  std::vector<int> coarse(groups_.size());
  std::size_t num_coarse = groups_.size();
  if (options.group_of_entry) {
    const std::vector<std::uint32_t>& ge = *options.group_of_entry;
    if (ge.size() != n)
      throw InvalidArgumentError("SilhouetteMatcher::queryFused", "group_of_entry", "group_of_entry has " + std::to_string(ge.size()) +
                                  " values for " + std::to_string(n) + " entries");
    num_coarse = 0;
    for (std::size_t g = 0; g < groups_.size(); ++g) {
      const std::uint32_t c0 = ge[groups_[g].entries.front()];
      for (std::uint32_t e : groups_[g].entries)
        if (ge[e] != c0)
          throw InvalidArgumentError(
              "SilhouetteMatcher::queryFused", "group_of_entry", "group_of_entry splits the entries of one (textile, hold point)");
      coarse[g] = static_cast<int>(c0);
      num_coarse = std::max<std::size_t>(num_coarse, static_cast<std::size_t>(c0) + 1);
    }
  } else {
    std::iota(coarse.begin(), coarse.end(), 0);
  }
  struct FusedBest {
    double score = -1;
    int g = 0;  // member group
    int v = 0;
    std::vector<std::uint32_t> pick;
  };
  std::vector<FusedBest> best(num_coarse);
  auto better = [](double s1, int g1, int v1, double s2, int g2, int v2) {
    return s1 > s2 || (s1 == s2 && (g1 < g2 || (g1 == g2 && v1 < v2)));
  };
  auto groupBefore = [&](int c1, int c2) {
    const FusedBest &b1 = best[static_cast<std::size_t>(c1)], &b2 = best[static_cast<std::size_t>(c2)];
    return better(b1.score, b1.g, b1.v, b2.score, b2.g, b2.v);
  };
  const std::size_t K = options.exhaustive ? num_coarse : static_cast<std::size_t>(std::max(options.top_k, 2));
  std::vector<int> top;
  auto threshold = [&]() { return top.size() < K ? 0.0 : best[static_cast<std::size_t>(top.back())].score; };

  for (std::size_t oi : order) {
    Candidate& c = cands[oi];
    const double t = threshold();
    if (!options.exhaustive && (c.bound < t || c.bound <= 0)) break;
    const int cg = coarse[static_cast<std::size_t>(c.g)];
    FusedBest& gb = best[static_cast<std::size_t>(cg)];
    if (!options.exhaustive) {
      const double floor = std::max(t, gb.score);
      if (c.bound < floor) continue;
      for (std::size_t i = 0; i < m; ++i)
        for (std::uint32_t e : views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])].entries)
          projectionPair(i, e);
      if (fusedValue(c, nullptr) < floor) continue;
    }
    for (std::size_t i = 0; i < m; ++i)
      for (std::uint32_t e : views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])].entries)
        exactPair(i, e);
    std::vector<std::uint32_t> pick(m);
    const double f = fusedValue(c, &pick);
    if (!(f > 0)) continue;
    if (gb.score >= 0 && !better(f, c.g, c.v, gb.score, gb.g, gb.v)) continue;
    gb.score = f;
    gb.g = c.g;
    gb.v = c.v;
    gb.pick = pick;
    if (std::find(top.begin(), top.end(), cg) == top.end()) {
      if (top.size() >= K && !groupBefore(cg, top.back())) continue;
      top.push_back(cg);
    }
    std::sort(top.begin(), top.end(), groupBefore);
    if (top.size() > K) top.pop_back();
  }

  // Work counters over (image, entry) pairs.
  for (const PairState& ps : st) {
    if (ps.level == 0) ++result.stats.pruned_area;
    if (ps.level == 1) ++result.stats.pruned_projection;
  }

  const std::size_t k = std::min(top.size(), static_cast<std::size_t>(options.top_k));
  const double s0 = top.empty() ? 0.0 : best[static_cast<std::size_t>(top[0])].score;
  const double s1 = top.size() > 1 ? best[static_cast<std::size_t>(top[1])].score : 0.0;
  for (std::size_t r = 0; r < k; ++r) {
    const FusedBest& gb = best[static_cast<std::size_t>(top[r])];
    const int g = gb.g;
    FusedMatch fm;
    fm.textile_id = groups_[static_cast<std::size_t>(g)].textile_id;
    fm.hold_point_id = groups_[static_cast<std::size_t>(g)].hold_point_id;
    fm.base_view_deg = views[static_cast<std::size_t>(g)][static_cast<std::size_t>(gb.v)].angle;
    fm.score = gb.score;
    fm.margin = gb.score - (r == 0 ? s1 : s0);
    for (std::size_t i = 0; i < m; ++i) {
      const std::uint32_t e = gb.pick[i];
      const PairState& ps = st[i * n + e];
      fm.images.push_back(FusedImageMatch{normaliseAngle(meta_[e].view_angle_deg), e, ps.dx, ps.dy, ps.ub});
    }
    result.matches.push_back(std::move(fm));
  }
  result.margin = s0 - s1;
  return result;
}

}  // namespace vision
}  // namespace textile_handling
