// Geometric building blocks of the collision module (docs/collision.md):
//  - exact orientation predicates (a floating-point filter with an exact expansion-arithmetic
//    fallback, after Shewchuk 1997), so that sign decisions never depend on rounding;
//  - closed segment-triangle and triangle-triangle intersection tests built on them;
//  - axis-aligned boxes and a deterministic spatial hash of boxes (Teschner et al. 2003).
// ROS-free; only Eigen.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Geometry>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace geom {

/// Sign (-1, 0, +1) of ((b - a) x (c - a)) . (d - a): +1 when d lies on the side of the plane abc
/// into which the right-handed normal of (a, b, c) points. Exact for finite inputs as long as the
/// intermediate products neither overflow nor underflow (coordinates within about 1e-90 .. 1e90).
int orient3d(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d);
/// Sign of (b - a) x (c - a): +1 when a, b, c run counter-clockwise. Exact.
int orient2d(const Vec2& a, const Vec2& b, const Vec2& c);

/// True when the closed segment pq and the closed triangle abc share a point (touching counts;
/// coplanar configurations are decided in the plane). Exact. Degenerate (collinear) triangles are
/// treated as their three edges.
bool segmentTriangleIntersect(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c);

/// True when the closed triangles (a1, b1, c1) and (a2, b2, c2) share a point: Devillers & Guigue
/// (2002) with exact predicates. Touching (a vertex on the other triangle, edges meeting) counts as
/// intersecting; coplanar triangles intersect when their closed 2-D projections overlap.
bool triangleTriangleIntersect(const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& a2, const Vec3& b2,
                               const Vec3& c2);
/// The same predicate by a different route (any of the six edges meets the other triangle); used to
/// cross-check triangleTriangleIntersect() in the tests. Both are exact, so they must always agree.
bool triangleTriangleIntersectByEdges(const Vec3& a1, const Vec3& b1, const Vec3& c1, const Vec3& a2,
                                      const Vec3& b2, const Vec3& c2);

/// Axis-aligned box [lo, hi]. An empty box has lo > hi.
struct Aabb {
  Vec3 lo = Vec3::Constant(std::numeric_limits<Real>::infinity());
  Vec3 hi = Vec3::Constant(-std::numeric_limits<Real>::infinity());
  void extend(const Vec3& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  void inflate(Real r) {
    lo.array() -= r;
    hi.array() += r;
  }
  bool overlaps(const Aabb& o) const {
    return lo.x() <= o.hi.x() && o.lo.x() <= hi.x() && lo.y() <= o.hi.y() && o.lo.y() <= hi.y() &&
           lo.z() <= o.hi.z() && o.lo.z() <= hi.z();
  }
};

/// Spatial hash of axis-aligned boxes on a uniform grid of cubic cells (Teschner et al. 2003: hash
/// function (73856093 x ^ 19349663 y ^ 83492791 z) mod table size, here a power of two). Every box
/// is stored in each cell it overlaps, as a compact entry (id + box rounded outward to float) so
/// that a query scans contiguous memory. Boxes spanning more than kMaxCellsPerAxis cells along an
/// axis go to an "oversized" list that every query scans. build() is sequential and deterministic
/// (counting sort in box order); queries are read-only and may run concurrently, each thread with
/// its own Query object (which removes the duplicates a box stored in several cells produces).
class SpatialHash {
 public:
  static constexpr int kMaxCellsPerAxis = 8;

  /// Stores `boxes` (ids 0..size-1) in cells of edge length `cell` (> 0). Keeps a pointer to
  /// `boxes`, which must stay alive and unchanged while the hash is queried.
  void build(const std::vector<Aabb>& boxes, Real cell);

  const Aabb& box(int id) const { return (*boxes_)[static_cast<size_t>(id)]; }
  int size() const { return boxes_ ? static_cast<int>(boxes_->size()) : 0; }
  Real cellSize() const { return cell_; }
  /// Number of (box, cell) entries (a measure of the hash's memory and query cost).
  size_t entries() const { return entries_.size(); }

  /// Per-thread query scratch.
  class Query {
   public:
    explicit Query(const SpatialHash& hash) : hash_(hash), mark_(static_cast<size_t>(hash.size()), 0) {}
    /// Calls f(id) once for every stored box that overlaps `box` (closed overlap), and possibly for
    /// boxes that miss it by less than the float rounding of the coordinates (conservative).
    template <class F>
    void forEachOverlap(const Aabb& box, F&& f) {
      forEachOverlapAbove(box, -1, std::forward<F>(f));
    }
    /// The same, restricted to the stored boxes with an id greater than `min_id` (entries are kept in
    /// id order within a bucket, so the others are skipped by a binary search): one query per box
    /// with its own id finds every overlapping pair once.
    template <class F>
    void forEachOverlapAbove(const Aabb& box, int min_id, F&& f);

   private:
    const SpatialHash& hash_;
    std::vector<std::uint32_t> mark_;
    std::uint32_t epoch_ = 0;
  };

 private:
  struct Entry {
    float lo[3], hi[3];
    int id;
  };
  using Cell = std::array<std::int64_t, 3>;
  Cell cellOf(const Vec3& p) const {
    return {static_cast<std::int64_t>(std::floor(p.x() * inv_cell_)),
            static_cast<std::int64_t>(std::floor(p.y() * inv_cell_)),
            static_cast<std::int64_t>(std::floor(p.z() * inv_cell_))};
  }
  size_t bucketOf(std::int64_t x, std::int64_t y, std::int64_t z) const {
    const std::uint64_t h = (static_cast<std::uint64_t>(x) * 73856093ULL) ^ (static_cast<std::uint64_t>(y) * 19349663ULL) ^
                            (static_cast<std::uint64_t>(z) * 83492791ULL);
    return static_cast<size_t>(h & mask_);
  }
  static bool spanOk(const Cell& lo, const Cell& hi) {
    for (int k = 0; k < 3; ++k)
      if (hi[k] - lo[k] >= kMaxCellsPerAxis || hi[k] < lo[k]) return false;
    return true;
  }
  static bool finiteBox(const Aabb& b) {
    return b.lo.allFinite() && b.hi.allFinite() && (b.lo.array() <= b.hi.array()).all();
  }
  // Float roundings that never move a bound inward (a relative step of 2^-22 exceeds the float
  // rounding error; the absolute 1e-30 covers values near zero).
  static float floatDown(double v) {
    const float f = static_cast<float>(v);
    return f - (std::fabs(f) * 2.4e-7f + 1e-30f);
  }
  static float floatUp(double v) {
    const float f = static_cast<float>(v);
    return f + (std::fabs(f) * 2.4e-7f + 1e-30f);
  }

  Real cell_ = 1, inv_cell_ = 1;
  std::uint64_t mask_ = 0;
  const std::vector<Aabb>* boxes_ = nullptr;
  std::vector<int> oversized_;          // ids of boxes not in the table
  std::vector<std::uint32_t> start_;    // bucket -> first entry (CSR), size table + 1
  std::vector<Entry> entries_;          // grouped by bucket, in box order within a bucket
  // Scratch of build(), kept so that a rebuild every step allocates nothing.
  std::vector<Cell> lo_, hi_;
  std::vector<char> in_table_;
  std::vector<std::uint32_t> bucket_, fill_;
};

template <class F>
void SpatialHash::Query::forEachOverlapAbove(const Aabb& q, int min_id, F&& f) {
  const SpatialHash& h = hash_;
  if (h.size() == 0) return;
  if (++epoch_ == 0) {  // wrapped around: clear the marks
    std::fill(mark_.begin(), mark_.end(), 0);
    epoch_ = 1;
  }
  auto report = [&](int id) {
    std::uint32_t& m = mark_[static_cast<size_t>(id)];
    if (m == epoch_) return;
    m = epoch_;
    f(id);
  };
  const Cell lo = h.cellOf(q.lo), hi = h.cellOf(q.hi);
  if (!finiteBox(q) || !spanOk(lo, hi)) {
    // A huge query: a linear scan is cheaper than visiting its cells.
    for (int i = min_id + 1; i < h.size(); ++i)
      if (h.box(i).overlaps(q)) report(i);
    return;
  }
  const float qlo[3] = {floatDown(q.lo.x()), floatDown(q.lo.y()), floatDown(q.lo.z())};
  const float qhi[3] = {floatUp(q.hi.x()), floatUp(q.hi.y()), floatUp(q.hi.z())};
  for (std::int64_t x = lo[0]; x <= hi[0]; ++x)
    for (std::int64_t y = lo[1]; y <= hi[1]; ++y)
      for (std::int64_t z = lo[2]; z <= hi[2]; ++z) {
        const size_t b = h.bucketOf(x, y, z);
        std::uint32_t k0 = h.start_[b];
        const std::uint32_t k1 = h.start_[b + 1];
        if (min_id >= 0)
          k0 = static_cast<std::uint32_t>(
              std::upper_bound(h.entries_.begin() + k0, h.entries_.begin() + k1, min_id,
                               [](int id, const Entry& e) { return id < e.id; }) -
              h.entries_.begin());
        for (std::uint32_t k = k0; k < k1; ++k) {
          const Entry& e = h.entries_[k];
          // Float test on boxes rounded outward: never misses an overlap.
          if (e.lo[0] > qhi[0] || e.hi[0] < qlo[0] || e.lo[1] > qhi[1] || e.hi[1] < qlo[1] || e.lo[2] > qhi[2] ||
              e.hi[2] < qlo[2])
            continue;
          report(e.id);
        }
      }
  for (int id : h.oversized_)
    if (id > min_id && h.box(id).overlaps(q)) report(id);
}

}  // namespace geom
}  // namespace textile_handling
