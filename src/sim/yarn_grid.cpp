// Yarns laid inside a textile outline (yarn_grid.h).
#include "textile_handling/sim/yarn_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

namespace {

constexpr std::size_t kNoCrossing = std::numeric_limits<std::size_t>::max();

// Where the line {p[axis] = c} crosses the closed polygon's edges, sorted: consecutive pairs bound
// the runs inside (even-odd rule; a vertex on the line counts once, by the half-open test).
std::vector<Real> lineCrossings(const std::vector<Vec2>& poly, int axis, Real c) {
  const int other = 1 - axis;
  std::vector<Real> t;
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Vec2& a = poly[k];
    const Vec2& b = poly[(k + 1) % poly.size()];
    if ((a[axis] > c) == (b[axis] > c)) continue;
    t.push_back(a[other] + (c - a[axis]) * (b[other] - a[other]) / (b[axis] - a[axis]));
  }
  std::sort(t.begin(), t.end());
  return t;
}

// Number of lines at offsets (k + 1/2) * spacing that fit in a span of `extent`.
std::size_t lineCount(Real extent, Real spacing) {
  return static_cast<std::size_t>(std::max(0.0, std::floor(extent / spacing + 0.5)));
}

}  // namespace

YarnGrid layYarnGrid(const std::vector<Vec2>& outline, const WovenFabric& fabric, const YarnGridOptions& options) {
  std::string error;
  if (!validatePolygon(outline, &error)) throw SimError("yarn grid outline: " + error);
  validateWovenFabric(fabric);
  if (!std::isfinite(options.min_end_segment_fraction) || options.min_end_segment_fraction < 0 ||
      options.min_end_segment_fraction >= 1)
    throw SimError("yarn grid min_end_segment_fraction must be in [0, 1)");
  Vec2 lo = outline.front(), hi = outline.front();
  for (const Vec2& p : outline) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  YarnGrid g;
  g.warp_spacing_m = fabric.warpSpacing();
  g.weft_spacing_m = fabric.weftSpacing();
  // Checked in floating point before any allocation: a huge outline or density cannot overflow here.
  const double lines_warp = std::floor((hi.y() - lo.y()) / g.warp_spacing_m + 0.5);
  const double lines_weft = std::floor((hi.x() - lo.x()) / g.weft_spacing_m + 0.5);
  if (lines_warp * lines_weft > static_cast<double>(kMaxYarnCrossings))
    throw SimError("yarn grid of " + std::to_string(static_cast<long long>(lines_warp)) + " warp x " +
                   std::to_string(static_cast<long long>(lines_weft)) + " weft lines (outline " +
                   std::to_string(hi.x() - lo.x()) + " x " + std::to_string(hi.y() - lo.y()) +
                   " m) would have more than " + std::to_string(kMaxYarnCrossings) + " crossings");
  g.warp_lines = lineCount(hi.y() - lo.y(), g.warp_spacing_m);
  g.weft_lines = lineCount(hi.x() - lo.x(), g.weft_spacing_m);
  auto warpY = [&](std::size_t i) { return lo.y() + (static_cast<Real>(i) + 0.5) * g.warp_spacing_m; };
  auto weftX = [&](std::size_t j) { return lo.x() + (static_cast<Real>(j) + 0.5) * g.weft_spacing_m; };

  // Crossings and warp pieces, line by line; `at` maps (warp, weft) to the crossing's index.
  std::vector<std::size_t> at(g.warp_lines * g.weft_lines, kNoCrossing);
  const Real min_end_warp = options.min_end_segment_fraction * g.weft_spacing_m;  // along a warp: weft spacing
  const Real min_end_weft = options.min_end_segment_fraction * g.warp_spacing_m;
  struct Run {
    Real from, to;
    std::vector<std::size_t> crossings;
  };
  std::vector<std::vector<Run>> warp_runs(g.warp_lines);
  for (std::size_t i = 0; i < g.warp_lines; ++i) {
    const Real y = warpY(i);
    const std::vector<Real> xs = lineCrossings(outline, 1, y);
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
      Run run{xs[k], xs[k + 1], {}};
      // The first weft line right of the run's start (the run lies within the bounding box).
      const std::size_t j0 = static_cast<std::size_t>(std::max<Real>(0, std::ceil((run.from - lo.x()) / g.weft_spacing_m - 0.5)));
      for (std::size_t j = j0; j < g.weft_lines; ++j) {
        const Real x = weftX(j);
        if (x <= run.from) continue;
        if (x >= run.to) break;
        at[i * g.weft_lines + j] = g.crossings.size();
        run.crossings.push_back(g.crossings.size());
        g.crossings.push_back({Vec2(x, y), i, j, fabric.weave.warpOnTop(i, j)});
      }
      if (!run.crossings.empty()) warp_runs[i].push_back(std::move(run));
    }
  }
  // A piece: its crossings in order, with an end node at either side unless too close.
  auto addPiece = [&](bool warp, std::size_t line, Real from, Real to, const std::vector<std::size_t>& xs, Real min_end) {
    YarnPiece p;
    p.warp = warp;
    p.line = line;
    const int axis = warp ? 0 : 1;
    const Real c = warp ? warpY(line) : weftX(line);
    auto addEnd = [&](Real s) {
      p.nodes.push_back(g.crossings.size() + g.ends.size());
      p.arc_length_m.push_back(s);
      g.ends.push_back(warp ? Vec2(s, c) : Vec2(c, s));
    };
    const Real first = g.crossings[xs.front()].position[axis], last = g.crossings[xs.back()].position[axis];
    if (first - from >= min_end) addEnd(from);
    for (std::size_t x : xs) {
      p.nodes.push_back(x);
      p.arc_length_m.push_back(g.crossings[x].position[axis]);
    }
    if (to - last >= min_end) addEnd(to);
    g.pieces.push_back(std::move(p));
  };
  // End nodes are numbered after every crossing, so pieces are made once all crossings exist.
  for (std::size_t i = 0; i < g.warp_lines; ++i)
    for (const Run& r : warp_runs[i]) addPiece(true, i, r.from, r.to, r.crossings, min_end_warp);
  for (std::size_t j = 0; j < g.weft_lines; ++j) {
    const Real x = weftX(j);
    const std::vector<Real> ys = lineCrossings(outline, 0, x);
    for (std::size_t k = 0; k + 1 < ys.size(); k += 2) {
      std::vector<std::size_t> xs;
      for (std::size_t i = 0; i < g.warp_lines; ++i) {
        const std::size_t c = at[i * g.weft_lines + j];
        if (c == kNoCrossing) continue;
        const Real y = g.crossings[c].position.y();
        if (y > ys[k] && y < ys[k + 1]) xs.push_back(c);
      }
      if (!xs.empty()) addPiece(false, j, ys[k], ys[k + 1], xs, min_end_weft);
    }
  }
  return g;
}

WeaveSegmentCounts countWeaveSegments(const YarnGrid& grid) {
  WeaveSegmentCounts n;
  for (const YarnPiece& p : grid.pieces)
    for (std::size_t k = 0; k + 1 < p.nodes.size(); ++k) {
      if (grid.isEnd(p.nodes[k]) || grid.isEnd(p.nodes[k + 1])) continue;
      const bool a = grid.crossings[p.nodes[k]].warp_on_top, b = grid.crossings[p.nodes[k + 1]].warp_on_top;
      ++(a != b ? n.interlaced : n.floats);
    }
  return n;
}

}  // namespace textile_handling
