#include "textile_handling/db/textile_symmetry.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

namespace textile_handling {
namespace db {

std::string toString(MirrorKind m) {
  switch (m) {
    case MirrorKind::kIdentity: return "identity";
    case MirrorKind::kMirrorX: return "mirror_x";
    case MirrorKind::kMirrorY: return "mirror_y";
    case MirrorKind::kMirrorXY: return "mirror_xy";
  }
  return "identity";
}

MirrorKind mirrorKindFromString(const std::string& s) {
  if (s == "identity") return MirrorKind::kIdentity;
  if (s == "mirror_x") return MirrorKind::kMirrorX;
  if (s == "mirror_y") return MirrorKind::kMirrorY;
  if (s == "mirror_xy") return MirrorKind::kMirrorXY;
  throw std::invalid_argument("unknown mirror kind '" + s + "' (identity, mirror_x, mirror_y, mirror_xy)");
}

std::string TextileSymmetry::name() const {
  if (mirror_x && mirror_y) return "xy";
  if (mirror_x) return "x";
  if (mirror_y) return "y";
  return "none";
}

std::vector<MirrorKind> TextileSymmetry::mirrors() const {
  std::vector<MirrorKind> out;
  if (mirror_x) out.push_back(MirrorKind::kMirrorX);
  if (mirror_y) out.push_back(MirrorKind::kMirrorY);
  if (mirror_x && mirror_y) out.push_back(MirrorKind::kMirrorXY);
  return out;
}

Vec2 TextileSymmetry::apply(MirrorKind m, const Vec2& p) const {
  const int bits = static_cast<int>(m);
  Vec2 q = p;
  if (bits & 1) q.x() = 2 * cx - p.x();
  if (bits & 2) q.y() = 2 * cy - p.y();
  return q;
}

bool TextileSymmetry::inFundamentalDomain(const Vec2& p, Real tol) const {
  if (mirror_x && p.x() > cx + tol) return false;
  if (mirror_y && p.y() > cy + tol) return false;
  return true;
}

Vec2 TextileSymmetry::canonical(const Vec2& p) const {
  Vec2 q = p;
  if (mirror_x && q.x() > cx) q.x() = 2 * cx - q.x();
  if (mirror_y && q.y() > cy) q.y() = 2 * cy - q.y();
  return q;
}

namespace {

Real boundaryDistance(const std::vector<Vec2>& poly, const Vec2& p) {
  Real best = std::numeric_limits<Real>::infinity();
  for (std::size_t k = 0; k < poly.size(); ++k)
    best = std::min(best, pointSegmentDistance(p, poly[k], poly[(k + 1) % poly.size()]));
  return best;
}

bool mirrorMaps(const std::vector<Vec2>& poly, const TextileSymmetry& s, MirrorKind m, Real tol) {
  std::vector<Vec2> img;
  img.reserve(poly.size());
  for (const Vec2& v : poly) img.push_back(s.apply(m, v));
  for (const Vec2& v : img)
    if (boundaryDistance(poly, v) > tol) return false;
  for (const Vec2& v : poly)
    if (boundaryDistance(img, v) > tol) return false;
  return true;
}

// Sutherland-Hodgman clip of a polygon to the half-plane {p : sign * (p[axis] - c) <= 0}.
std::vector<Vec2> clipHalfPlane(const std::vector<Vec2>& poly, int axis, Real c) {
  std::vector<Vec2> out;
  const std::size_t n = poly.size();
  auto inside = [&](const Vec2& p) { return p[axis] <= c; };
  for (std::size_t k = 0; k < n; ++k) {
    const Vec2& a = poly[k];
    const Vec2& b = poly[(k + 1) % n];
    const bool ia = inside(a), ib = inside(b);
    if (ia) out.push_back(a);
    if (ia != ib) {
      const Real t = (c - a[axis]) / (b[axis] - a[axis]);
      Vec2 q = a + t * (b - a);
      q[axis] = c;
      out.push_back(q);
    }
  }
  return out;
}

std::vector<Vec2> simplify(const std::vector<Vec2>& poly, Real tol) {
  std::vector<Vec2> p;
  for (const Vec2& v : poly)
    if (p.empty() || (v - p.back()).norm() > tol) p.push_back(v);
  while (p.size() > 1 && (p.front() - p.back()).norm() <= tol) p.pop_back();
  bool changed = true;
  while (changed && p.size() >= 3) {
    changed = false;
    for (std::size_t k = 0; k < p.size(); ++k) {
      const Vec2& a = p[(k + p.size() - 1) % p.size()];
      const Vec2& b = p[k];
      const Vec2& c = p[(k + 1) % p.size()];
      const Vec2 u = b - a, w = c - b;
      const Real cross = u.x() * w.y() - u.y() * w.x();
      if (std::abs(cross) <= tol * (u.norm() + w.norm()) && u.dot(w) > 0) {
        p.erase(p.begin() + static_cast<std::ptrdiff_t>(k));
        changed = true;
        break;
      }
    }
  }
  return p;
}

struct PointKey {
  long long x, y;
  bool operator<(const PointKey& o) const { return x != o.x ? x < o.x : y < o.y; }
};
PointKey keyOf(const Vec2& p) { return {std::llround(p.x() * 1e6), std::llround(p.y() * 1e6)}; }

// Ranks of values with values within tol counting as equal.
std::vector<int> ranks(const std::vector<Real>& v, Real tol) {
  std::vector<Real> s = v;
  std::sort(s.begin(), s.end());
  std::vector<Real> reps;
  for (Real x : s)
    if (reps.empty() || x - reps.back() > tol) reps.push_back(x);
  std::vector<int> r(v.size());
  for (std::size_t k = 0; k < v.size(); ++k) {
    auto it = std::lower_bound(reps.begin(), reps.end(), v[k] - tol);
    r[k] = static_cast<int>(it - reps.begin());
  }
  return r;
}

}  // namespace

TextileSymmetry detectSymmetry(const TextileOutline& textile, Real tol) {
  const std::vector<Vec2> poly = fullOutline(textile);
  Vec2 lo = poly.front(), hi = poly.front();
  for (const Vec2& v : poly) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  TextileSymmetry s;
  s.cx = 0.5 * (lo.x() + hi.x());
  s.cy = 0.5 * (lo.y() + hi.y());
  const Real t = tol * (1.0 + (hi - lo).norm());
  s.mirror_x = mirrorMaps(poly, s, MirrorKind::kMirrorX, t);
  s.mirror_y = mirrorMaps(poly, s, MirrorKind::kMirrorY, t);
  return s;
}

std::vector<Vec2> fundamentalDomainPolygon(const TextileOutline& textile, const TextileSymmetry& symmetry) {
  std::vector<Vec2> poly = fullOutline(textile);
  if (symmetry.mirror_x) poly = clipHalfPlane(poly, 0, symmetry.cx);
  if (symmetry.mirror_y) poly = clipHalfPlane(poly, 1, symmetry.cy);
  poly = simplify(poly, 1e-12);
  std::string err;
  if (!validatePolygon(poly, &err)) return {};
  return poly;
}

std::vector<Vec2> fundamentalDomainLattice(const TextileOutline& textile, const TextileSymmetry& symmetry,
                                           Real lattice_spacing) {
  if (!std::isfinite(lattice_spacing) || lattice_spacing <= 0)
    throw std::invalid_argument("lattice spacing must be finite and > 0");
  if (!symmetry.any()) return holdPointLattice(textile, lattice_spacing);
  const std::vector<Vec2> dom = fundamentalDomainPolygon(textile, symmetry);
  if (!dom.empty()) {
    TextileOutline d;
    d.name = textile.name + "_fundamental_domain";
    d.outline = dom;
    return holdPointLattice(d, lattice_spacing);
  }
  std::vector<Vec2> out;
  for (const Vec2& p : holdPointLattice(textile, lattice_spacing))
    if (symmetry.inFundamentalDomain(p, 1e-9 * lattice_spacing)) out.push_back(p);
  return out;
}

std::vector<Vec2> fundamentalDomainGrid(const TextileOutline& textile, const TextileSymmetry& symmetry, int nx, int ny) {
  if (nx < 1 || ny < 1) throw std::invalid_argument("hold-point grid needs nx >= 1 and ny >= 1");
  const std::vector<Vec2> full = fullOutline(textile);
  Vec2 lo = full.front(), hi = full.front();
  for (const Vec2& v : full) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  if (symmetry.mirror_x) hi.x() = symmetry.cx;
  if (symmetry.mirror_y) hi.y() = symmetry.cy;
  std::vector<Vec2> out;
  for (int i = 0; i < ny; ++i)
    for (int j = 0; j < nx; ++j) {
      const Real x = nx == 1 ? lo.x() : (j == nx - 1 ? hi.x() : lo.x() + (hi.x() - lo.x()) * j / (nx - 1));
      const Real y = ny == 1 ? lo.y() : (i == ny - 1 ? hi.y() : lo.y() + (hi.y() - lo.y()) * i / (ny - 1));
      const Vec2 p(x, y);
      if (pointInPolygon(full, p, 1e-9)) out.push_back(p);
    }
  return out;
}

std::vector<PlannedHoldPoint> planHoldPoints(const std::vector<Vec2>& canonical, const TextileSymmetry& symmetry) {
  std::vector<PlannedHoldPoint> plan;
  std::map<PointKey, int> seen;
  auto known = [&](const Vec2& p) {
    const PointKey k = keyOf(p);
    for (long long dx = -1; dx <= 1; ++dx)
      for (long long dy = -1; dy <= 1; ++dy) {
        auto it = seen.find({k.x + dx, k.y + dy});
        if (it != seen.end() && (plan[static_cast<std::size_t>(it->second)].position - p).norm() <= 1e-6) return true;
      }
    return false;
  };
  for (const Vec2& c : canonical) {
    if (!c.allFinite()) throw std::invalid_argument("hold point is not finite");
    if (known(c)) continue;  // duplicate canonical point
    PlannedHoldPoint h;
    h.position = c;
    h.source = static_cast<int>(plan.size());
    seen[keyOf(c)] = h.source;
    plan.push_back(h);
  }
  const std::size_t n_sim = plan.size();
  for (std::size_t s = 0; s < n_sim; ++s)
    for (MirrorKind m : symmetry.mirrors()) {
      const Vec2 p = symmetry.apply(m, plan[s].position);
      if (known(p)) continue;
      PlannedHoldPoint h;
      h.position = p;
      h.mirror = m;
      h.source = static_cast<int>(s);
      seen[keyOf(p)] = static_cast<int>(plan.size());
      plan.push_back(h);
    }
  std::vector<Real> xs, ys;
  for (const auto& h : plan) {
    xs.push_back(h.position.x());
    ys.push_back(h.position.y());
  }
  const std::vector<int> rj = ranks(xs, 1e-6), ri = ranks(ys, 1e-6);
  for (std::size_t k = 0; k < plan.size(); ++k) {
    plan[k].lattice_i = ri[k];
    plan[k].lattice_j = rj[k];
  }
  return plan;
}

std::vector<Index> mirrorPermutation(const ParticleGrid& grid, const TextileSymmetry& symmetry, MirrorKind m) {
  const Index n = grid.numActive();
  if (n == 0) return {};
  const Real d = grid.spacing();
  std::vector<Index> perm(static_cast<std::size_t>(n), -1);
  for (Index k = 0; k < n; ++k) {
    const Vec2 q = symmetry.apply(m, grid.activePosition(k));
    const Vec2 g = (q - grid.origin()) / d;
    const long j = std::lround(g.x()), i = std::lround(g.y());
    if (i < 0 || j < 0 || i >= grid.rows() || j >= grid.cols()) return {};
    const Index c = grid.activeIndex(static_cast<Index>(i), static_cast<Index>(j));
    if (c < 0) return {};
    if ((grid.activePosition(c) - q).norm() > 1e-6 * d) return {};
    perm[static_cast<std::size_t>(k)] = c;
  }
  return perm;
}

Real mirrorSymmetricSpacing(const TextileOutline& textile, const TextileSymmetry& symmetry, Real spacing) {
  if (!(std::isfinite(spacing) && spacing > 0))
    throw std::invalid_argument("mirrorSymmetricSpacing: spacing must be finite and > 0");
  if (!symmetry.any()) return spacing;
  constexpr std::size_t kMaxTries = 100;
  auto symmetric = [&](Real d) {
    std::string error;
    const ParticleGrid grid = ParticleGrid::rasterize(textile, d, &error);
    if (grid.empty()) return false;
    for (MirrorKind m : symmetry.mirrors())
      if (mirrorPermutation(grid, symmetry, m).empty()) return false;
    return true;
  };
  if (symmetric(spacing)) return spacing;
  const std::vector<Vec2> full = fullOutline(textile);
  Vec2 lo = full.front(), hi = lo;
  for (const Vec2& p : full) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  // A symmetric grid has a whole number of steps across the box in each mirrored direction.
  std::vector<Real> tries;
  for (Real extent : {hi.x() - lo.x(), hi.y() - lo.y()})
    for (long n = static_cast<long>(std::ceil(extent / spacing - 1e-9)); extent / n >= 0.5 * spacing; ++n)
      if (extent / n < spacing) tries.push_back(extent / n);
  std::sort(tries.begin(), tries.end(), std::greater<Real>());
  // Each try rasterises the textile: bound the work for fine spacings on large textiles.
  if (tries.size() > kMaxTries) tries.resize(kMaxTries);
  for (Real d : tries)
    if (symmetric(d)) return d;
  return spacing;
}

VecX mirrorPositions(const VecX& positions, const std::vector<Index>& perm, MirrorKind m, const Vec3& hold_world) {
  if (positions.size() != 3 * static_cast<Eigen::Index>(perm.size()))
    throw std::invalid_argument("mirrorPositions: permutation and positions differ in size");
  const int bits = static_cast<int>(m);
  VecX out(positions.size());
  for (std::size_t k = 0; k < perm.size(); ++k) {
    Vec3 p = positions.segment<3>(3 * static_cast<Eigen::Index>(k));
    if (bits & 1) p.x() = 2 * hold_world.x() - p.x();
    if (bits & 2) p.y() = 2 * hold_world.y() - p.y();
    out.segment<3>(3 * static_cast<Eigen::Index>(perm[k])) = p;
  }
  return out;
}

}  // namespace db
}  // namespace textile_handling
