// Distance primitives of the self-collision pass (private to src/sim): cheap separating-axis
// rejections, closest points and squared distances of points, segments and triangles (Ericson,
// Real-Time Collision Detection), triangle normals and edge keys. Positions 3 DOFs per particle.
// The helpers sit in an anonymous namespace, as they did in the single source file they came from:
// each translation unit keeps its own copy, so no name can collide with another part of the library.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>

#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

namespace {

inline bool overlapInflated(const geom::Aabb& a, const geom::Aabb& b, Real r) {
  return a.lo.x() - r <= b.hi.x() && b.lo.x() <= a.hi.x() + r && a.lo.y() - r <= b.hi.y() && b.lo.y() <= a.hi.y() + r &&
         a.lo.z() - r <= b.hi.z() && b.lo.z() <= a.hi.z() + r;
}

// Cheap separating-axis rejections (the axis between the centres): true when the features are
// farther apart than sqrt(r2). Conservative: the distance is at least the gap of the projections
// onto any axis. For the crossing tests (exact predicates) a gap of 1 um (far above the rounding
// of these few products at cloth coordinates, whatever the axis length) is required.
constexpr Real kApartMargin2 = 1e-12;
inline bool segmentsApart(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, Real r2) {
  const Vec3 w = 0.5 * ((q1 + q2) - (p1 + p2));
  const Real ww = w.squaredNorm();
  const Real s = ww - 0.5 * (std::abs((p2 - p1).dot(w)) + std::abs((q2 - q1).dot(w)));
  return s > 0 && s * s > r2 * ww;
}
inline bool trianglesApart(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0, const Vec3& b1,
                           const Vec3& b2, Real r2) {
  const Vec3 ga = (a0 + a1 + a2) / 3.0, gb = (b0 + b1 + b2) / 3.0;
  const Vec3 w = gb - ga;
  const Real ww = w.squaredNorm();
  const Real s = ww - std::max({(a0 - ga).dot(w), (a1 - ga).dot(w), (a2 - ga).dot(w)}) -
                 std::max({(gb - b0).dot(w), (gb - b1).dot(w), (gb - b2).dot(w)});
  return s > 0 && s * s > r2 * ww;
}
inline bool segmentTriangleApart(const Vec3& p1, const Vec3& p2, const Vec3& a, const Vec3& b, const Vec3& c,
                                 Real r2) {
  const Vec3 g = (a + b + c) / 3.0;
  const Vec3 w = g - 0.5 * (p1 + p2);
  const Real ww = w.squaredNorm();
  const Real s = ww - 0.5 * std::abs((p2 - p1).dot(w)) - std::max({(g - a).dot(w), (g - b).dot(w), (g - c).dot(w)});
  return s > 0 && s * s > r2 * ww;
}
inline bool pointTriangleApart(const Vec3& x, const Vec3& a, const Vec3& b, const Vec3& c, Real r2) {
  const Vec3 g = (a + b + c) / 3.0;
  const Vec3 w = x - g;
  const Real ww = w.squaredNorm();
  const Real s = ww - std::max({(a - g).dot(w), (b - g).dot(w), (c - g).dot(w)});
  return s > 0 && s * s > r2 * ww;
}

inline std::uint64_t edgeKey(Index a, Index b) {
  if (a > b) std::swap(a, b);
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) | static_cast<std::uint32_t>(b);
}

inline Vec3 triNormal(const VecX& x, const std::array<Index, 3>& c) {
  const Vec3 a = node3(x, c[0]);
  return (node3(x, c[1]) - a).cross(node3(x, c[2]) - a);
}

// Closest points of the segments p1p2 and q1q2 (Ericson, Real-Time Collision Detection, 5.1.9):
// parameters s (on p) and t (on q). Returns false for (nearly) parallel or degenerate segments.
inline bool segmentClosestParams(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2, Real* s, Real* t) {
  const Vec3 d1 = p2 - p1, d2 = q2 - q1, r = p1 - q1;
  const Real a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  if (!(a > 0) || !(e > 0)) return false;
  const Real c = d1.dot(r), b = d1.dot(d2);
  const Real den = a * e - b * b;
  if (!(den > 1e-6 * a * e)) return false;  // parallel within ~0.06 degrees: vertex-triangle pairs cover it
  Real ss = std::clamp((b * f - c * e) / den, 0.0, 1.0);
  Real tt = (b * ss + f) / e;
  if (tt < 0) {
    tt = 0;
    ss = std::clamp(-c / a, 0.0, 1.0);
  } else if (tt > 1) {
    tt = 1;
    ss = std::clamp((b - c) / a, 0.0, 1.0);
  }
  *s = ss;
  *t = tt;
  return true;
}

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5): returns the
// squared distance.
inline Real pointTriangleDistance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const Real d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Vec3 bp = p - b;
  const Real d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const Real vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (p - (a + (d1 / (d1 - d3)) * ab)).squaredNorm();
  const Vec3 cp = p - c;
  const Real d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const Real vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (p - (a + (d2 / (d2 - d6)) * ac)).squaredNorm();
  const Real va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0)
    return (p - (b + ((d4 - d3) / ((d4 - d3) + (d5 - d6))) * (c - b))).squaredNorm();
  const Real den = va + vb + vc;
  if (!(den != 0)) return std::min({ap.squaredNorm(), bp.squaredNorm(), cp.squaredNorm()});
  const Real v = vb / den, w = vc / den;
  return (p - (a + v * ab + w * ac)).squaredNorm();
}

// Squared distance between the segments p1p2 and q1q2 (Ericson 5.1.9, parallel case included).
inline Real segmentDistance2(const Vec3& p1, const Vec3& p2, const Vec3& q1, const Vec3& q2) {
  const Vec3 d1 = p2 - p1, d2 = q2 - q1, r = p1 - q1;
  const Real a = d1.dot(d1), e = d2.dot(d2), f = d2.dot(r);
  Real s = 0, t = 0;
  if (a <= 0 && e <= 0) return r.squaredNorm();
  if (a <= 0) {
    t = std::clamp(f / e, 0.0, 1.0);
  } else {
    const Real c = d1.dot(r);
    if (e <= 0) {
      s = std::clamp(-c / a, 0.0, 1.0);
    } else {
      const Real b = d1.dot(d2), den = a * e - b * b;
      s = den > 0 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
      t = (b * s + f) / e;
      if (t < 0) {
        t = 0;
        s = std::clamp(-c / a, 0.0, 1.0);
      } else if (t > 1) {
        t = 1;
        s = std::clamp((b - c) / a, 0.0, 1.0);
      }
    }
  }
  return ((p1 + s * d1) - (q1 + t * d2)).squaredNorm();
}

}  // namespace

}  // namespace textile_handling
