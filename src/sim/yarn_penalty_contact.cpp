// Penalty self-contact of the yarn-level model on extruded triangles (yarn_penalty_contact.h).
#include "textile_handling/sim/yarn_penalty_contact.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>

#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/yarn_crossing_kernels.h"

namespace textile_handling {
namespace yarn {

namespace {

constexpr int kStride = 5;  // DOFs per node of the yarn model's state

Vec3 vertex(const PenaltyVector& p, int i) { return p.segment<3>(3 * i); }

// (n, -w_a n, -w_b n, -w_c n): the gradient of the signed distance d.
PenaltyVector distanceGradient(const TriangleProjection& t) {
  PenaltyVector g;
  g.segment<3>(0) = t.normal;
  for (int i = 0; i < 3; ++i) g.segment<3>(3 + 3 * i) = -t.weight[static_cast<std::size_t>(i)] * t.normal;
  return g;
}

// Blocks s_i^2 m on the node (s_0 = 1) and the triangle nodes (s_i = weights).
PenaltyBlocks weightedBlocks(const Mat3& m, const std::array<Real, 3>& w) {
  PenaltyBlocks b;
  b.block[0] = m;
  for (std::size_t i = 0; i < 3; ++i) b.block[i + 1] = w[i] * w[i] * m;
  return b;
}

}  // namespace

TriangleProjection projectOnTriangle(const PenaltyVector& p) {
  TriangleProjection t;
  const Vec3 a = vertex(p, 1), e1 = vertex(p, 2) - a, e2 = vertex(p, 3) - a, q = vertex(p, 0) - a;
  const Vec3 nn = e1.cross(e2);
  const Real area2 = nn.norm();
  // A sliver with an edge of 1e-6 of the others has no meaningful normal.
  if (!(area2 > 1e-12 * std::max(e1.squaredNorm(), e2.squaredNorm()))) return t;
  t.normal = nn / area2;
  t.distance = t.normal.dot(q);
  // With q = w_b e1 + w_c e2 + d n: n . (q x e2) = w_b |nn|, n . (e1 x q) = w_c |nn|.
  t.weight[1] = t.normal.dot(q.cross(e2)) / area2;
  t.weight[2] = t.normal.dot(e1.cross(q)) / area2;
  t.weight[0] = 1 - t.weight[1] - t.weight[2];
  t.valid = true;
  return t;
}

Real penaltyDistance(const PenaltyVector& p, int side, Real gamma) {
  const TriangleProjection t = projectOnTriangle(p);
  return t.valid ? gamma - side * t.distance : 0;
}

Real penaltyEnergy(const PenaltyVector& p, int side, Real gamma, Real k_p) {
  const Real delta = penaltyDistance(p, side, gamma);
  return delta > 0 ? 0.5 * k_p * delta * delta : 0;
}

PenaltyVector penaltyGradient(const PenaltyVector& p, int side, Real gamma, Real k_p) {
  const TriangleProjection t = projectOnTriangle(p);
  const Real delta = t.valid ? gamma - side * t.distance : 0;
  if (!(delta > 0)) return PenaltyVector::Zero();
  return -k_p * delta * side * distanceGradient(t);
}

PenaltyBlocks penaltyStiffnessBlocks(const PenaltyVector& p, int side, Real gamma, Real k_p) {
  const TriangleProjection t = projectOnTriangle(p);
  if (!t.valid || !(gamma - side * t.distance > 0)) return {};
  return weightedBlocks(-k_p * t.normal * t.normal.transpose(), t.weight);
}

PenaltyVector penaltyDampingForce(const PenaltyVector& p, const PenaltyVector& v, int side, Real gamma, Real d_p) {
  const TriangleProjection t = projectOnTriangle(p);
  if (!t.valid || !(gamma - side * t.distance > 0)) return PenaltyVector::Zero();
  // g^T v = n^T (xdot - pdot) with pdot = sum w_i v_i (the weights held).
  const PenaltyVector g = distanceGradient(t);
  return -d_p * g.dot(v) * g;
}

PenaltyBlocks penaltyDampingBlocks(const PenaltyVector& p, int side, Real gamma, Real d_p) {
  const TriangleProjection t = projectOnTriangle(p);
  if (!t.valid || !(gamma - side * t.distance > 0)) return {};
  return weightedBlocks(-d_p * t.normal * t.normal.transpose(), t.weight);
}

namespace {

// The tangential offset r = P (x - sum beta_i X_i) and the normal force k_p delta of a contact.
struct TangentialOffset {
  TriangleProjection t;
  Vec3 r = Vec3::Zero();
  Real normal_force = 0;
  bool active = false;
};

TangentialOffset tangentialOffset(const PenaltyVector& p, const std::array<Real, 3>& anchor, int side, Real gamma, Real k_p) {
  TangentialOffset o;
  o.t = projectOnTriangle(p);
  const Real delta = o.t.valid ? gamma - side * o.t.distance : 0;
  if (!(delta > 0)) return o;
  Vec3 a = Vec3::Zero();
  for (int i = 0; i < 3; ++i) a += anchor[static_cast<std::size_t>(i)] * vertex(p, i + 1);
  const Vec3 x_a = vertex(p, 0) - a;
  o.r = x_a - o.t.normal.dot(x_a) * o.t.normal;
  o.normal_force = k_p * delta;
  o.active = true;
  return o;
}

}  // namespace

PenaltyFriction penaltyFriction(const PenaltyVector& p, const std::array<Real, 3>& anchor, int side, Real gamma, Real k_p,
                                Real k_t, Real mu) {
  PenaltyFriction f;
  const TangentialOffset o = tangentialOffset(p, anchor, side, gamma, k_p);
  if (!o.active) return f;
  const Real len = o.r.norm();
  // The scalar stick/slip spring on |r| (anchor 0), directed along r.
  const StickSlip s = stickSlipSpring(len, 0, k_t, mu * o.normal_force);
  f.stick = s.stick;
  const Vec3 force = len > 0 ? Vec3(s.force * o.r / len) : Vec3::Zero();
  f.force.segment<3>(0) = force;
  for (int i = 0; i < 3; ++i) f.force.segment<3>(3 + 3 * i) = -anchor[static_cast<std::size_t>(i)] * force;
  if (s.stick) {
    const Mat3 P = Mat3::Identity() - o.t.normal * o.t.normal.transpose();
    f.blocks = weightedBlocks(-k_t * P, anchor);
  }
  return f;
}

std::array<Real, 3> penaltyFrictionAnchor(const PenaltyVector& p, const std::array<Real, 3>& anchor, int side, Real gamma,
                                          Real k_p, Real k_t, Real mu) {
  const TangentialOffset o = tangentialOffset(p, anchor, side, gamma, k_p);
  if (!o.active) return anchor;
  const Real len = o.r.norm(), limit = mu * o.normal_force;
  if (k_t * len <= limit) return anchor;
  // Move the anchor point towards x in the tangent plane until the spring sits at the limit.
  Vec3 a = Vec3::Zero();
  for (int i = 0; i < 3; ++i) a += anchor[static_cast<std::size_t>(i)] * vertex(p, i + 1);
  PenaltyVector q = p;
  // stickSlipAnchor() on |r| gives the anchor's new offset along r, |r| - limit / k_t.
  q.segment<3>(0) = a + stickSlipAnchor(len, 0, k_t, limit) / len * o.r;
  const TriangleProjection t = projectOnTriangle(q);
  return t.valid ? t.weight : anchor;
}

// ---- Triangles and detection ---------------------------------------------------------------------

bool YarnTriangles::excluded(std::size_t node, std::size_t triangle) const {
  const auto& n = near[node];
  for (std::size_t v : triangles[triangle])
    if (std::binary_search(n.begin(), n.end(), v)) return true;
  return false;
}

YarnTriangles yarnTriangles(const YarnGrid& grid) {
  const std::size_t c = grid.crossings.size();
  // The next crossing along the warp (0) and the weft (1) of every crossing, or c (none).
  std::vector<std::array<std::size_t, 2>> next(c, {c, c});
  for (const YarnPiece& piece : grid.pieces)
    for (std::size_t k = 0; k + 1 < piece.nodes.size(); ++k) {
      const std::size_t a = piece.nodes[k], b = piece.nodes[k + 1];
      if (a < c && b < c) next[a][piece.warp ? 0 : 1] = b;
    }
  YarnTriangles t;
  for (std::size_t a = 0; a < c; ++a) {
    const std::size_t u = next[a][0], v = next[a][1];
    if (u == c || v == c) continue;
    const std::size_t d = next[u][1];
    if (d == c || next[v][0] != d) continue;  // not a closed quad (a hole or an outline notch)
    t.triangles.push_back({a, u, d});
    t.triangles.push_back({a, d, v});
  }
  t.near.assign(grid.nodeCount(), {});
  for (std::size_t k = 0; k < grid.nodeCount(); ++k) t.near[k].push_back(k);
  for (const auto& tri : t.triangles)
    for (std::size_t i : tri)
      for (std::size_t j : tri)
        if (i != j) t.near[i].push_back(j);
  for (auto& n : t.near) {
    std::sort(n.begin(), n.end());
    n.erase(std::unique(n.begin(), n.end()), n.end());
  }
  return t;
}

PenaltyVector packPenaltyStencil(const VecX& x, std::size_t node, const std::array<std::size_t, 3>& triangle) {
  PenaltyVector p;
  p.segment<3>(0) = x.segment<3>(static_cast<Eigen::Index>(kStride * node));
  for (int i = 0; i < 3; ++i)
    p.segment<3>(3 + 3 * i) = x.segment<3>(static_cast<Eigen::Index>(kStride * triangle[static_cast<std::size_t>(i)]));
  return p;
}

namespace {

struct Candidate {
  Real abs_distance;
  std::size_t triangle;
  TriangleProjection t;
};

bool shareVertex(const std::array<std::size_t, 3>& a, const std::array<std::size_t, 3>& b) {
  for (std::size_t i : a)
    for (std::size_t j : b)
      if (i == j) return true;
  return false;
}

// The contacts kept of one node's candidates, with side and anchor from its previous contacts.
void keepContacts(const YarnTriangles& tris, std::size_t node, std::vector<Candidate>& cand,
                  const PenaltyContact* prev_begin, const PenaltyContact* prev_end, std::vector<PenaltyContact>& out) {
  std::sort(cand.begin(), cand.end(), [](const Candidate& a, const Candidate& b) {
    return a.abs_distance != b.abs_distance ? a.abs_distance < b.abs_distance : a.triangle < b.triangle;
  });
  const std::size_t first = out.size();
  for (const Candidate& c : cand) {
    const auto& tri = tris.triangles[c.triangle];
    bool shadowed = false;
    for (std::size_t k = first; k < out.size() && !shadowed; ++k) shadowed = shareVertex(tris.triangles[out[k].triangle], tri);
    if (shadowed) continue;
    PenaltyContact pc;
    pc.node = node;
    pc.triangle = c.triangle;
    pc.side = c.t.distance >= 0 ? 1 : -1;
    pc.anchor = c.t.weight;
    const PenaltyContact* same = nullptr;
    const PenaltyContact* neighbour = nullptr;
    for (const PenaltyContact* q = prev_begin; q != prev_end; ++q) {
      if (q->triangle == c.triangle) same = q;
      else if (!neighbour && shareVertex(tris.triangles[q->triangle], tri)) neighbour = q;
    }
    if (same) {
      pc.side = same->side;
      pc.anchor = same->anchor;
    } else if (neighbour) {
      pc.side = neighbour->side;
    }
    out.push_back(pc);
  }
  std::sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end(),
            [](const PenaltyContact& a, const PenaltyContact& b) { return a.triangle < b.triangle; });
}

}  // namespace

std::vector<PenaltyContact> detectPenaltyContacts(const YarnTriangles& tris, std::size_t crossings, const VecX& x,
                                                  const PenaltyDetection& options,
                                                  const std::vector<PenaltyContact>& previous, bool brute_force) {
  std::vector<PenaltyContact> out;
  const std::size_t T = tris.triangles.size();
  if (T == 0) return out;
  const Real gamma = options.gamma;
  // The prism of a triangle lies within gamma of it: its box is the triangle's, inflated by gamma.
  std::vector<geom::Aabb> boxes(T);
  Real extent = 0;
  for (std::size_t t = 0; t < T; ++t) {
    for (std::size_t v : tris.triangles[t]) boxes[t].extend(x.segment<3>(static_cast<Eigen::Index>(kStride * v)));
    boxes[t].inflate(gamma);
    extent += (boxes[t].hi - boxes[t].lo).maxCoeff();
  }
  geom::SpatialHash hash;
  if (!brute_force) hash.build(boxes, options.cell > 0 ? options.cell : extent / static_cast<Real>(T));
  // Crossings are independent: fixed chunks of them are detected on all threads, each with its own
  // query and list, and the lists are joined in chunk order, so the result is the serial one.
  constexpr std::size_t kChunks = 64;
  std::vector<std::vector<PenaltyContact>> found(kChunks);
#pragma omp parallel for schedule(dynamic, 1) if (crossings >= 4096)
  for (std::ptrdiff_t c = 0; c < static_cast<std::ptrdiff_t>(kChunks); ++c) {
    const std::size_t lo = crossings * static_cast<std::size_t>(c) / kChunks;
    const std::size_t hi = crossings * static_cast<std::size_t>(c + 1) / kChunks;
    geom::SpatialHash::Query query(hash);
    std::vector<Candidate> cand;
    auto test = [&](std::size_t node, std::size_t t) {
      if (tris.excluded(node, t)) return;
      const TriangleProjection pr = projectOnTriangle(packPenaltyStencil(x, node, tris.triangles[t]));
      if (!pr.valid || !(std::abs(pr.distance) < gamma)) return;
      for (Real w : pr.weight)
        if (!(w >= 0)) return;
      cand.push_back({std::abs(pr.distance), t, pr});
    };
    // The previous contacts are sorted by node: this chunk's start among them.
    const PenaltyContact* prev = std::lower_bound(previous.data(), previous.data() + previous.size(), lo,
                                                  [](const PenaltyContact& p, std::size_t n) { return p.node < n; });
    const PenaltyContact* prev_end = previous.data() + previous.size();
    for (std::size_t node = lo; node < hi; ++node) {
      cand.clear();
      const Vec3 xn = x.segment<3>(static_cast<Eigen::Index>(kStride * node));
      if (brute_force) {
        for (std::size_t t = 0; t < T; ++t) test(node, t);
      } else {
        geom::Aabb q;
        q.extend(xn);
        query.forEachOverlap(q, [&](int t) { test(node, static_cast<std::size_t>(t)); });
      }
      while (prev != prev_end && prev->node < node) ++prev;
      const PenaltyContact* p_end = prev;
      while (p_end != prev_end && p_end->node == node) ++p_end;
      if (!cand.empty()) keepContacts(tris, node, cand, prev, p_end, found[static_cast<std::size_t>(c)]);
    }
  }
  for (auto& part : found) out.insert(out.end(), part.begin(), part.end());
  return out;
}

}  // namespace yarn
}  // namespace textile_handling
