// Per-query machinery of the silhouette matcher shared by the single-image query and the fusion of
// several images (private to src/vision): the query preparation, the per-entry bounds (area,
// row / column projections) and the exact search of one entry, with access to the packed store of
// SilhouetteMatcher (MatcherAccess is its friend), and the option check and ranking of both queries.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "textile_handling/vision/silhouette_matcher.h"
#include "silhouette_shift_search.h"

namespace textile_handling {
namespace vision {
namespace matcher_detail {

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

}  // namespace matcher_detail

// Friend of SilhouetteMatcher: the search machinery that needs the packed store.
struct MatcherAccess {
  using QueryPrep = matcher_detail::QueryPrep;
  using Scratch = matcher_detail::Scratch;
  using EntryOutcome = matcher_detail::EntryOutcome;

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
    const int r0 = by0 & ~7, r1 = matcher_detail::roundUp8(by1);
    int rmax = 0;
    for (int dy = -Dy; dy <= Dy; ++dy) {
      const int v = matcher_detail::sumMin16(rb + r0, q.rowpad.data() + q.roff + r0 + dy, r1 - r0);
      s.rbound[static_cast<std::size_t>(dy + Dy)] = v;
      rmax = std::max(rmax, v);
    }
    if (rmax == 0 || iouFromCounts(rmax, q.area, b) < floor) return rmax;
    int cmax = 0;
    if (m.bytes_) {
      const std::uint8_t* cb = &m.col_counts8_[e * static_cast<std::size_t>(m.cols_padded16_)];
      const int c0 = bx0 & ~15, c1 = matcher_detail::roundUp16(bx1);
      for (int dx = -Dx; dx <= Dx; ++dx) {
        const int v = matcher_detail::sumMin8(cb + c0, q.colpad8.data() + q.coff8 + c0 + dx, c1 - c0);
        s.cbound[static_cast<std::size_t>(dx + Dx)] = v;
        cmax = std::max(cmax, v);
      }
    } else {
      const std::int16_t* cb = &m.col_counts_[e * static_cast<std::size_t>(m.cols_padded_)];
      const int c0 = bx0 & ~7, c1 = matcher_detail::roundUp8(bx1);
      for (int dx = -Dx; dx <= Dx; ++dx) {
        const int v = matcher_detail::sumMin16(cb + c0, q.colpad.data() + q.coff + c0 + dx, c1 - c0);
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
    matcher_detail::ShiftSearch ss;
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
    matcher_detail::runShiftSearch(ss);
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

namespace matcher_detail {

// Best entry of one aggregation group so far.
struct GroupBest {
  double score = -1;  // < 0: none yet
  std::uint32_t entry = 0;
  int dx = 0, dy = 0;
};

// Ranking of results: higher score first, ties to the smaller entry index.
inline bool betterEntry(double s1, std::uint32_t e1, double s2, std::uint32_t e2) {
  return s1 > s2 || (s1 == s2 && e1 < e2);
}

inline void validateOptions(const MatchOptions& o, const char* what) {
  if (o.max_dx < 0 || o.max_dy < 0)
    throw InvalidArgumentError(what, "max_dx/max_dy", "max_dx and max_dy must be >= 0");
  if (o.top_k < 1) throw InvalidArgumentError(what, "top_k", "top_k must be >= 1");
}

}  // namespace matcher_detail
}  // namespace vision
}  // namespace textile_handling
