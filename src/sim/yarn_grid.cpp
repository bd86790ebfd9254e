// Yarns laid inside a textile outline (yarn_grid.h).
#include "textile_handling/sim/yarn_grid.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

namespace {

constexpr std::size_t kNoCrossing = std::numeric_limits<std::size_t>::max();

// One point where a grid line meets the polygon: its coordinate along the line and the edge it lies on.
struct EdgeHit {
  Real t;
  std::size_t edge;
};

// Where the line {p[axis] = c} crosses the closed polygon's edges, sorted along it: consecutive pairs
// bound the runs inside (even-odd rule; a vertex on the line counts once, by the half-open test).
std::vector<EdgeHit> lineCrossings(const std::vector<Vec2>& poly, int axis, Real c) {
  const int other = 1 - axis;
  std::vector<EdgeHit> t;
  for (std::size_t k = 0; k < poly.size(); ++k) {
    const Vec2& a = poly[k];
    const Vec2& b = poly[(k + 1) % poly.size()];
    if ((a[axis] > c) == (b[axis] > c)) continue;
    t.push_back({a[other] + (c - a[axis]) * (b[other] - a[other]) / (b[axis] - a[axis]), k});
  }
  std::sort(t.begin(), t.end(), [](const EdgeHit& x, const EdgeHit& y) { return x.t < y.t; });
  return t;
}

// Number of lines at offsets (k + 1/2) * spacing that fit in a span of `extent`.
std::size_t lineCount(Real extent, Real spacing) {
  return static_cast<std::size_t>(std::max(0.0, std::floor(extent / spacing + 0.5)));
}

// Throws SimError naming the first bad option of layYarnGrid() for an outline of `edges` edges.
void validateGridOptions(const YarnGridOptions& options, std::size_t edges) {
  if (!std::isfinite(options.min_end_segment_fraction) || options.min_end_segment_fraction < 0 ||
      options.min_end_segment_fraction >= 1)
    throw SimError("yarn grid min_end_segment_fraction must be in [0, 1)");
  std::vector<std::size_t> first(edges, edges);  // per edge: where seam_edges names it first
  for (std::size_t k = 0; k < options.seam_edges.size(); ++k) {
    const std::size_t e = options.seam_edges[k];
    const std::string name = "yarn grid seam_edges[" + std::to_string(k) + "] = " + std::to_string(e);
    if (e >= edges)
      throw SimError(name + ": the outline has " + std::to_string(edges) + " edges (0 to " + std::to_string(edges - 1) + ")");
    if (first[e] != edges) throw SimError(name + " repeats seam_edges[" + std::to_string(first[e]) + "]");
    first[e] = k;
  }
}

// Where a yarn end lies: the outline edge and whether it ends a warp (else a weft) piece.
struct EndSite {
  std::size_t edge;
  bool warp;
};

// Appends a seam piece to g for every seam edge with two or more ends on it (`sites`: per end of g).
// The seam's arc length is the distance from the edge's first vertex; it is stored in the coordinate
// the end's own yarn leaves unused (a warp end's v, a weft end's u). An end less than `min_gap` along
// the edge from the previous sewn one is skipped: a shorter seam segment would be the sheet's stiffest
// spring, and coincident ends none at all.
void addSeams(const std::vector<Vec2>& outline, const std::vector<std::size_t>& seam_edges,
              const std::vector<EndSite>& sites, Real min_gap, YarnGrid* g) {
  for (std::size_t edge : seam_edges) {
    const Vec2 a = outline[edge], b = outline[(edge + 1) % outline.size()];
    const Vec2 along = (b - a).normalized();
    std::vector<std::pair<Real, std::size_t>> on_edge;  // (arc length, end index)
    for (std::size_t e = 0; e < sites.size(); ++e)
      if (sites[e].edge == edge) on_edge.emplace_back((g->ends[e] - a).dot(along), e);
    std::sort(on_edge.begin(), on_edge.end());
    YarnPiece p;
    p.seam = true;
    p.warp = false;
    p.line = edge;
    for (const auto& [s, e] : on_edge) {
      if (!p.nodes.empty() && !(s - p.arc_length_m.back() > min_gap)) continue;
      p.nodes.push_back(g->crossings.size() + e);
      p.arc_length_m.push_back(s);
      p.slide_offsets.push_back(sites[e].warp ? 4 : 3);
    }
    if (p.nodes.size() >= 2) g->pieces.push_back(std::move(p));
  }
}

}  // namespace

YarnGrid layYarnGrid(const std::vector<Vec2>& outline, const WovenFabric& fabric, const YarnGridOptions& options) {
  std::string error;
  if (!validatePolygon(outline, &error)) throw SimError("yarn grid outline: " + error);
  validateWovenFabric(fabric);
  validateGridOptions(options, outline.size());
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
    EdgeHit from, to;
    std::vector<std::size_t> crossings;
  };
  std::vector<std::vector<Run>> warp_runs(g.warp_lines);
  for (std::size_t i = 0; i < g.warp_lines; ++i) {
    const Real y = warpY(i);
    const std::vector<EdgeHit> xs = lineCrossings(outline, 1, y);
    for (std::size_t k = 0; k + 1 < xs.size(); k += 2) {
      Run run{xs[k], xs[k + 1], {}};
      // The first weft line right of the run's start (the run lies within the bounding box).
      const std::size_t j0 = static_cast<std::size_t>(std::max<Real>(0, std::ceil((run.from.t - lo.x()) / g.weft_spacing_m - 0.5)));
      for (std::size_t j = j0; j < g.weft_lines; ++j) {
        const Real x = weftX(j);
        if (x <= run.from.t) continue;
        if (x >= run.to.t) break;
        at[i * g.weft_lines + j] = g.crossings.size();
        run.crossings.push_back(g.crossings.size());
        g.crossings.push_back({Vec2(x, y), i, j, fabric.weave.warpOnTop(i, j)});
      }
      if (!run.crossings.empty()) warp_runs[i].push_back(std::move(run));
    }
  }
  // A piece: its crossings in order, with an end node at either side unless too close.
  std::vector<EndSite> sites;  // per end node
  auto addPiece = [&](bool warp, std::size_t line, const EdgeHit& from, const EdgeHit& to,
                      const std::vector<std::size_t>& xs, Real min_end) {
    YarnPiece p;
    p.warp = warp;
    p.line = line;
    const int axis = warp ? 0 : 1;
    const Real c = warp ? warpY(line) : weftX(line);
    auto addEnd = [&](const EdgeHit& hit) {
      p.nodes.push_back(g.crossings.size() + g.ends.size());
      p.arc_length_m.push_back(hit.t);
      g.ends.push_back(warp ? Vec2(hit.t, c) : Vec2(c, hit.t));
      sites.push_back({hit.edge, warp});
    };
    const Real first = g.crossings[xs.front()].position[axis], last = g.crossings[xs.back()].position[axis];
    if (first - from.t >= min_end) addEnd(from);
    for (std::size_t x : xs) {
      p.nodes.push_back(x);
      p.arc_length_m.push_back(g.crossings[x].position[axis]);
    }
    if (to.t - last >= min_end) addEnd(to);
    g.pieces.push_back(std::move(p));
  };
  // End nodes are numbered after every crossing, so pieces are made once all crossings exist.
  for (std::size_t i = 0; i < g.warp_lines; ++i)
    for (const Run& r : warp_runs[i]) addPiece(true, i, r.from, r.to, r.crossings, min_end_warp);
  for (std::size_t j = 0; j < g.weft_lines; ++j) {
    const Real x = weftX(j);
    const std::vector<EdgeHit> ys = lineCrossings(outline, 0, x);
    for (std::size_t k = 0; k + 1 < ys.size(); k += 2) {
      std::vector<std::size_t> xs;
      for (std::size_t i = 0; i < g.warp_lines; ++i) {
        const std::size_t c = at[i * g.weft_lines + j];
        if (c == kNoCrossing) continue;
        const Real y = g.crossings[c].position.y();
        if (y > ys[k].t && y < ys[k + 1].t) xs.push_back(c);
      }
      if (!xs.empty()) addPiece(false, j, ys[k], ys[k + 1], xs, min_end_weft);
    }
  }
  addSeams(outline, options.seam_edges, sites,
           options.min_end_segment_fraction * std::min(g.warp_spacing_m, g.weft_spacing_m), &g);
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
