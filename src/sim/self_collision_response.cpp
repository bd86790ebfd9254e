// Response to one handled collision, shared by the versions: the side test of a point against a
// triangle, the rollback of a particle to x_old, the thesis's velocity reflection and the velocity
// response of v3 (docs/collision.md, "velocity response").
#include "textile_handling/sim/self_collision_pass.h"

#include <algorithm>
#include <cmath>
#include <vector>

namespace textile_handling {

bool SelfCollisionPass::sideChanged(Index q, Index t, const VecX& x_old, const VecX& x) const {
  const auto& c = tris_.triangles[static_cast<size_t>(t)];
  const int so = geom::orient3d(node3(x_old, c[0]), node3(x_old, c[1]), node3(x_old, c[2]), node3(x_old, q));
  if (so == 0) return false;
  const int sn = geom::orient3d(node3(x, c[0]), node3(x, c[1]), node3(x, c[2]), node3(x, q));
  return so * sn < 0;
}

bool SelfCollisionPass::rollback(Index p, const VecX& x_old, VecX& x, std::vector<Index>& moved) const {
  if (pinned_[static_cast<size_t>(p)]) return false;
  auto xp = node3(x, p);
  const auto xo = node3(x_old, p);
  if (xp == xo) return false;
  xp = xo;
  moved.push_back(p);  // once per apply(): afterwards x(p) == x_old(p)
  return true;
}

void SelfCollisionPass::reflect(Index p, const Vec3& n, VecX& v) const {
  if (pinned_[static_cast<size_t>(p)]) return;
  auto vp = node3(v, p);
  const Real vn = vp.dot(n);
  const Vec3 vpar = Vec3(vp) - vn * n;
  vp = (1.0 - options_.tangential_damping) * vpar + options_.restitution * std::abs(vn) * n;  // thesis: v_par + |v_n| n
}

void SelfCollisionPass::respond(const Index* a, int na, const Index* b, int nb, const Vec3& n, VecX& v) const {
  if (options_.response == CollisionResponse::kStop) {
    for (int k = 0; k < na; ++k)
      if (!pinned_[static_cast<size_t>(a[k])]) node3(v, a[k]).setZero();
    for (int k = 0; k < nb; ++k)
      if (!pinned_[static_cast<size_t>(b[k])]) node3(v, b[k]).setZero();
    return;
  }
  if (options_.response == CollisionResponse::kThesis) {
    for (int k = 0; k < na; ++k) reflect(a[k], n, v);
    for (int k = 0; k < nb; ++k) reflect(b[k], -n, v);
    return;
  }
  // Momentum-conserving impulse on the relative velocity of the two groups (equal particle masses;
  // each group moves as one body, pinned particles have infinite mass).
  Vec3 va = Vec3::Zero(), vb = Vec3::Zero();
  int fa = 0, fb = 0;
  for (int k = 0; k < na; ++k) {
    va += node3(v, a[k]);
    fa += pinned_[static_cast<size_t>(a[k])] ? 0 : 1;
  }
  for (int k = 0; k < nb; ++k) {
    vb += node3(v, b[k]);
    fb += pinned_[static_cast<size_t>(b[k])] ? 0 : 1;
  }
  va /= na;
  vb /= nb;
  const Real ima = fa > 0 ? 1.0 / fa : 0.0, imb = fb > 0 ? 1.0 / fb : 0.0;
  if (ima + imb == 0) return;
  const Vec3 u = va - vb;
  const Real un = u.dot(n);
  if (un >= 0) return;  // already separating
  const Vec3 du = -(1.0 + options_.restitution) * un * n - options_.tangential_damping * (u - un * n);
  const Vec3 dva = (ima / (ima + imb)) * du, dvb = -(imb / (ima + imb)) * du;
  for (int k = 0; k < na; ++k)
    if (!pinned_[static_cast<size_t>(a[k])]) node3(v, a[k]) += dva;
  for (int k = 0; k < nb; ++k)
    if (!pinned_[static_cast<size_t>(b[k])]) node3(v, b[k]) += dvb;
}

}  // namespace textile_handling
