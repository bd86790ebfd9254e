// Proximity stage of version 3 (persistent contact): detection of close vertex-triangle and edge-edge
// pairs and their momentum-conserving inelastic correction with friction.
//
// Bridson, Fedkiw & Anderson (2002), section 7.1 ("repulsions"), adapted to a post-step pass: the
// pass receives the accepted step x_old -> x (x = x_old + h v for the implicit integrators) and
// corrects the step's displacement and the end velocity of close pairs, instead of the velocity
// that an explicit position update would use. See docs/collision.md, "Persistent contact".
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "collision_primitives.h"
#include "self_collision_parallel.h"

namespace textile_handling {

void SelfCollisionPass::detectProximity(const VecX& x_old, Real thickness, std::vector<ProxPair>& pairs) const {
  // Pairs closer than the search radius R at x_old, among the candidates of the list.
  const Real R = proximitySearchRadius(thickness);
  // A vertex projecting slightly outside a triangle still counts (the neighbouring triangle of a
  // fold's ridge may not see it either); weights are clamped to the triangle.
  constexpr Real kBaryTol = 0.05;
  // Edge-edge pairs only where the closest points are interior to both edges (elsewhere a
  // vertex-triangle pair describes the contact).
  constexpr Real kEdgeEnd = 1e-3;
  auto vertexTriangle = [&](Index p, Index t2, std::vector<ProxPair>& out) {
    const auto& c = tris_.triangles[static_cast<size_t>(t2)];
    const Vec3 xp = node3(x_old, p);
    const Vec3 a = node3(x_old, c[0]);
    const Vec3 e0 = node3(x_old, c[1]) - a, e1 = node3(x_old, c[2]) - a;
    Vec3 nrm = e0.cross(e1);
    const Real len = nrm.norm();
    if (!(len > 1e-9 * (e0.squaredNorm() + e1.squaredNorm()))) return;  // degenerate triangle
    nrm /= len;
    const Vec3 w = xp - a;
    Real dist = nrm.dot(w);
    if (!(std::abs(dist) < R) || dist == 0) return;
    const Real d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = w.dot(e0), d21 = w.dot(e1);
    const Real den = d00 * d11 - d01 * d01;
    Real b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den, b0 = 1 - b1 - b2;
    if (std::min({b0, b1, b2}) < -kBaryTol) return;
    b0 = std::max(b0, 0.0);
    b1 = std::max(b1, 0.0);
    b2 = std::max(b2, 0.0);
    const Real sum = b0 + b1 + b2;
    if (dist < 0) {
      nrm = -nrm;
      dist = -dist;
    }
    ProxPair pp;
    pp.type = 0;
    pp.a = p;
    pp.b = t2;
    pp.idx[0] = p;
    pp.w[0] = 1;
    for (int k = 0; k < 3; ++k) pp.idx[k + 1] = c[static_cast<size_t>(k)];
    pp.w[1] = -b0 / sum;
    pp.w[2] = -b1 / sum;
    pp.w[3] = -b2 / sum;
    pp.n = nrm;
    pp.gap = dist;
    out.push_back(pp);
  };
  auto edgeEdge = [&](Index e1, Index e2, std::vector<ProxPair>& out) {
    const auto& p = tris_.edges[static_cast<size_t>(e1)];
    const auto& q = tris_.edges[static_cast<size_t>(e2)];
    const Vec3 p1 = node3(x_old, p[0]), p2 = node3(x_old, p[1]), q1 = node3(x_old, q[0]), q2 = node3(x_old, q[1]);
    Real s = 0, t = 0;
    if (!segmentClosestParams(p1, p2, q1, q2, &s, &t)) return;
    if (s < kEdgeEnd || s > 1 - kEdgeEnd || t < kEdgeEnd || t > 1 - kEdgeEnd) return;
    const Vec3 d = (p1 + s * (p2 - p1)) - (q1 + t * (q2 - q1));
    const Real dist = d.norm();
    if (!(dist < R) || !(dist > 0)) return;
    ProxPair pp;
    pp.type = 1;
    pp.a = e1;
    pp.b = e2;
    pp.idx[0] = p[0];
    pp.idx[1] = p[1];
    pp.idx[2] = q[0];
    pp.idx[3] = q[1];
    pp.w[0] = 1 - s;
    pp.w[1] = s;
    pp.w[2] = -(1 - t);
    pp.w[3] = -t;
    pp.n = d / dist;
    pp.gap = dist;
    out.push_back(pp);
  };
  const Index nvt = static_cast<Index>(prox_cache_vt_.size()), nee = static_cast<Index>(prox_cache_ee_.size());
  const Index m = nvt + nee;
  auto& local = local_prox_;
  resetThreadLists(local, threadCount());
#pragma omp parallel if (m >= kParallelMin)
  {
    auto& out = local[static_cast<size_t>(threadId())].items;
#pragma omp for schedule(static)
    for (Index k = 0; k < m; ++k) {
      if (k < nvt) {
        const auto& c = prox_cache_vt_[static_cast<size_t>(k)];
        vertexTriangle(c.first, c.second, out);
      } else {
        const auto& c = prox_cache_ee_[static_cast<size_t>(k - nvt)];
        edgeEdge(c.first, c.second, out);
      }
    }
    // Each thread sorts what it found; the sorted lists are merged below (pairs are unique, so
    // the merged order is the sorted order whatever the thread count).
    std::sort(out.begin(), out.end());
  }
  pairs.clear();
  for (auto& l : local) {
    const size_t mid = pairs.size();
    pairs.insert(pairs.end(), l.items.begin(), l.items.end());
    std::inplace_merge(pairs.begin(), pairs.begin() + static_cast<std::ptrdiff_t>(mid), pairs.end());
  }
}

Real SelfCollisionPass::estimateStep(const VecX& x_old, const VecX& x_pred, const VecX& v) const {
  // The implicit integrators end a step with x = x_old + h v exactly (pinned particles excepted);
  // h is recovered by least squares and accepted only when the relation holds to rounding.
  const Index nv = tris_.num_vertices;
  Real dv = 0, vv = 0, big = 0;
  for (Index p = 0; p < nv; ++p) {
    if (pinned_[static_cast<size_t>(p)]) continue;
    const Vec3 dp = node3(x_pred, p) - node3(x_old, p);
    dv += dp.dot(node3(v, p));
    vv += node3(v, p).squaredNorm();
    big = std::max(big, dp.norm());
  }
  if (!(vv > 0) || !(dv > 0)) return -1;
  const Real h = dv / vv;
  for (Index p = 0; p < nv; ++p) {
    if (pinned_[static_cast<size_t>(p)]) continue;
    if (!((Vec3(node3(x_pred, p) - node3(x_old, p)) - h * Vec3(node3(v, p))).norm() <= 1e-6 * big + 1e-15)) return -1;
  }
  return h;
}

long SelfCollisionPass::resolveProximity(const std::vector<ProxPair>& pairs, Real thickness, const VecX& x_old,
                                         const VecX& x_pred, VecX& x, VecX& v, SelfCollisionStats& st) {
  // A projection of the step x_old -> x_pred onto the contact constraints, by Gauss-Seidel over the
  // pairs (sorted: deterministic) in the mass metric (position-based dynamics, Mueller et al. 2007,
  // with accumulated multipliers as in XPBD, Macklin et al. 2016):
  //  * contact (inequality): the relative normal displacement of the step,
  //    delta = n . sum_i w_i (x_i - x_old_i), must not fall below T - gap (gap >= T: approach up to
  //    the thickness) or s (T - gap) (gap < T: no approach, restore a fraction s of the deficit). A
  //    multiplier lambda moves particle i by w_i m_i^-1 lambda n: Bridson et al. 2002's
  //    momentum-conserving vertex-face / edge-edge impulse, in positions;
  //  * Coulomb friction: the relative tangential displacement is cancelled by a tangential
  //    multiplier limited to mu lambda_n (sticking inside the cone, sliding outside);
  //  * grid edges (propagate): every grid edge touched keeps its length after the step, so that a
  //    correction moves the patch the integrator moved with it instead of straining the stiff
  //    tension springs (Provot 1995's deformation constraints, as a projection).
  // With contact-force feedback (a ContactForceModel passes the contact forces of the last step to
  // the integrator) the step x_old -> x_pred already felt the multipliers of the previous step as
  // forces: they are the starting point and only the change is applied here; the total is stored
  // as accelerations for the next step. At rest the change vanishes: the rest state is a fixed point.
  const Real mu = options_.proximity_friction, sep = options_.proximity_separation;
  const Index nv = tris_.num_vertices;
  const Index ne = tris_.num_grid_edges;
  const bool propagate = options_.proximity_propagate;
  Real h = estimateStep(x_old, x_pred, v);
  // A step in which nothing moved (exact rest) says nothing about h: keep the last one, so that the
  // contact forces carry on.
  if (!(h > 0) && force_feedback_ && last_h_ > 0 && x_pred == x_old) h = last_h_;
  if (h > 0) last_h_ = h;
  // Corrections below this are not worth a sweep: 0.1 % of the thickness, and at most what moves a
  // particle at 0.1 mm/s (far below the rest threshold) over the step.
  const Real tol = h > 0 ? std::min(1e-3 * thickness, 1e-4 * h) : 1e-3 * thickness;
  const bool feedback = force_feedback_ && h > 0;
  std::vector<Real> ln(pairs.size(), 0.0), W(pairs.size(), 0.0);
  std::vector<Vec3> lt(pairs.size(), Vec3::Zero());
  for (size_t k = 0; k < pairs.size(); ++k) {
    Real w = 0;
    for (int j = 0; j < 4; ++j) w += pairs[k].w[j] * pairs[k].w[j] * inv_mass_[static_cast<size_t>(pairs[k].idx[j])];
    W[k] = w;
    if (!feedback) continue;
    const auto it = contact_memory_.find(pairKey(pairs[k]));
    if (it == contact_memory_.end()) continue;
    const Vec3 lam = (h * h) * it->second;  // the multiplier the last step's force amounts to
    ln[k] = std::max(0.0, lam.dot(pairs[k].n));
    lt[k] = lam - lam.dot(pairs[k].n) * pairs[k].n;
    const Real cap = mu * ln[k], ltn = lt[k].norm();
    if (ltn > cap) lt[k] *= ltn > 0 ? cap / ltn : 0.0;
  }
  std::vector<char> in_region(static_cast<size_t>(nv), 0);
  std::vector<Index> region;
  auto touch = [&](Index p) {
    if (!in_region[static_cast<size_t>(p)]) {
      in_region[static_cast<size_t>(p)] = 1;
      region.push_back(p);
    }
  };
  auto applyPair = [&](size_t k, const Vec3& d, VecX& s) {
    const ProxPair& pp = pairs[k];
    for (int j = 0; j < 4; ++j) {
      const Real im = inv_mass_[static_cast<size_t>(pp.idx[j])];
      if (im > 0 && pp.w[j] != 0) {
        node3(s, pp.idx[j]) += (pp.w[j] * im) * d;
        touch(pp.idx[j]);
      }
    }
  };
  std::vector<char> edge_listed(propagate ? static_cast<size_t>(ne) : 0, 0);
  std::vector<std::pair<Index, Real>> edges;  // grid edges and their target lengths (after the step)
  size_t region_scanned = 0;                  // region[0, region_scanned) has its edges listed
  for (int it = 0; it < options_.proximity_iterations; ++it) {
    Real change = 0;
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (!(W[k] > 0)) continue;
      const ProxPair& pp = pairs[k];
      Vec3 rel = Vec3::Zero();
      for (int j = 0; j < 4; ++j) rel += pp.w[j] * (node3(x, pp.idx[j]) - node3(x_old, pp.idx[j]));
      const Real delta = pp.n.dot(rel);
      const Real target = pp.gap >= thickness ? thickness - pp.gap : sep * (thickness - pp.gap);
      // A pair without multipliers that does not approach past its target stays so (n_new = 0
      // caps the friction at 0: nothing moves); most pairs of a sweep are such.
      if (ln[k] == 0 && lt[k].isZero(0) && !(target - delta > 0)) continue;
      const Real n_new = std::max(0.0, ln[k] + (target - delta) / W[k]);
      // Friction: cancel the relative tangential displacement within |lambda_t| <= mu lambda_n.
      Vec3 t_new = lt[k] - (rel - delta * pp.n) / W[k];
      t_new -= pp.n.dot(t_new) * pp.n;
      const Real cap = mu * n_new, tn = t_new.norm();
      if (tn > cap) t_new *= tn > 0 ? cap / tn : 0.0;
      const Real dn = n_new - ln[k];
      const Vec3 dt = t_new - lt[k];
      const Real moved = (std::abs(dn) + dt.norm()) * W[k];
      if (!(moved > tol)) continue;
      applyPair(k, dn * pp.n + dt, x);
      ln[k] = n_new;
      lt[k] = t_new;
      change = std::max(change, moved);
    }
    if (!propagate) {
      if (!(change > tol)) break;
      continue;
    }
    // Grid edges around every particle moved so far (kept sorted: deterministic). The region only
    // grows, so only its particles added since the last sweep can bring new edges.
    const size_t before = edges.size();
    for (; region_scanned < region.size(); ++region_scanned) {
      const Index p = region[region_scanned];
      for (Index q = vertex_edge_start_[static_cast<size_t>(p)]; q < vertex_edge_start_[static_cast<size_t>(p) + 1]; ++q) {
        const Index e = vertex_edge_list_[static_cast<size_t>(q)];
        if (e >= ne || edge_listed[static_cast<size_t>(e)]) continue;
        edge_listed[static_cast<size_t>(e)] = 1;
        const auto& ed = tris_.edges[static_cast<size_t>(e)];
        edges.emplace_back(e, (node3(x_pred, ed[0]) - node3(x_pred, ed[1])).norm());
      }
    }
    if (edges.size() != before) {  // sort the new ones and merge them in
      const auto mid = edges.begin() + static_cast<std::ptrdiff_t>(before);
      std::sort(mid, edges.end());
      std::inplace_merge(edges.begin(), mid, edges.end());
    }
    for (size_t k = 0; k < edges.size(); ++k) {
      const auto& ed = tris_.edges[static_cast<size_t>(edges[k].first)];
      const Index a = ed[0], b = ed[1];
      const Real wa = inv_mass_[static_cast<size_t>(a)], wb = inv_mass_[static_cast<size_t>(b)];
      if (!(wa + wb > 0)) continue;
      Vec3 u = node3(x, a) - node3(x, b);
      const Real len = u.norm();
      if (!(len > 0)) continue;
      const Real c = len - edges[k].second;
      if (!(std::abs(c) > tol)) continue;
      u *= c / ((wa + wb) * len);
      if (wa > 0) {
        node3(x, a) -= wa * u;
        touch(a);
      }
      if (wb > 0) {
        node3(x, b) += wb * u;
        touch(b);
      }
      change = std::max(change, std::abs(c));
      ++st.proximity_edge_projections;
    }
    if (!(change > tol)) break;
  }
  long contacts = 0;
  for (size_t k = 0; k < pairs.size(); ++k) contacts += ln[k] > 0 ? 1 : 0;
  // Contact forces for the next step (as accelerations of the particles, relative-mass weighted).
  contact_memory_.clear();
  if (feedback) {
    if (contact_accel_.size() != 3 * nv) contact_accel_ = VecX::Zero(3 * nv);
    contact_accel_.setZero();
    const Real ih2 = 1.0 / (h * h);
    for (size_t k = 0; k < pairs.size(); ++k) {
      if (!(ln[k] > 0)) continue;
      const Vec3 a = ih2 * (ln[k] * pairs[k].n + lt[k]);
      contact_memory_.emplace(pairKey(pairs[k]), a);
      for (int j = 0; j < 4; ++j) {
        const Real im = inv_mass_[static_cast<size_t>(pairs[k].idx[j])];
        if (im > 0) node3(contact_accel_, pairs[k].idx[j]) += (pairs[k].w[j] * im) * a;
      }
    }
  } else {
    contact_accel_.resize(0);
  }
  // Velocities: with x = x_old + h v the end velocity follows the corrected displacement, which
  // keeps x and v consistent (the correction acts as an impulse). Otherwise (h unknown) an inelastic
  // impulse on the relative normal velocity of every contact, with friction.
  if (h > 0) {
    std::sort(region.begin(), region.end());
    for (Index p : region) node3(v, p) += (Vec3(node3(x, p)) - Vec3(node3(x_pred, p))) / h;
  } else {
    for (int it = 0; it < options_.proximity_iterations; ++it) {
      bool any = false;
      for (size_t k = 0; k < pairs.size(); ++k) {
        if (!(ln[k] > 0) || !(W[k] > 0)) continue;
        const ProxPair& pp = pairs[k];
        Vec3 rel = Vec3::Zero();
        for (int j = 0; j < 4; ++j) rel += pp.w[j] * node3(v, pp.idx[j]);
        const Real un = pp.n.dot(rel);
        if (!(un < 0)) continue;
        Vec3 d = -un * pp.n;
        const Vec3 ut = rel - un * pp.n;
        const Real utn = ut.norm();
        if (mu > 0 && utn > 0) d -= std::min(1.0, mu * -un / utn) * ut;
        applyPair(k, d / W[k], v);
        any = true;
      }
      if (!any) break;
    }
  }
  return contacts;
}

}  // namespace textile_handling
