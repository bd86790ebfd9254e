// Version 3 of the thesis (edge test, candidate set, rollback to x_old): detection passes, the
// point-in-triangle check and the fallback rollback.
// See docs/collision.md.
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "textile_handling/sim/timing.h"
#include "collision_primitives.h"
#include "self_collision_parallel.h"

namespace textile_handling {

namespace {

// Linearised crossing of q through the plane of triangle c between the old and new states: the
// barycentric coordinates (of the projection onto the interpolated triangle) at the interpolated
// time where the signed distance vanishes. Returns the smallest coordinate (large negative when
// the crossing is far outside); +inf for a degenerate triangle (accepted).
Real crossingMinBarycentric(Index q, const std::array<Index, 3>& c, const VecX& x_old, const VecX& x) {
  const Vec3 no = triNormal(x_old, c), nn = triNormal(x, c);
  const Real lo = no.norm(), ln = nn.norm();
  if (!(lo > 0) || !(ln > 0)) return std::numeric_limits<Real>::infinity();
  const Real d_old = no.dot(node3(x_old, q) - node3(x_old, c[0])) / lo;
  const Real d_new = nn.dot(node3(x, q) - node3(x, c[0])) / ln;
  const Real den = d_old - d_new;
  const Real s = den != 0 ? std::clamp(d_old / den, 0.0, 1.0) : 0.5;
  auto lerp = [&](Index p) -> Vec3 { return node3(x_old, p) + s * (node3(x, p) - node3(x_old, p)); };
  const Vec3 Q = lerp(q), C0 = lerp(c[0]), C1 = lerp(c[1]), C2 = lerp(c[2]);
  const Vec3 e0 = C1 - C0, e1 = C2 - C0, w = Q - C0;
  const Real d00 = e0.dot(e0), d01 = e0.dot(e1), d11 = e1.dot(e1), d20 = w.dot(e0), d21 = w.dot(e1);
  const Real den2 = d00 * d11 - d01 * d01;
  if (!(den2 > 1e-30 * d00 * d11)) return std::numeric_limits<Real>::infinity();
  const Real b1 = (d11 * d20 - d01 * d21) / den2;
  const Real b2 = (d00 * d21 - d01 * d20) / den2;
  return std::min({1 - b1 - b2, b1, b2});
}

}  // namespace

long SelfCollisionPass::applyV3(const VecX& x_old, VecX& x, VecX& v, SelfCollisionStats& st) {
  const Index E = options_.include_diagonals ? tris_.numEdges() : tris_.num_grid_edges;
  const Index nv = tris_.num_vertices;
  auto t0 = Clock::now();
  // Broad phase (docs/collision.md, "Broad phase and cost"): two Verlet lists, kept from step to
  // step while they provably contain everything needed.
  //  * cand_: the triangle pairs whose swept boxes at the build (x_old, x and the step continued
  //    by kCandidateLookahead steps) were within Rc of each other (plus the topological
  //    neighbours, listed once). Two triangles that touch now were within Rc at the build as long
  //    as every particle stayed within Rc / 2 of its box then, or no two particles moved apart by
  //    more than Rc since, less a rigid motion (cand_ref_): rigid motions keep all distances.
  //  * prox_cache_*: the vertex-triangle and edge-edge pairs within Rp at the x_old of their build
  //    (prox_ref_), taken from cand_: a pair within the search radius R now was within Rp then
  //    while no two particles of x_old moved apart by more than Rp - R, less a rigid motion. The
  //    list is rebuilt from cand_ when cand_ still covers Rp at x_old (budget Rc - Rp), else cand_
  //    is rebuilt first.
  // Without the proximity stage (Rc = 0) cand_ is built every step. Which lists are reused never
  // changes a result: what is kept is always a superset of what is tested, and everything found
  // is sorted. Rollbacks only put particles back to x_old, which the list covers.
  const Real thickness = options_.thickness_factor * tris_.spacing;
  const bool prox = options_.proximity && thickness > 0;
  const Real R = proximitySearchRadius(thickness);
  const Real Rp = prox ? proximityListRadius(thickness) : 0.0;
  const Real Rc = prox ? candidateListRadius(thickness) : 0.0;
  auto outside = [&](const VecX& y) {  // largest distance of a particle outside its reference box
    Real d = 0;
    const Real* lo = list_lo_.data();
    const Real* hi = list_hi_.data();
    const Real* py = y.data();
    for (Index k = 0; k < 3 * nv; ++k) d = std::max({d, lo[k] - py[k], py[k] - hi[k]});
    return d;
  };
  auto buildCandidates = [&](const VecX& xn) {
    const Real ahead = prox ? kCandidateLookahead : 0.0;
    collectCandidates(x_old, xn, Rc, ahead);
    list_lo_.resize(static_cast<size_t>(3 * nv));
    list_hi_.resize(static_cast<size_t>(3 * nv));
    for (Index k = 0; k < 3 * nv; ++k) {
      const Real ext = xn[k] + ahead * (xn[k] - x_old[k]);
      list_lo_[static_cast<size_t>(k)] = std::min({x_old[k], xn[k], ext});
      list_hi_[static_cast<size_t>(k)] = std::max({x_old[k], xn[k], ext});
    }
    setReference(cand_ref_, xn);
    cand_valid_ = prox;
    cand_radius_ = Rc;
    ++st.candidate_list_builds;
  };
  // cand_ contains every triangle pair within `reach` of each other at y.
  auto candidatesCover = [&](const VecX& y, Real reach) {
    if (!prox || !cand_valid_ || cand_radius_ != Rc || list_lo_.size() != static_cast<size_t>(y.size())) return false;
    const Real budget = Rc - reach;
    if (!(budget >= 0)) return false;
    if (2 * outside(y) <= budget) return true;
    return movedLessThan(cand_ref_, y, budget);
  };
  hash_current_ = false;
  if (prox) {
    bool rebuild = !list_valid_ || list_radius_ != Rp || list_edges_ != options_.proximity_edges ||
                   prox_ref_.x.size() != x_old.size();
    if (!rebuild) rebuild = !movedLessThan(prox_ref_, x_old, Rp - R);
    if (rebuild) {
      if (!candidatesCover(x_old, Rp)) buildCandidates(x);
      buildProximityCache(x_old, Rp);
      setReference(prox_ref_, x_old);
      list_valid_ = true;
      list_radius_ = Rp;
      list_edges_ = options_.proximity_edges;
      ++st.proximity_list_builds;
    }
  }
  st.broad_ms += msSince(t0);
  if (prox) {
    t0 = Clock::now();
    std::vector<ProxPair> pairs;
    detectProximity(x_old, thickness, pairs);
    st.proximity_pairs = static_cast<long>(pairs.size());
    st.proximity_detect_ms += msSince(t0);
    if (pairs.empty()) {
      resetContactForces();
    } else {
      const VecX x_pred = x;
      st.proximity_contacts = resolveProximity(pairs, thickness, x_old, x_pred, x, v, st);
    }
    st.proximity_ms += msSince(t0);
  }
  t0 = Clock::now();
  // The triangle pairs that can touch at x (after the proximity stage's corrections): those of the
  // proximity build that were within Rp while no two particles have moved apart by more than Rp
  // since (a quarter of the candidate pairs on the towel), else the candidate pairs.
  const bool near_pairs_cover = prox && list_valid_ && movedLessThan(prox_ref_, x, Rp - 1e-6);
  if (!near_pairs_cover && !candidatesCover(x, 0.0)) buildCandidates(x);
  st.broad_ms += msSince(t0);
  t0 = Clock::now();
  computeSweptBoxes(x_old, x);  // the current swept boxes (the list's boxes contain them)
  st.broad_ms += msSince(t0);
  if (!orphan_edges_.empty() && !hash_current_) {  // orphan edges are queried against the hash
    buildHash(x_old, x, 0.0);
    hash_current_ = true;
  }
  t0 = Clock::now();
  std::vector<Hit> hits;
  detectFromCandidates(near_pairs_cover ? prox_tri_ : cand_, E, x, hits);
  if (near_pairs_cover) ++st.detections_from_proximity_build;
  st.detect_ms += msSince(t0);
  st.crossings = static_cast<long>(hits.size());
  long events = 0;
  std::vector<Index> moved;

  // Thesis step for one crossing (edge e cuts triangle t owned by p0): every endpoint q of e that
  // changed sides relative to a candidate triangle of p0 (with its crossing inside that triangle)
  // is rolled back together with the triangle's corners, and the velocities are reflected apart.
  auto thesisResolve = [&](const Hit& h) {
    bool handled = false;
    const auto ed = tris_.edges[static_cast<size_t>(h.a)];
    const Index p0 = tris_.owner[static_cast<size_t>(h.t)];
    for (Index q : ed) {
      for (Index k = tris_.candidate_start[static_cast<size_t>(p0)]; k < tris_.candidate_start[static_cast<size_t>(p0) + 1]; ++k) {
        const Index tc = tris_.candidate_list[static_cast<size_t>(k)];
        if (tris_.triangleHasVertex(tc, q)) continue;
        if (!sideChanged(q, tc, x_old, x)) continue;
        const auto& c = tris_.triangles[static_cast<size_t>(tc)];
        if (options_.point_in_triangle_check &&
            crossingMinBarycentric(q, c, x_old, x) < -options_.barycentric_tolerance) {
          ++st.point_test_rejections;
          continue;
        }
        bool ch = rollback(q, x_old, x, moved);
        for (Index cc : c) ch = rollback(cc, x_old, x, moved) || ch;
        if (!ch) continue;  // only pinned particles moved: nothing a rollback can do
        Vec3 nrm = triNormal(x_old, c).normalized();
        if (geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q)) < 0) nrm = -nrm;
        respond(&q, 1, c.data(), 3, nrm, v);
        ++events;
        ++st.thesis_events;
        handled = true;
      }
    }
    return handled;
  };
  // Fallback for a crossing no candidate side change explains: restore the edge and the crossed
  // triangle, whose old configuration was crossing-free.
  auto fallbackResolve = [&](const Hit& h) {
    const auto ed = tris_.edges[static_cast<size_t>(h.a)];
    const auto& c = tris_.triangles[static_cast<size_t>(h.t)];
    bool ch = false;
    for (Index q : ed) ch = rollback(q, x_old, x, moved) || ch;
    for (Index cc : c) ch = rollback(cc, x_old, x, moved) || ch;
    if (!ch) return false;
    // Normal toward the edge's old side (its first endpoint off the plane).
    Vec3 nrm = triNormal(x_old, c).normalized();
    int side = 0;
    for (Index q : ed)
      if (side == 0)
        side = geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q));
    if (side != 0) respond(ed.data(), 2, c.data(), 3, side > 0 ? nrm : Vec3(-nrm), v);
    ++events;
    ++st.fallback_events;
    return true;
  };

  for (int pass = 0;; ++pass) {
    if (hits.empty()) break;
    if (pass >= options_.max_passes) {
      st.unresolved = static_cast<long>(hits.size());
      break;
    }
    ++st.passes;
    t0 = Clock::now();
    moved.clear();
    // Sequential resolution in (edge, triangle) order: thesis rollbacks first; the fallback only
    // in a pass where no thesis rollback applies any more (so a crossing seen from the other
    // side, by another edge, gets the thesis treatment first).
    bool any_change = false;
    for (const Hit& h : hits)
      if (edgeCrosses(h.a, h.t, x)) any_change = thesisResolve(h) || any_change;
    if (!any_change && options_.fallback_rollback)
      for (const Hit& h : hits)
        if (edgeCrosses(h.a, h.t, x)) any_change = fallbackResolve(h) || any_change;
    st.resolve_ms += msSince(t0);
    t0 = Clock::now();
    if (!any_change) {
      long left = 0;
      for (const Hit& h : hits) left += edgeCrosses(h.a, h.t, x) ? 1 : 0;
      st.unresolved = left;
      st.detect_ms += msSince(t0);
      break;
    }
    // Next pass: crossings left over from this pass plus those a moved particle may have created.
    std::vector<Hit> left;
    for (const Hit& h : hits)
      if (edgeCrosses(h.a, h.t, x)) left.push_back(h);
    if (!hash_current_) {  // the candidate list was reused: the queries need this step's boxes
      buildHash(x_old, x, 0.0);
      hash_current_ = true;
    }
    detectIncremental(moved, E, x, hits);
    hits.insert(hits.end(), left.begin(), left.end());
    std::sort(hits.begin(), hits.end());
    hits.erase(std::unique(hits.begin(), hits.end()), hits.end());
    st.detect_ms += msSince(t0);
  }
  return events;
}

}  // namespace textile_handling
