#include "textile_handling/sim/collision_geometry.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace textile_handling {
namespace geom {

namespace {

// ---- exact expansion arithmetic (Shewchuk 1997) -------------------------------------------------
// An expansion is a sum of non-overlapping doubles stored in increasing magnitude, zeros removed;
// its sign is the sign of its last (largest) component.

using Expansion = std::vector<double>;

inline void twoSum(double a, double b, double& x, double& y) {
  x = a + b;
  const double bv = x - a;
  const double av = x - bv;
  y = (a - av) + (b - bv);
}

inline void twoProduct(double a, double b, double& x, double& y) {
  x = a * b;
  y = std::fma(a, b, -x);  // exact: fma is correctly rounded
}

// e += b (Grow-Expansion with zero elimination).
void grow(Expansion& e, double b) {
  Expansion h;
  h.reserve(e.size() + 1);
  double q = b;
  for (double ei : e) {
    double s, t;
    twoSum(q, ei, s, t);
    if (t != 0) h.push_back(t);
    q = s;
  }
  if (q != 0) h.push_back(q);
  e.swap(h);
}

Expansion difference(double a, double b) {
  double x, y;
  twoSum(a, -b, x, y);
  Expansion e;
  if (y != 0) e.push_back(y);
  if (x != 0) e.push_back(x);
  return e;
}

Expansion add(const Expansion& a, const Expansion& b) {
  Expansion r = a;
  for (double v : b) grow(r, v);
  return r;
}

Expansion negate(Expansion a) {
  for (double& v : a) v = -v;
  return a;
}

Expansion multiply(const Expansion& a, const Expansion& b) {
  Expansion r;
  for (double bv : b)
    for (double av : a) {
      double x, y;
      twoProduct(av, bv, x, y);
      if (y != 0) grow(r, y);
      if (x != 0) grow(r, x);
    }
  return r;
}

int sign(const Expansion& e) { return e.empty() ? 0 : (e.back() > 0 ? 1 : -1); }

// det [a-d; b-d; c-d] exactly (the rows are the three difference vectors).
int orient3dExact(const Vec3& pa, const Vec3& pb, const Vec3& pc, const Vec3& pd) {
  Expansion A[3], B[3], C[3];
  for (int k = 0; k < 3; ++k) {
    A[k] = difference(pa[k], pd[k]);
    B[k] = difference(pb[k], pd[k]);
    C[k] = difference(pc[k], pd[k]);
  }
  // A . (B x C)
  const Expansion cx = add(multiply(B[1], C[2]), negate(multiply(B[2], C[1])));
  const Expansion cy = add(multiply(B[2], C[0]), negate(multiply(B[0], C[2])));
  const Expansion cz = add(multiply(B[0], C[1]), negate(multiply(B[1], C[0])));
  return sign(add(add(multiply(A[0], cx), multiply(A[1], cy)), multiply(A[2], cz)));
}

// det [a-c; b-c] exactly.
int orient2dExact(const Vec2& pa, const Vec2& pb, const Vec2& pc) {
  const Expansion ax = difference(pa.x(), pc.x()), ay = difference(pa.y(), pc.y());
  const Expansion bx = difference(pb.x(), pc.x()), by = difference(pb.y(), pc.y());
  return sign(add(multiply(ax, by), negate(multiply(ay, bx))));
}

constexpr double kEps = 1.1102230246251565e-16;  // 2^-53
constexpr double kO3dErrBound = (7.0 + 56.0 * kEps) * kEps;
constexpr double kCcwErrBound = (3.0 + 16.0 * kEps) * kEps;

// Shewchuk's orient3d filter: sign of det [pa-pd; pb-pd; pc-pd].
int orient3dShewchuk(const Vec3& pa, const Vec3& pb, const Vec3& pc, const Vec3& pd) {
  const double adx = pa.x() - pd.x(), bdx = pb.x() - pd.x(), cdx = pc.x() - pd.x();
  const double ady = pa.y() - pd.y(), bdy = pb.y() - pd.y(), cdy = pc.y() - pd.y();
  const double adz = pa.z() - pd.z(), bdz = pb.z() - pd.z(), cdz = pc.z() - pd.z();
  const double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
  const double cdxady = cdx * ady, adxcdy = adx * cdy;
  const double adxbdy = adx * bdy, bdxady = bdx * ady;
  const double det = adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
  const double permanent = (std::fabs(bdxcdy) + std::fabs(cdxbdy)) * std::fabs(adz) +
                           (std::fabs(cdxady) + std::fabs(adxcdy)) * std::fabs(bdz) +
                           (std::fabs(adxbdy) + std::fabs(bdxady)) * std::fabs(cdz);
  const double bound = kO3dErrBound * permanent;
  if (det > bound) return 1;
  if (-det > bound) return -1;
  return orient3dExact(pa, pb, pc, pd);
}

// ---- 2-D helpers for coplanar configurations -----------------------------------------------------

// Drops the coordinate along which the normal of (a, b, c) is largest (the projection that keeps
// the largest area). Exact for points that lie exactly in the plane.
int dominantAxis(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 n = (b - a).cross(c - a).cwiseAbs();
  if (n.x() >= n.y() && n.x() >= n.z()) return 0;
  return n.y() >= n.z() ? 1 : 2;
}

Vec2 drop(const Vec3& p, int axis) {
  if (axis == 0) return Vec2(p.y(), p.z());
  if (axis == 1) return Vec2(p.z(), p.x());
  return Vec2(p.x(), p.y());
}

// q lies on the closed segment pr, given that p, q, r are collinear.
bool onSegment2(const Vec2& p, const Vec2& q, const Vec2& r) {
  return std::min(p.x(), r.x()) <= q.x() && q.x() <= std::max(p.x(), r.x()) && std::min(p.y(), r.y()) <= q.y() &&
         q.y() <= std::max(p.y(), r.y());
}

bool segmentsIntersect2(const Vec2& p, const Vec2& q, const Vec2& r, const Vec2& s) {
  const int o1 = orient2d(p, q, r), o2 = orient2d(p, q, s), o3 = orient2d(r, s, p), o4 = orient2d(r, s, q);
  if (o1 * o2 < 0 && o3 * o4 < 0) return true;
  if (o1 == 0 && onSegment2(p, r, q)) return true;
  if (o2 == 0 && onSegment2(p, s, q)) return true;
  if (o3 == 0 && onSegment2(r, p, s)) return true;
  if (o4 == 0 && onSegment2(r, q, s)) return true;
  return false;
}

bool pointInTriangle2(const Vec2& p, const Vec2& a, const Vec2& b, const Vec2& c) {
  const int s1 = orient2d(a, b, p), s2 = orient2d(b, c, p), s3 = orient2d(c, a, p);
  if (orient2d(a, b, c) == 0) return false;  // degenerate: the edge tests decide
  return !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0));
}

bool segmentTriangle2(const Vec2& p, const Vec2& q, const Vec2& a, const Vec2& b, const Vec2& c) {
  if (pointInTriangle2(p, a, b, c) || pointInTriangle2(q, a, b, c)) return true;
  return segmentsIntersect2(p, q, a, b) || segmentsIntersect2(p, q, b, c) || segmentsIntersect2(p, q, c, a);
}

// ---- Devillers & Guigue 2002, with exact predicates ----------------------------------------------

// Closed 2-D triangle overlap, both triangles counter-clockwise (the "ccw" test of the paper).
bool testVertex(const Vec2& p1, const Vec2& q1, const Vec2& r1, const Vec2& p2, const Vec2& q2, const Vec2& r2) {
  if (orient2d(r2, p2, q1) >= 0) {
    if (orient2d(r2, q2, q1) <= 0) {
      if (orient2d(p1, p2, q1) > 0) return orient2d(p1, q2, q1) <= 0;
      return orient2d(p1, p2, r1) >= 0 && orient2d(q1, r1, p2) >= 0;
    }
    return orient2d(p1, q2, q1) <= 0 && orient2d(r2, q2, r1) <= 0 && orient2d(q1, r1, q2) >= 0;
  }
  if (orient2d(r2, p2, r1) >= 0) {
    if (orient2d(q1, r1, r2) >= 0) return orient2d(p1, p2, r1) >= 0;
    return orient2d(q1, r1, q2) >= 0 && orient2d(r2, r1, q2) >= 0;
  }
  return false;
}

bool testEdge(const Vec2& p1, const Vec2& q1, const Vec2& r1, const Vec2& p2, const Vec2& /*q2*/, const Vec2& r2) {
  if (orient2d(r2, p2, q1) >= 0) {
    if (orient2d(p1, p2, q1) >= 0) return orient2d(p1, q1, r2) >= 0;
    return orient2d(q1, r1, p2) >= 0 && orient2d(r1, p1, p2) >= 0;
  }
  if (orient2d(r2, p2, r1) >= 0) {
    if (orient2d(p1, p2, r1) >= 0) return orient2d(p1, r1, r2) >= 0 || orient2d(q1, r1, r2) >= 0;
  }
  return false;
}

bool ccwTriTri2(const Vec2& p1, const Vec2& q1, const Vec2& r1, const Vec2& p2, const Vec2& q2, const Vec2& r2) {
  if (orient2d(p2, q2, p1) >= 0) {
    if (orient2d(q2, r2, p1) >= 0) {
      if (orient2d(r2, p2, p1) >= 0) return true;
      return testEdge(p1, q1, r1, p2, q2, r2);
    }
    if (orient2d(r2, p2, p1) >= 0) return testEdge(p1, q1, r1, r2, p2, q2);
    return testVertex(p1, q1, r1, p2, q2, r2);
  }
  if (orient2d(q2, r2, p1) >= 0) {
    if (orient2d(r2, p2, p1) >= 0) return testEdge(p1, q1, r1, q2, r2, p2);
    return testVertex(p1, q1, r1, q2, r2, p2);
  }
  return testVertex(p1, q1, r1, r2, p2, q2);
}

bool triTri2(const Vec2& p1, const Vec2& q1, const Vec2& r1, const Vec2& p2, const Vec2& q2, const Vec2& r2) {
  const bool cw1 = orient2d(p1, q1, r1) < 0, cw2 = orient2d(p2, q2, r2) < 0;
  if (cw1) {
    if (cw2) return ccwTriTri2(p1, r1, q1, p2, r2, q2);
    return ccwTriTri2(p1, r1, q1, p2, q2, r2);
  }
  if (cw2) return ccwTriTri2(p1, q1, r1, p2, r2, q2);
  return ccwTriTri2(p1, q1, r1, p2, q2, r2);
}

bool coplanarTriTri(const Vec3& p1, const Vec3& q1, const Vec3& r1, const Vec3& p2, const Vec3& q2, const Vec3& r2) {
  const int ax = dominantAxis(p1, q1, r1);
  return triTri2(drop(p1, ax), drop(q1, ax), drop(r1, ax), drop(p2, ax), drop(q2, ax), drop(r2, ax));
}

// The two triangles straddle each other's planes; p1 and p2 are the vertices alone on their side.
bool checkMinMax(const Vec3& p1, const Vec3& q1, const Vec3& r1, const Vec3& p2, const Vec3& q2, const Vec3& r2) {
  if (orient3d(q1, p2, p1, q2) > 0) return false;
  if (orient3d(p1, p2, r1, r2) > 0) return false;
  return true;
}

bool triTri3d(const Vec3& p1, const Vec3& q1, const Vec3& r1, const Vec3& p2, const Vec3& q2, const Vec3& r2, int dp2,
              int dq2, int dr2) {
  if (dp2 > 0) {
    if (dq2 > 0) return checkMinMax(p1, r1, q1, r2, p2, q2);
    if (dr2 > 0) return checkMinMax(p1, r1, q1, q2, r2, p2);
    return checkMinMax(p1, q1, r1, p2, q2, r2);
  }
  if (dp2 < 0) {
    if (dq2 < 0) return checkMinMax(p1, q1, r1, r2, p2, q2);
    if (dr2 < 0) return checkMinMax(p1, q1, r1, q2, r2, p2);
    return checkMinMax(p1, r1, q1, p2, q2, r2);
  }
  if (dq2 < 0) {
    if (dr2 >= 0) return checkMinMax(p1, r1, q1, q2, r2, p2);
    return checkMinMax(p1, q1, r1, p2, q2, r2);
  }
  if (dq2 > 0) {
    if (dr2 > 0) return checkMinMax(p1, r1, q1, p2, q2, r2);
    return checkMinMax(p1, q1, r1, q2, r2, p2);
  }
  if (dr2 > 0) return checkMinMax(p1, q1, r1, r2, p2, q2);
  if (dr2 < 0) return checkMinMax(p1, r1, q1, r2, p2, q2);
  return coplanarTriTri(p1, q1, r1, p2, q2, r2);
}

// Closed 3-D segments pq and ab share a point. Exact.
bool segmentSegment3(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b) {
  if (orient3d(p, q, a, b) != 0) return false;  // not coplanar
  // Project along an axis that keeps the common plane (or line) non-degenerate.
  int ax = dominantAxis(p, q, a);
  if ((p - q).cross(a - p).squaredNorm() == 0 && (p - q).cross(b - p).squaredNorm() == 0) {
    const Vec3 d = ((q - p).squaredNorm() > 0 ? q - p : b - a).cwiseAbs();
    ax = (d.x() <= d.y() && d.x() <= d.z()) ? 0 : (d.y() <= d.z() ? 1 : 2);  // drop the smallest
  } else if ((p - q).cross(a - p).squaredNorm() == 0) {
    ax = dominantAxis(p, q, b);
  }
  return segmentsIntersect2(drop(p, ax), drop(q, ax), drop(a, ax), drop(b, ax));
}

bool degenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
  // Exactly collinear corners: every orientation with a fourth point vanishes.
  const int ax = dominantAxis(a, b, c);
  return orient2d(drop(a, ax), drop(b, ax), drop(c, ax)) == 0;
}

}  // namespace

int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  // ((b-a) x (c-a)) . (d-a) = det [b-a; c-a; d-a] = Shewchuk's orient3d(b, c, d, a).
  return orient3dShewchuk(b, c, d, a);
}

int orient2d(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double detleft = (a.x() - c.x()) * (b.y() - c.y());
  const double detright = (a.y() - c.y()) * (b.x() - c.x());
  const double det = detleft - detright;
  const double bound = kCcwErrBound * (std::fabs(detleft) + std::fabs(detright));
  if (det > bound) return 1;
  if (-det > bound) return -1;
  return orient2dExact(a, b, c);
}

bool segmentTriangleIntersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  const int o1 = orient3d(a, b, c, p), o2 = orient3d(a, b, c, q);
  if (o1 * o2 > 0) return false;
  if (o1 == 0 && o2 == 0) {
    if (degenerate(a, b, c))  // a collinear "triangle" is the union of its edges
      return segmentSegment3(p, q, a, b) || segmentSegment3(p, q, b, c) || segmentSegment3(p, q, c, a);
    const int ax = dominantAxis(a, b, c);
    return segmentTriangle2(drop(p, ax), drop(q, ax), drop(a, ax), drop(b, ax), drop(c, ax));
  }
  // The segment meets the plane in exactly one point; it lies in the closed triangle iff the line
  // pq does not pass strictly outside any edge.
  const int s1 = orient3d(p, q, a, b), s2 = orient3d(p, q, b, c), s3 = orient3d(p, q, c, a);
  return !((s1 > 0 || s2 > 0 || s3 > 0) && (s1 < 0 || s2 < 0 || s3 < 0));
}

bool triangleTriangleIntersect(const Vec3& p1, const Vec3& q1, const Vec3& r1, const Vec3& p2, const Vec3& q2,
                               const Vec3& r2) {
  if (degenerate(p1, q1, r1) || degenerate(p2, q2, r2))
    return triangleTriangleIntersectByEdges(p1, q1, r1, p2, q2, r2);
  const int dp1 = orient3d(p2, q2, r2, p1), dq1 = orient3d(p2, q2, r2, q1), dr1 = orient3d(p2, q2, r2, r1);
  if (dp1 * dq1 > 0 && dp1 * dr1 > 0) return false;
  const int dp2 = orient3d(p1, q1, r1, p2), dq2 = orient3d(p1, q1, r1, q2), dr2 = orient3d(p1, q1, r1, r2);
  if (dp2 * dq2 > 0 && dp2 * dr2 > 0) return false;
  // Permute triangle 1 so that p1 is alone on its side of plane 2 (or on it).
  if (dp1 > 0) {
    if (dq1 > 0) return triTri3d(r1, p1, q1, p2, r2, q2, dp2, dr2, dq2);
    if (dr1 > 0) return triTri3d(q1, r1, p1, p2, r2, q2, dp2, dr2, dq2);
    return triTri3d(p1, q1, r1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dp1 < 0) {
    if (dq1 < 0) return triTri3d(r1, p1, q1, p2, q2, r2, dp2, dq2, dr2);
    if (dr1 < 0) return triTri3d(q1, r1, p1, p2, q2, r2, dp2, dq2, dr2);
    return triTri3d(p1, q1, r1, p2, r2, q2, dp2, dr2, dq2);
  }
  if (dq1 < 0) {
    if (dr1 >= 0) return triTri3d(q1, r1, p1, p2, r2, q2, dp2, dr2, dq2);
    return triTri3d(p1, q1, r1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dq1 > 0) {
    if (dr1 > 0) return triTri3d(p1, q1, r1, p2, r2, q2, dp2, dr2, dq2);
    return triTri3d(q1, r1, p1, p2, q2, r2, dp2, dq2, dr2);
  }
  if (dr1 > 0) return triTri3d(r1, p1, q1, p2, q2, r2, dp2, dq2, dr2);
  if (dr1 < 0) return triTri3d(r1, p1, q1, p2, r2, q2, dp2, dr2, dq2);
  return coplanarTriTri(p1, q1, r1, p2, q2, r2);
}

bool triangleTriangleIntersectByEdges(const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& a2, const Vec3& b2,
                                      const Vec3& c2) {
  return segmentTriangleIntersect(a1, b1, a2, b2, c2) || segmentTriangleIntersect(b1, c1, a2, b2, c2) ||
         segmentTriangleIntersect(c1, a1, a2, b2, c2) || segmentTriangleIntersect(a2, b2, a1, b1, c1) ||
         segmentTriangleIntersect(b2, c2, a1, b1, c1) || segmentTriangleIntersect(c2, a2, a1, b1, c1);
}

// ---- spatial hash --------------------------------------------------------------------------------

void SpatialHash::build(const std::vector<Aabb>& boxes, Real cell) {
  cell_ = cell > 0 && std::isfinite(cell) ? cell : 1.0;
  inv_cell_ = 1.0 / cell_;
  boxes_ = &boxes;
  const size_t n = boxes.size();
  oversized_.clear();
  std::vector<Cell>& lo = lo_;
  std::vector<Cell>& hi = hi_;
  std::vector<char>& in_table = in_table_;
  lo.resize(n);
  hi.resize(n);
  in_table.assign(n, 0);
  size_t count = 0;
  for (size_t i = 0; i < n; ++i) {
    const Aabb& b = boxes[i];
    if (finiteBox(b)) {
      lo[i] = cellOf(b.lo);
      hi[i] = cellOf(b.hi);
      if (spanOk(lo[i], hi[i])) {
        in_table[i] = 1;
        count += static_cast<size_t>((hi[i][0] - lo[i][0] + 1) * (hi[i][1] - lo[i][1] + 1) * (hi[i][2] - lo[i][2] + 1));
        continue;
      }
    }
    oversized_.push_back(static_cast<int>(i));
  }
  // Power-of-two table with at least two buckets per entry.
  size_t table = 16;
  while (table < 2 * count) table <<= 1;
  mask_ = table - 1;
  start_.assign(table + 1, 0);
  std::vector<std::uint32_t>& bucket = bucket_;
  bucket.resize(count);
  size_t k = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!in_table[i]) continue;
    for (std::int64_t x = lo[i][0]; x <= hi[i][0]; ++x)
      for (std::int64_t y = lo[i][1]; y <= hi[i][1]; ++y)
        for (std::int64_t z = lo[i][2]; z <= hi[i][2]; ++z) {
          const auto b = static_cast<std::uint32_t>(bucketOf(x, y, z));
          bucket[k++] = b;
          ++start_[b + 1];
        }
  }
  for (size_t b = 0; b < table; ++b) start_[b + 1] += start_[b];
  entries_.resize(count);
  std::vector<std::uint32_t>& fill = fill_;
  fill.assign(start_.begin(), start_.end() - 1);
  k = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!in_table[i]) continue;
    const Aabb& b = boxes[i];
    Entry e;
    for (int c = 0; c < 3; ++c) {
      e.lo[c] = floatDown(b.lo[c]);
      e.hi[c] = floatUp(b.hi[c]);
    }
    e.id = static_cast<int>(i);
    const size_t cells = static_cast<size_t>((hi[i][0] - lo[i][0] + 1) * (hi[i][1] - lo[i][1] + 1) * (hi[i][2] - lo[i][2] + 1));
    for (size_t c = 0; c < cells; ++c) entries_[fill[bucket[k++]]++] = e;
  }
}

}  // namespace geom
}  // namespace textile_handling
