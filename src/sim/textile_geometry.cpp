// Flat textile outlines, validation and particle-grid rasterisation.
// See textile_geometry.h for the contracts; all lengths in metres.
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace textile_handling {

namespace {

// Two points closer than this [m] count as coincident, and a point closer than
// this to a segment counts as touching it. Far below any textile feature, far
// above double rounding noise for metre-scale coordinates.
constexpr Real kLengthTol = 1e-12;
// Smallest accepted |area| [m^2].
constexpr Real kMinArea = 1e-12;
// A half-outline vertex this close [m] to the mirror axis counts as on it.
constexpr Real kAxisTol = 1e-9;
// Grid sizes are floor(extent/d + kIndexTol) so that an extent that is an exact
// multiple of d (up to rounding) yields the node on the far edge.
constexpr Real kIndexTol = 1e-9;
// Guards against absurd allocations from a tiny spacing.
constexpr double kMaxGridNodes = 1e8;
constexpr double kMaxHoldPoints = 1e7;

Real cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

std::string formatReal(Real v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

std::string formatPoint(const Vec2& p) { return "(" + formatReal(p.x()) + ", " + formatReal(p.y()) + ")"; }

// "i-j" name of edge i of an n-gon (from vertex i to vertex (i+1) mod n).
std::string edgeName(std::size_t i, std::size_t n) {
  return std::to_string(i) + "-" + std::to_string((i + 1) % n);
}

void setError(std::string* error, const std::string& message) {
  if (error != nullptr) *error = message;
}

// "textile 'NAME': " with the name cut to the allowed length (the name may not be validated yet).
std::string textilePrefix(const TextileOutline& textile) {
  const std::string& name = textile.name;
  return "textile '" + (name.size() > kMaxTextileNameLength ? name.substr(0, kMaxTextileNameLength) + "..." : name) +
         "': ";
}

// The outline size limit, checked before any work that grows with the outline.
bool checkOutlineSize(const TextileOutline& textile, std::string* error) {
  if (textile.outline.size() <= kMaxOutlineVertices) return true;
  setError(error, textilePrefix(textile) + "outline has " + std::to_string(textile.outline.size()) +
                      " vertices, more than the limit of " + std::to_string(kMaxOutlineVertices));
  return false;
}

// Closed segments a-b and c-d intersect or come within `tol` of each other at
// an endpoint. The endpoint distance tests catch touching and collinear
// overlaps; the strict orientation test catches proper crossings.
bool segmentsIntersect(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d, Real tol) {
  if (pointSegmentDistance(a, c, d) <= tol || pointSegmentDistance(b, c, d) <= tol ||
      pointSegmentDistance(c, a, b) <= tol || pointSegmentDistance(d, a, b) <= tol) {
    return true;
  }
  const Real o1 = cross2(b - a, c - a);
  const Real o2 = cross2(b - a, d - a);
  const Real o3 = cross2(d - c, a - c);
  const Real o4 = cross2(d - c, b - c);
  const bool ab_separates = (o1 > 0 && o2 < 0) || (o1 < 0 && o2 > 0);
  const bool cd_separates = (o3 > 0 && o4 < 0) || (o3 < 0 && o4 > 0);
  return ab_separates && cd_separates;
}

struct BoundingBox {
  Vec2 min;
  Vec2 max;
};

BoundingBox boundingBox(const std::vector<Vec2>& points) {
  BoundingBox box{points.front(), points.front()};
  for (const Vec2& p : points) {
    box.min = box.min.cwiseMin(p);
    box.max = box.max.cwiseMax(p);
  }
  return box;
}

// Lattice line coordinates lo + k*s covering [lo, hi]; see holdPointLattice()
// for how a remainder that is not a multiple of s is handled.
std::vector<Real> latticeLines(Real lo, Real hi, Real s) {
  const Real extent = hi - lo;
  const auto count = static_cast<std::int64_t>(std::floor(extent / s + kIndexTol));
  std::vector<Real> lines;
  lines.reserve(static_cast<std::size_t>(count) + 2);
  for (std::int64_t k = 0; k <= count; ++k) lines.push_back(lo + static_cast<Real>(k) * s);
  const Real remainder = hi - lines.back();
  if (remainder > 0.25 * s) {
    lines.push_back(hi);
  } else if (count > 0) {
    lines.back() = hi;  // exact far edge; absorbs rounding noise or a small remainder
  }
  return lines;
}

// pointInPolygon() for the points of one horizontal line y = const (a grid row), with the same
// arithmetic on the same edges in the same roles, so the answers are identical; only edges that can
// matter at that height are tested. That keeps rasterisation O(rows * n + nodes * k) for an n-gon
// instead of O(nodes * n), k being the few edges that cross or touch a row.
class RowClassifier {
 public:
  RowClassifier(const std::vector<Vec2>& polygon, Real y, Real tolerance) : polygon_(polygon), tolerance_(tolerance) {
    const std::size_t n = polygon.size();
    // An edge whose y-range is farther from the row than this cannot be within `tolerance` of a row
    // point, even after rounding (1 nm dwarfs double rounding of metre-scale coordinates).
    const Real reach = 2 * tolerance + 1e-9;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2& a = polygon[i];
      const Vec2& b = polygon[(i + 1) % n];
      if (std::min(a.y(), b.y()) - reach <= y && y <= std::max(a.y(), b.y()) + reach) near_.push_back(i);
    }
    for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
      if ((polygon[j].y() > y) != (polygon[i].y() > y)) crossing_.emplace_back(j, i);
    }
  }

  bool inside(const Vec2& p) const {
    const std::size_t n = polygon_.size();
    if (n < 3) return false;
    for (const std::size_t i : near_) {
      if (pointSegmentDistance(p, polygon_[i], polygon_[(i + 1) % n]) <= tolerance_) return true;
    }
    bool inside = false;
    for (const auto& [j, i] : crossing_) {
      const Vec2& a = polygon_[j];
      const Vec2& b = polygon_[i];
      const Real x_cross = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (p.x() < x_cross) inside = !inside;
    }
    return inside;
  }

 private:
  const std::vector<Vec2>& polygon_;
  Real tolerance_;
  std::vector<std::size_t> near_;                            // boundary candidates: edge i runs i -> i+1
  std::vector<std::pair<std::size_t, std::size_t>> crossing_;  // (j, i): edges from vertex j to i crossing y
};

// Accepts points unless they lie within `radius` of an already accepted point.
// A hash of square cells with side `radius` keeps this O(1) per point.
class PointDeduplicator {
 public:
  explicit PointDeduplicator(Real radius) : radius_(radius) {}

  bool add(const Vec2& p) {
    const std::int64_t cx = cell(p.x());
    const std::int64_t cy = cell(p.y());
    for (std::int64_t dx = -1; dx <= 1; ++dx) {
      for (std::int64_t dy = -1; dy <= 1; ++dy) {
        const auto it = cells_.find({cx + dx, cy + dy});
        if (it == cells_.end()) continue;
        for (std::size_t k : it->second) {
          if ((points_[k] - p).norm() < radius_) return false;
        }
      }
    }
    cells_[{cx, cy}].push_back(points_.size());
    points_.push_back(p);
    return true;
  }

  const std::vector<Vec2>& points() const { return points_; }

 private:
  std::int64_t cell(Real v) const { return static_cast<std::int64_t>(std::floor(v / radius_)); }

  Real radius_;
  std::vector<Vec2> points_;
  std::map<std::pair<std::int64_t, std::int64_t>, std::vector<std::size_t>> cells_;
};

NamedPoint namedPoint(const std::string& name, const std::string& kind, Real x, Real y) {
  NamedPoint p;
  p.name = name;
  p.kind = kind;
  p.position = Vec2(x, y);
  return p;
}

// Rectangle [0, w] x [0, h] (counter-clockwise from the origin) with its four
// corners named corner_ll, corner_lr, corner_ul, corner_ur.
TextileOutline rectangleTextile(const std::string& name, Real w, Real h) {
  TextileOutline t;
  t.name = name;
  t.outline = {Vec2(0, 0), Vec2(w, 0), Vec2(w, h), Vec2(0, h)};
  t.named_points = {namedPoint("corner_ll", "corner", 0, 0), namedPoint("corner_lr", "corner", w, 0),
                    namedPoint("corner_ul", "corner", 0, h), namedPoint("corner_ur", "corner", w, h)};
  return t;
}

TextileOutline tshirtTextile() {
  TextileOutline t;
  t.name = "tshirt";
  t.mirrored = true;
  t.mirror_x = 0;
  // Right half, counter-clockwise from the hem middle up to the front neck
  // middle. Body half width 0.25 m, shoulder top 0.70 m above the hem; the
  // sleeve top edge (shoulder -> cuff top) is about 0.20 m long and the cuff
  // about 0.14 m wide; the neck opening is 0.18 m wide and 0.08 m deep.
  t.outline = {
      Vec2(0.00, 0.00),  // hem middle (on the axis)
      Vec2(0.25, 0.00),  // hem corner
      Vec2(0.25, 0.50),  // armpit
      Vec2(0.31, 0.44),  // cuff, under-sleeve end
      Vec2(0.38, 0.56),  // cuff, top-sleeve end
      Vec2(0.21, 0.67),  // shoulder point
      Vec2(0.09, 0.70),  // neck side (highest point)
      Vec2(0.08, 0.67),  // neckline curve
      Vec2(0.05, 0.64),  // neckline curve
      Vec2(0.00, 0.62),  // front neck middle (on the axis)
  };
  t.named_points = {
      namedPoint("hem_corner_left", "corner", -0.25, 0.00),
      namedPoint("hem_corner_right", "corner", 0.25, 0.00),
      namedPoint("sleeve_end_left", "grasp", -0.345, 0.50),  // cuff middle
      namedPoint("sleeve_end_right", "grasp", 0.345, 0.50),
      namedPoint("shoulder_left", "grasp", -0.21, 0.67),
      namedPoint("shoulder_right", "grasp", 0.21, 0.67),
      namedPoint("collar", "grasp", 0.00, 0.62),
  };
  return t;
}

}  // namespace

Real polygonSignedArea(const std::vector<Vec2>& vertices) {
  const std::size_t n = vertices.size();
  if (n < 3) return 0;
  Real twice_area = 0;
  for (std::size_t i = 0; i < n; ++i) twice_area += cross2(vertices[i], vertices[(i + 1) % n]);
  return 0.5 * twice_area;
}

Real pointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const Real len2 = ab.squaredNorm();
  if (len2 <= 0) return (p - a).norm();
  const Real t = std::clamp((p - a).dot(ab) / len2, Real(0), Real(1));
  return (p - (a + t * ab)).norm();
}

bool pointInPolygon(const std::vector<Vec2>& polygon, const Vec2& p, Real boundary_tolerance) {
  const std::size_t n = polygon.size();
  if (n < 3) return false;
  // Boundary first: the crossing test below is unreliable for points on edges.
  for (std::size_t i = 0; i < n; ++i) {
    if (pointSegmentDistance(p, polygon[i], polygon[(i + 1) % n]) <= boundary_tolerance) return true;
  }
  // Even-odd ray casting towards +x with the half-open rule on y, so a ray
  // through a vertex is counted exactly once.
  bool inside = false;
  for (std::size_t i = 0, j = n - 1; i < n; j = i++) {
    const Vec2& a = polygon[j];
    const Vec2& b = polygon[i];
    if ((a.y() > p.y()) != (b.y() > p.y())) {
      const Real x_cross = a.x() + (p.y() - a.y()) * (b.x() - a.x()) / (b.y() - a.y());
      if (p.x() < x_cross) inside = !inside;
    }
  }
  return inside;
}

bool validateTextileName(const std::string& name, std::string* error) {
  // Quote at most the allowed length: a hostile name may be megabytes long.
  const std::string shown = name.size() > kMaxTextileNameLength ? name.substr(0, kMaxTextileNameLength) + "..." : name;
  if (name.empty()) {
    setError(error, "name is empty (1-" + std::to_string(kMaxTextileNameLength) + " characters required)");
    return false;
  }
  if (name.size() > kMaxTextileNameLength) {
    setError(error, "name '" + shown + "' has " + std::to_string(name.size()) + " characters, more than the limit of " +
                        std::to_string(kMaxTextileNameLength));
    return false;
  }
  for (const char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
                    c == '-' || c == '.';
    if (!ok) {
      setError(error, "name '" + shown + "' may only contain letters, digits, '_', '-' and '.'");
      return false;
    }
  }
  if (error != nullptr) error->clear();
  return true;
}

bool findEdgeCrossingBruteForce(const std::vector<Vec2>& vertices, std::size_t* first, std::size_t* second) {
  const std::size_t n = vertices.size();
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = i + 2; k < n; ++k) {
      if (i == 0 && k == n - 1) continue;  // adjacent through the closing edge
      if (segmentsIntersect(vertices[i], vertices[(i + 1) % n], vertices[k], vertices[(k + 1) % n], kLengthTol)) {
        *first = i;
        *second = k;
        return true;
      }
    }
  }
  return false;
}

bool findEdgeCrossing(const std::vector<Vec2>& vertices, std::size_t* first, std::size_t* second) {
  const std::size_t n = vertices.size();
  if (n < 4) return false;  // every pair of edges of a triangle is adjacent
  // Sweep over the edges' bounding boxes (grown by the touching tolerance) in order of their left
  // ends; only pairs whose boxes overlap are tested. Every candidate is tested (no early exit) so
  // that the reported pair is the lowest one, as the brute force reports it.
  struct Box {
    Real x0, x1, y0, y1;
  };
  std::vector<Box> boxes(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2& a = vertices[i];
    const Vec2& b = vertices[(i + 1) % n];
    boxes[i] = {std::min(a.x(), b.x()) - kLengthTol, std::max(a.x(), b.x()) + kLengthTol,
                std::min(a.y(), b.y()) - kLengthTol, std::max(a.y(), b.y()) + kLengthTol};
  }
  std::vector<std::size_t> order(n);
  for (std::size_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return boxes[a].x0 < boxes[b].x0 || (boxes[a].x0 == boxes[b].x0 && a < b);
  });
  const auto adjacent = [n](std::size_t a, std::size_t b) {
    const std::size_t d = a > b ? a - b : b - a;
    return d == 1 || d == n - 1;
  };
  bool found = false;
  std::pair<std::size_t, std::size_t> best(n, n);
  std::vector<std::size_t> active;
  for (const std::size_t e : order) {
    const Box& be = boxes[e];
    std::size_t kept = 0;
    for (const std::size_t o : active) {
      const Box& bo = boxes[o];
      if (bo.x1 < be.x0) continue;  // ends left of every later box: leaves the sweep
      active[kept++] = o;
      if (bo.y1 < be.y0 || be.y1 < bo.y0 || adjacent(e, o)) continue;
      const std::pair<std::size_t, std::size_t> pair(std::min(e, o), std::max(e, o));
      if (found && !(pair < best)) continue;
      if (segmentsIntersect(vertices[pair.first], vertices[(pair.first + 1) % n], vertices[pair.second],
                            vertices[(pair.second + 1) % n], kLengthTol)) {
        found = true;
        best = pair;
      }
    }
    active.resize(kept);
    active.push_back(e);
  }
  if (found) {
    *first = best.first;
    *second = best.second;
  }
  return found;
}

bool validatePolygon(const std::vector<Vec2>& vertices, std::string* error) {
  const std::size_t n = vertices.size();
  if (n > kMaxPolygonVertices) {
    setError(error, "polygon has " + std::to_string(n) + " vertices, more than the limit of " +
                        std::to_string(kMaxPolygonVertices));
    return false;
  }
  if (n < 3) {
    setError(error, "polygon has " + std::to_string(n) + " vertices; at least 3 are required");
    return false;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!vertices[i].allFinite()) {
      setError(error, "polygon vertex " + std::to_string(i) + " is not finite: " + formatPoint(vertices[i]));
      return false;
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = (i + 1) % n;
    if ((vertices[i] - vertices[k]).norm() <= kLengthTol) {
      setError(error, "polygon vertices " + std::to_string(i) + " and " + std::to_string(k) + " coincide at " +
                          formatPoint(vertices[i]) + " (repeated vertex)");
      return false;
    }
  }

  // All-collinear loops fold back on themselves too; report the root cause.
  std::size_t far = 1;
  for (std::size_t i = 2; i < n; ++i) {
    if ((vertices[i] - vertices[0]).squaredNorm() > (vertices[far] - vertices[0]).squaredNorm()) far = i;
  }
  const Vec2 axis = (vertices[far] - vertices[0]).normalized();
  Real max_offset = 0;
  for (const Vec2& v : vertices) max_offset = std::max(max_offset, std::abs(cross2(axis, v - vertices[0])));
  if (max_offset <= kLengthTol) {
    setError(error, "polygon is degenerate: all " + std::to_string(n) + " vertices are collinear (zero area)");
    return false;
  }

  // Adjacent edges share a vertex, so they only intersect improperly when one
  // doubles back along the other.
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t prev = (i + n - 1) % n;
    const std::size_t next = (i + 1) % n;
    if (pointSegmentDistance(vertices[next], vertices[prev], vertices[i]) <= kLengthTol ||
        pointSegmentDistance(vertices[prev], vertices[i], vertices[next]) <= kLengthTol) {
      setError(error, "polygon edges " + edgeName(prev, n) + " and " + edgeName(i, n) +
                          " overlap (the outline doubles back at vertex " + std::to_string(i) + ")");
      return false;
    }
  }

  std::size_t first = 0, second = 0;
  if (findEdgeCrossing(vertices, &first, &second)) {
    setError(error, "polygon edge " + edgeName(first, n) + " crosses edge " + edgeName(second, n) +
                        " (self-intersection)");
    return false;
  }

  const Real area = polygonSignedArea(vertices);
  if (std::abs(area) < kMinArea) {
    setError(error, "polygon area " + formatReal(std::abs(area)) + " m^2 is below the minimum " +
                        formatReal(kMinArea) + " m^2 (degenerate polygon)");
    return false;
  }
  if (error != nullptr) error->clear();
  return true;
}

bool buildFullOutline(const TextileOutline& textile, std::vector<Vec2>* full, std::string* error) {
  const std::string prefix = textilePrefix(textile);
  if (!checkOutlineSize(textile, error)) return false;
  std::string reason;
  if (!textile.mirrored) {
    if (!validatePolygon(textile.outline, &reason)) {
      setError(error, prefix + reason);
      return false;
    }
    if (full != nullptr) *full = textile.outline;
    if (error != nullptr) error->clear();
    return true;
  }

  const Real m = textile.mirror_x;
  if (!std::isfinite(m)) {
    setError(error, prefix + "mirror_x is not finite (" + formatReal(m) + ")");
    return false;
  }
  const std::vector<Vec2>& half = textile.outline;
  const std::size_t n = half.size();
  bool all_finite = true;
  for (const Vec2& v : half) all_finite = all_finite && v.allFinite();
  // Axis checks come before the general polygon checks because they give the
  // more specific reason (a vertex on the axis also makes the half non-simple).
  if (n >= 3 && all_finite) {
    const std::string axis = "the mirror axis x = " + formatReal(m);
    if (std::abs(half.front().x() - m) > kAxisTol || std::abs(half.back().x() - m) > kAxisTol) {
      setError(error, prefix + "a mirrored half outline must start and end on " + axis +
                          ", but its first vertex is " + formatPoint(half.front()) + " and its last vertex is " +
                          formatPoint(half.back()));
      return false;
    }
    for (std::size_t i = 1; i + 1 < n; ++i) {
      if (half[i].x() < m - kAxisTol) {
        setError(error, prefix + "half outline vertex " + std::to_string(i) + " " + formatPoint(half[i]) +
                            " lies on the wrong side of " + axis + " (must be x >= mirror_x)");
        return false;
      }
      if (half[i].x() <= m + kAxisTol) {
        setError(error, prefix + "half outline vertex " + std::to_string(i) + " " + formatPoint(half[i]) +
                            " lies on " + axis + "; only the first and last vertices may");
        return false;
      }
    }
  }
  // The half outline, closed along the axis, must itself be a simple polygon.
  if (!validatePolygon(half, &reason)) {
    setError(error, prefix + "half outline: " + reason);
    return false;
  }

  std::vector<Vec2> result;
  result.reserve(2 * n - 2);
  result.push_back(Vec2(m, half.front().y()));  // snapped onto the axis
  for (std::size_t i = 1; i + 1 < n; ++i) result.push_back(half[i]);
  result.push_back(Vec2(m, half.back().y()));
  for (std::size_t i = n - 2; i >= 1; --i) result.push_back(Vec2(2 * m - half[i].x(), half[i].y()));
  if (!validatePolygon(result, &reason)) {
    setError(error, prefix + "full (mirrored) outline: " + reason);
    return false;
  }
  if (full != nullptr) *full = std::move(result);
  if (error != nullptr) error->clear();
  return true;
}

std::vector<Vec2> fullOutline(const TextileOutline& textile) {
  std::vector<Vec2> full;
  std::string error;
  if (!buildFullOutline(textile, &full, &error)) throw SimError(error);
  return full;
}

bool validateTextileOutline(const TextileOutline& textile, std::string* error) {
  const std::string prefix = textilePrefix(textile);
  if (!checkOutlineSize(textile, error)) return false;
  if (textile.named_points.size() > kMaxNamedPoints) {
    setError(error, prefix + std::to_string(textile.named_points.size()) +
                        " named points, more than the limit of " + std::to_string(kMaxNamedPoints));
    return false;
  }
  std::string reason;
  if (!textile.name.empty() && !validateTextileName(textile.name, &reason)) {
    setError(error, "textile " + reason);
    return false;
  }
  std::vector<Vec2> full;
  if (!buildFullOutline(textile, &full, error)) return false;
  std::set<std::string> names;
  for (std::size_t i = 0; i < textile.named_points.size(); ++i) {
    const NamedPoint& p = textile.named_points[i];
    if (!validateTextileName(p.name, &reason)) {
      setError(error, prefix + "named point " + std::to_string(i) + ": " + reason);
      return false;
    }
    if (!names.insert(p.name).second) {
      setError(error, prefix + "named point '" + p.name + "' is defined twice");
      return false;
    }
    if (p.kind != "corner" && p.kind != "grasp") {
      setError(error, prefix + "named point '" + p.name + "' has kind '" + p.kind +
                          "'; expected \"corner\" or \"grasp\"");
      return false;
    }
    if (!p.position.allFinite() || !pointInPolygon(full, p.position, kAxisTol)) {
      setError(error, prefix + "named point '" + p.name + "' at " + formatPoint(p.position) +
                          " lies outside the outline");
      return false;
    }
  }
  if (error != nullptr) error->clear();
  return true;
}

ParticleGrid ParticleGrid::rasterize(const TextileOutline& textile, Real spacing, std::string* error) {
  const std::string prefix = "cannot rasterise " + textilePrefix(textile);
  if (!std::isfinite(spacing) || spacing <= 0) {
    setError(error, prefix + "particle spacing must be finite and > 0 m, got " + formatReal(spacing));
    return ParticleGrid();
  }
  std::vector<Vec2> polygon;
  std::string reason;
  if (!buildFullOutline(textile, &polygon, &reason)) {
    setError(error, prefix + reason);
    return ParticleGrid();
  }

  const BoundingBox box = boundingBox(polygon);
  const double cols_minus_1 = std::floor((box.max.x() - box.min.x()) / spacing + kIndexTol);
  const double rows_minus_1 = std::floor((box.max.y() - box.min.y()) / spacing + kIndexTol);
  if ((cols_minus_1 + 1) * (rows_minus_1 + 1) > kMaxGridNodes) {
    setError(error, prefix + "spacing " + formatReal(spacing) + " m gives a grid of " + formatReal(rows_minus_1 + 1) +
                        " x " + formatReal(cols_minus_1 + 1) + " nodes, more than the limit of " +
                        formatReal(kMaxGridNodes));
    return ParticleGrid();
  }

  ParticleGrid grid;
  grid.rows_ = static_cast<Index>(rows_minus_1) + 1;
  grid.cols_ = static_cast<Index>(cols_minus_1) + 1;
  grid.spacing_ = spacing;
  // Mirrored: centre the columns on the axis so that node j and node cols-1-j
  // are reflections of each other.
  const Real origin_x =
      textile.mirrored ? textile.mirror_x - 0.5 * static_cast<Real>(grid.cols_ - 1) * spacing : box.min.x();
  grid.origin_ = Vec2(origin_x, box.min.y());
  grid.polygon_ = std::move(polygon);

  const Real tolerance = 1e-9 * spacing;
  const std::size_t cols = static_cast<std::size_t>(grid.cols_);
  std::vector<char> is_active(static_cast<std::size_t>(grid.rows_) * cols, 0);
  // Mirrored: evaluate the x >= mirror_x half only (cols/2 is the axis column
  // for odd cols, the first column right of the axis for even cols) and copy,
  // so that rounding can never break the symmetry.
  const Index first_col = textile.mirrored ? grid.cols_ / 2 : 0;
  for (Index i = 0; i < grid.rows_; ++i) {
    const RowClassifier row(grid.polygon_, grid.node(i, first_col).y(), tolerance);
    for (Index j = first_col; j < grid.cols_; ++j) {
      const char inside = row.inside(grid.node(i, j)) ? 1 : 0;
      const std::size_t row_start = static_cast<std::size_t>(i) * cols;
      is_active[row_start + static_cast<std::size_t>(j)] = inside;
      if (textile.mirrored) is_active[row_start + static_cast<std::size_t>(grid.cols_ - 1 - j)] = inside;
    }
  }

  grid.compact_of_node_.assign(is_active.size(), -1);
  for (Index i = 0; i < grid.rows_; ++i) {
    for (Index j = 0; j < grid.cols_; ++j) {
      const std::size_t r = static_cast<std::size_t>(i) * cols + static_cast<std::size_t>(j);
      if (!is_active[r]) continue;
      grid.compact_of_node_[r] = static_cast<Index>(grid.compact_row_.size());
      grid.compact_row_.push_back(i);
      grid.compact_col_.push_back(j);
    }
  }

  if (grid.numActive() < 4) {
    setError(error, prefix + "only " + std::to_string(grid.numActive()) + " active particle(s) at spacing " +
                        formatReal(spacing) + " m; at least 4 are required (use a smaller spacing)");
    return ParticleGrid();
  }
  if (error != nullptr) error->clear();
  return grid;
}

Index ParticleGrid::activeIndex(Index i, Index j) const {
  if (i < 0 || j < 0 || i >= rows_ || j >= cols_) return -1;
  return compact_of_node_[static_cast<std::size_t>(i) * static_cast<std::size_t>(cols_) + static_cast<std::size_t>(j)];
}

std::vector<Vec2> ParticleGrid::activePositions2D() const {
  std::vector<Vec2> positions;
  positions.reserve(compact_row_.size());
  for (Index c = 0; c < numActive(); ++c) positions.push_back(activePosition(c));
  return positions;
}

Index ParticleGrid::nearestActive(const Vec2& p) const {
  Index best = -1;
  Real best_distance2 = 0;
  for (Index c = 0; c < numActive(); ++c) {
    const Real distance2 = (activePosition(c) - p).squaredNorm();
    if (best < 0 || distance2 < best_distance2) {
      best = c;
      best_distance2 = distance2;
    }
  }
  return best;
}

Index ParticleGrid::neighbour(Index compact, int dir) const {
  if (compact < 0 || compact >= numActive()) return -1;
  static constexpr int kDj[4] = {1, 0, -1, 0};
  static constexpr int kDi[4] = {0, 1, 0, -1};
  if (dir < 0 || dir > 3) return -1;
  const std::size_t c = static_cast<std::size_t>(compact);
  return activeIndex(compact_row_[c] + kDi[dir], compact_col_[c] + kDj[dir]);
}

std::vector<Vec2> holdPointLattice(const TextileOutline& textile, Real lattice_spacing) {
  const Real s = lattice_spacing;
  if (!std::isfinite(s) || s <= 0) {
    throw SimError("holdPointLattice: lattice spacing must be finite and > 0 m, got " + formatReal(s));
  }
  const std::vector<Vec2> polygon = fullOutline(textile);
  const BoundingBox box = boundingBox(polygon);
  const double lines_x = std::floor((box.max.x() - box.min.x()) / s) + 2;
  const double lines_y = std::floor((box.max.y() - box.min.y()) / s) + 2;
  if (lines_x * lines_y > kMaxHoldPoints) {
    throw SimError("holdPointLattice: lattice spacing " + formatReal(s) + " m is too small for textile '" +
                                textile.name + "' (more than " + formatReal(kMaxHoldPoints) + " points)");
  }

  PointDeduplicator points(0.25 * s);
  for (const Vec2& v : polygon) points.add(v);

  const std::vector<Real> xs = latticeLines(box.min.x(), box.max.x(), s);
  const std::vector<Real> ys = latticeLines(box.min.y(), box.max.y(), s);
  const Real tolerance = 1e-9 * s;
  for (Real y : ys) {
    for (Real x : xs) {
      const Vec2 p(x, y);
      if (pointInPolygon(polygon, p, tolerance)) points.add(p);
    }
  }

  const std::size_t n = polygon.size();
  for (std::size_t e = 0; e < n; ++e) {
    Vec2 start = polygon[e];
    Vec2 end = polygon[(e + 1) % n];
    // Start from the lexicographically smaller endpoint so that samples do not
    // depend on the polygon orientation and follow the lattice on axis-aligned edges.
    if (end.x() < start.x() || (end.x() == start.x() && end.y() < start.y())) std::swap(start, end);
    const Real length = (end - start).norm();
    const Vec2 direction = (end - start) / length;
    for (int k = 1; static_cast<Real>(k) * s < length - tolerance; ++k) {
      points.add(start + (static_cast<Real>(k) * s) * direction);
    }
  }

  // Sort by quantised (y, x): rounding noise must not split a row.
  const Real quantum = 1e-6 * s;
  std::vector<std::pair<std::pair<long long, long long>, Vec2>> keyed;
  keyed.reserve(points.points().size());
  for (const Vec2& p : points.points()) {
    keyed.push_back({{std::llround((p.y() - box.min.y()) / quantum), std::llround((p.x() - box.min.x()) / quantum)}, p});
  }
  std::sort(keyed.begin(), keyed.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  std::vector<Vec2> result;
  result.reserve(keyed.size());
  for (const auto& entry : keyed) result.push_back(entry.second);
  return result;
}

TextileOutline presetTextile(const std::string& name) {
  if (name == "towel") {
    const Real w = 0.64;
    const Real h = 0.46;
    TextileOutline t = rectangleTextile(name, w, h);
    t.named_points.push_back(namedPoint("short_side_left_mid", "grasp", 0, 0.5 * h));
    t.named_points.push_back(namedPoint("short_side_right_mid", "grasp", w, 0.5 * h));
    t.named_points.push_back(namedPoint("long_side_bottom_mid", "grasp", 0.5 * w, 0));
    t.named_points.push_back(namedPoint("long_side_top_mid", "grasp", 0.5 * w, h));
    return t;
  }
  if (name == "square" || name == "tablecloth") {
    const Real side = name == "square" ? 0.30 : 1.00;
    TextileOutline t = rectangleTextile(name, side, side);
    t.named_points.push_back(namedPoint("centre", "grasp", 0.5 * side, 0.5 * side));
    return t;
  }
  if (name == "tshirt") return tshirtTextile();

  std::string known;
  for (const std::string& n : presetTextileNames()) known += (known.empty() ? "" : ", ") + n;
  throw SimError("unknown textile preset '" + name + "'; known presets: " + known);
}

std::vector<std::string> presetTextileNames() { return {"towel", "square", "tablecloth", "tshirt"}; }

}  // namespace textile_handling
