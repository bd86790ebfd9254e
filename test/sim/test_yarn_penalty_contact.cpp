// Penalty self-contact of the yarn-level model (yarn_penalty_contact.h): the kernel's force against
// its energy and its diagonal Jacobian blocks against finite differences, detection inside and outside
// a prism and the exclusion of a node's own ring, the hashed broad phase against all pairs, and the
// model with self_contact on: forces against the energy gradient, diagonal blocks, options, save/resume.
// docs/yarn_model.md, "Collisions".
#include "yarn_test_support.h"  // first: see there

#include "../test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/yarn_penalty_contact.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

using yarn::PenaltyVector;
using yarn_test_support::numericGradientN;
using yarn_test_support::numericJacobianN;

constexpr Real kGamma = 1e-3, kK = 2e3;

// A node above a tilted triangle of about 2 mm, at height `h` times gamma over the point with weights w.
PenaltyVector nodeOverTriangle(Real h, const std::array<Real, 3>& w, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> u(-1, 1);
  PenaltyVector p;
  p.segment<3>(3) = Vec3(0, 0, 0) + 2e-4 * Vec3(u(rng), u(rng), u(rng));
  p.segment<3>(6) = Vec3(2e-3, 0, 3e-4) + 2e-4 * Vec3(u(rng), u(rng), u(rng));
  p.segment<3>(9) = Vec3(0, 2e-3, -2e-4) + 2e-4 * Vec3(u(rng), u(rng), u(rng));
  const Vec3 n = (p.segment<3>(6) - p.segment<3>(3)).cross(p.segment<3>(9) - p.segment<3>(3)).normalized();
  p.segment<3>(0) = w[0] * p.segment<3>(3) + w[1] * p.segment<3>(6) + w[2] * p.segment<3>(9) + h * kGamma * n;
  return p;
}

TEST(YarnPenaltyContact, ProjectionGivesDistanceAndWeights) {
  const PenaltyVector p = nodeOverTriangle(0.4, {0.2, 0.3, 0.5}, 1);
  const yarn::TriangleProjection t = yarn::projectOnTriangle(p);
  ASSERT_TRUE(t.valid);
  EXPECT_NEAR(t.distance, 0.4 * kGamma, 1e-15);
  EXPECT_NEAR(t.weight[0], 0.2, 1e-12);
  EXPECT_NEAR(t.weight[1], 0.3, 1e-12);
  EXPECT_NEAR(t.weight[2], 0.5, 1e-12);
  EXPECT_NEAR(yarn::penaltyDistance(p, 1, kGamma), 0.6 * kGamma, 1e-15);
  EXPECT_NEAR(yarn::penaltyDistance(p, -1, kGamma), 1.4 * kGamma, 1e-15);
  PenaltyVector sliver = p;
  sliver.segment<3>(9) = 0.5 * (p.segment<3>(3) + p.segment<3>(6));
  EXPECT_FALSE(yarn::projectOnTriangle(sliver).valid);
}

TEST(YarnPenaltyContact, ForceIsMinusTheEnergyGradient) {
  int active = 0;
  for (unsigned seed = 0; seed < 20; ++seed)
    for (int side : {1, -1}) {
      // From well inside on the kept side through the plane (delta > gamma) to outside (delta < 0).
      const Real h = -1.5 + 0.15 * seed;
      const PenaltyVector p = nodeOverTriangle(h, {0.5, 0.25, 0.25}, seed);
      const PenaltyVector g = yarn::penaltyGradient(p, side, kGamma, kK);
      const PenaltyVector num = numericGradientN<12>(
          [&](const PenaltyVector& q) { return yarn::penaltyEnergy(q, side, kGamma, kK); }, p, 1e-9);
      EXPECT_LT((g - num).norm(), 1e-6 * g.norm() + 1e-9) << "seed " << seed << " side " << side;
      if (yarn::penaltyDistance(p, side, kGamma) > 0) {
        ++active;
        // The notes' force: k_p delta n_s on x, pushing it towards its side.
        const Vec3 n = yarn::projectOnTriangle(p).normal;
        EXPECT_LT((-g.segment<3>(0) - kK * yarn::penaltyDistance(p, side, kGamma) * side * n).norm(), 1e-12);
        // No resultant: the triangle gets the opposite force.
        EXPECT_LT((g.segment<3>(0) + g.segment<3>(3) + g.segment<3>(6) + g.segment<3>(9)).norm(), 1e-9 * g.norm());
      } else {
        EXPECT_EQ(g.norm(), 0);
      }
    }
  EXPECT_GT(active, 10);
}

// The diagonal 3 x 3 block i of a 12 x 12 matrix.
Mat3 diagonalBlock(const Eigen::Matrix<Real, 12, 12>& m, int i) { return m.block<3, 3>(3 * i, 3 * i); }

TEST(YarnPenaltyContact, DiagonalBlocksMatchFiniteDifferences) {
  for (unsigned seed = 0; seed < 10; ++seed) {
    const int side = seed % 2 ? 1 : -1;
    const PenaltyVector p = nodeOverTriangle(side * (0.8 - 0.15 * seed), {0.6, 0.3, 0.1}, seed);
    ASSERT_GT(yarn::penaltyDistance(p, side, kGamma), 0);
    const auto J = numericJacobianN<12>([&](const PenaltyVector& q) { return PenaltyVector(-yarn::penaltyGradient(q, side, kGamma, kK)); },
                                        p, 1e-9);
    const yarn::PenaltyBlocks b = yarn::penaltyStiffnessBlocks(p, side, kGamma, kK);
    // The node's own block is exact.
    EXPECT_LT((b.block[0] - diagonalBlock(J, 0)).norm(), 1e-6 * kK) << seed;
    // A triangle node's block is the Gauss-Newton part: exact along n when x lies in the plane (the
    // left-out terms are of order delta - gamma); off the plane it keeps the sign and the order.
    const Vec3 n = yarn::projectOnTriangle(p).normal;
    for (int i = 1; i < 4; ++i) {
      EXPECT_LE(n.dot(b.block[i] * n), 0);
      EXPECT_NEAR(n.dot(b.block[i] * n), n.dot(diagonalBlock(J, i) * n), 0.5 * kK) << seed;
    }
  }
  PenaltyVector in_plane = nodeOverTriangle(0, {0.6, 0.3, 0.1}, 3);
  const auto J = numericJacobianN<12>([&](const PenaltyVector& q) { return PenaltyVector(-yarn::penaltyGradient(q, 1, kGamma, kK)); },
                                      in_plane, 1e-9);
  const yarn::PenaltyBlocks b = yarn::penaltyStiffnessBlocks(in_plane, 1, kGamma, kK);
  const Vec3 n = yarn::projectOnTriangle(in_plane).normal;
  for (int i = 1; i < 4; ++i) EXPECT_NEAR(n.dot(b.block[i] * n), n.dot(diagonalBlock(J, i) * n), 1e-5 * kK);
  EXPECT_NEAR(n.dot(b.block[1] * n), -kK * 0.36, 1e-9 * kK);
  // Outside the prism nothing.
  const yarn::PenaltyBlocks none = yarn::penaltyStiffnessBlocks(nodeOverTriangle(1.2, {0.6, 0.3, 0.1}, 3), 1, kGamma, kK);
  for (const Mat3& m : none.block) EXPECT_EQ(m.norm(), 0);
}

TEST(YarnPenaltyContact, DampingBlocksMatchFiniteDifferencesInVelocity) {
  const Real d_p = 0.3;
  const PenaltyVector p = nodeOverTriangle(0.3, {0.2, 0.5, 0.3}, 4);
  std::mt19937 rng(5);
  std::uniform_real_distribution<Real> u(-1, 1);
  PenaltyVector v;
  for (int k = 0; k < 12; ++k) v[k] = u(rng);
  const auto J = numericJacobianN<12>([&](const PenaltyVector& w) { return yarn::penaltyDampingForce(p, w, 1, kGamma, d_p); }, v, 1e-6);
  const yarn::PenaltyBlocks b = yarn::penaltyDampingBlocks(p, 1, kGamma, d_p);
  for (int i = 0; i < 4; ++i) EXPECT_LT((b.block[static_cast<std::size_t>(i)] - diagonalBlock(J, i)).norm(), 1e-9) << i;
  // It opposes the approach: a node moving into the triangle along -n is slowed.
  const Vec3 n = yarn::projectOnTriangle(p).normal;
  PenaltyVector approach = PenaltyVector::Zero();
  approach.segment<3>(0) = -n;
  EXPECT_NEAR(yarn::penaltyDampingForce(p, approach, 1, kGamma, d_p).segment<3>(0).dot(n), d_p, 1e-12);
  // A rigid velocity of the whole stencil is no approach.
  PenaltyVector rigid;
  for (int i = 0; i < 4; ++i) rigid.segment<3>(3 * i) = Vec3(0.3, -0.2, 0.7);
  EXPECT_LT(yarn::penaltyDampingForce(p, rigid, 1, kGamma, d_p).norm(), 1e-12);
}

TEST(YarnPenaltyContact, FrictionSticksBelowAndSlipsAboveTheCoulombLimit) {
  const Real mu = 0.3, k_t = kK;
  PenaltyVector p = nodeOverTriangle(0.5, {0.3, 0.3, 0.4}, 6);
  const std::array<Real, 3> anchor = yarn::projectOnTriangle(p).weight;
  const Real limit = mu * kK * 0.5 * kGamma;
  const Vec3 n = yarn::projectOnTriangle(p).normal, t = n.unitOrthogonal();
  // Stick: a tangential shift s gives -k_t s t, with the exact node block -k_t P.
  PenaltyVector q = p;
  q.segment<3>(0) += 0.5 * limit / k_t * t;
  yarn::PenaltyFriction f = yarn::penaltyFriction(q, anchor, 1, kGamma, kK, k_t, mu);
  EXPECT_TRUE(f.stick);
  EXPECT_LT((f.force.segment<3>(0) + 0.5 * limit * t).norm(), 1e-9 * limit);
  const auto J = numericJacobianN<12>(
      [&](const PenaltyVector& r) { return yarn::penaltyFriction(r, anchor, 1, kGamma, kK, k_t, mu).force; }, q, 1e-10);
  EXPECT_LT((f.blocks.block[0] - diagonalBlock(J, 0)).norm(), 1e-5 * k_t);
  EXPECT_LT((f.force.segment<3>(0) + f.force.segment<3>(3) + f.force.segment<3>(6) + f.force.segment<3>(9)).norm(), 1e-9 * limit);
  // Slip: the force is capped at mu k_p delta, the anchor follows to the limit.
  q = p;
  q.segment<3>(0) += 3 * limit / k_t * t;
  f = yarn::penaltyFriction(q, anchor, 1, kGamma, kK, k_t, mu);
  EXPECT_FALSE(f.stick);
  EXPECT_NEAR(f.force.segment<3>(0).norm(), limit, 1e-9 * limit);
  const std::array<Real, 3> moved = yarn::penaltyFrictionAnchor(q, anchor, 1, kGamma, kK, k_t, mu);
  const yarn::PenaltyFriction after = yarn::penaltyFriction(q, moved, 1, kGamma, kK, k_t, mu);
  EXPECT_NEAR(after.force.segment<3>(0).norm(), limit, 1e-6 * limit);
  EXPECT_EQ(yarn::penaltyFrictionAnchor(p, anchor, 1, kGamma, kK, k_t, mu), anchor);  // stick: unchanged
}

// ---- Triangles and detection ---------------------------------------------------------------------

// A 6 x 6 mm patch of the default fabric (1 yarn/mm) with free ends.
YarnGrid patchGrid() {
  const std::vector<Vec2> square = {Vec2(0, 0), Vec2(0.006, 0), Vec2(0.006, 0.006), Vec2(0, 0.006)};
  return layYarnGrid(square, WovenFabric{});
}

VecX flatState(const YarnGrid& g) {
  VecX x = VecX::Zero(5 * static_cast<Eigen::Index>(g.nodeCount()));
  for (std::size_t k = 0; k < g.nodeCount(); ++k) x.segment<2>(5 * static_cast<Eigen::Index>(k)) = g.nodePosition(k);
  return x;
}

TEST(YarnPenaltyContact, TrianglesCoverEveryQuadWithTheSheetsOrientation) {
  const YarnGrid g = patchGrid();
  const yarn::YarnTriangles t = yarn::yarnTriangles(g);
  ASSERT_EQ(g.crossings.size(), 36u);
  EXPECT_EQ(t.triangles.size(), 2u * 5 * 5);
  const VecX x = flatState(g);
  for (std::size_t k = 0; k < t.triangles.size(); ++k) {
    const yarn::TriangleProjection p = yarn::projectOnTriangle(yarn::packPenaltyStencil(x, 0, t.triangles[k]));
    EXPECT_NEAR(p.normal.z(), 1, 1e-12);  // warp (x) then weft (y): +z
  }
  // An interior crossing's ring: itself and its 6 neighbours by triangles (4 along the yarns, 2 diagonal).
  const std::size_t interior = 2 * 6 + 2;
  EXPECT_EQ(t.near[interior].size(), 7u);
}

std::vector<yarn::PenaltyContact> contactsOf(std::size_t node, const std::vector<yarn::PenaltyContact>& all) {
  std::vector<yarn::PenaltyContact> c;
  for (const auto& k : all)
    if (k.node == node) c.push_back(k);
  return c;
}

TEST(YarnPenaltyContact, ANodeInsideAPrismIsDetectedAndOneOutsideOrInItsRingIsNot) {
  const YarnGrid g = patchGrid();
  const yarn::YarnTriangles t = yarn::yarnTriangles(g);
  yarn::PenaltyDetection d;
  d.gamma = kGamma;
  const std::size_t node = 0;                           // a corner crossing
  const std::size_t far = t.triangles.size() - 1;       // a triangle at the opposite corner
  ASSERT_FALSE(t.excluded(node, far));
  auto centroid = [&](std::size_t tri, const VecX& x) {
    Vec3 c = Vec3::Zero();
    for (std::size_t v : t.triangles[tri]) c += x.segment<3>(5 * static_cast<Eigen::Index>(v)) / 3;
    return c;
  };
  VecX x = flatState(g);
  const Vec3 c = centroid(far, x);
  for (Real h : {0.3, -0.7}) {
    x.segment<3>(5 * node) = c + Vec3(0, 0, h * kGamma);
    // (Other crossings may lie in the prisms of the node's own triangles, stretched over the sheet.)
    const auto found = contactsOf(node, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {}));
    ASSERT_EQ(found.size(), 1u) << h;
    EXPECT_EQ(found[0].node, node);
    EXPECT_EQ(found[0].triangle, far);
    EXPECT_EQ(found[0].side, h > 0 ? 1 : -1);
    // A previous contact with the triangle keeps its side even after the node crossed the plane.
    yarn::PenaltyContact before = found[0];
    before.side = -before.side;
    EXPECT_EQ(contactsOf(node, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {before}))[0].side, before.side);
  }
  x.segment<3>(5 * node) = c + Vec3(0, 0, 1.1 * kGamma);  // above the prism
  EXPECT_TRUE(contactsOf(node, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {})).empty());
  x.segment<3>(5 * node) = c + Vec3(0.004, 0, 0.1 * kGamma);  // beside the sheet
  EXPECT_TRUE(contactsOf(node, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {})).empty());
  // A node lifted a little above the flat sheet (a bend) lies in its own and its ring's prisms only: none.
  x = flatState(g);
  const std::size_t interior = 2 * 6 + 2;
  x.segment<3>(5 * interior) += Vec3(1e-4, 1e-4, 0.3 * kGamma);
  EXPECT_TRUE(yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {}).empty());
  // Over an edge between two triangles of one layer: one contact.
  x = flatState(g);
  const auto& tri = t.triangles[far];
  x.segment<3>(5 * node) = 0.5 * (x.segment<3>(5 * static_cast<Eigen::Index>(tri[0])) + x.segment<3>(5 * static_cast<Eigen::Index>(tri[2]))) +
                           Vec3(0, 0, 0.2 * kGamma);
  EXPECT_EQ(contactsOf(node, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {})).size(), 1u);
}

bool sameContacts(const std::vector<yarn::PenaltyContact>& a, const std::vector<yarn::PenaltyContact>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t k = 0; k < a.size(); ++k)
    if (a[k].node != b[k].node || a[k].triangle != b[k].triangle || a[k].side != b[k].side || a[k].anchor != b[k].anchor)
      return false;
  return true;
}

// Crumpled: the flat grid squeezed to 40 % in x and y with random heights of +-1.5 mm, so layers overlap.
VecX crumpledState(const YarnGrid& g, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> u(-1, 1);
  VecX x = flatState(g);
  for (std::size_t k = 0; k < g.nodeCount(); ++k) {
    const Eigen::Index i = 5 * static_cast<Eigen::Index>(k);
    x.segment<2>(i) = 0.4 * x.segment<2>(i) + 3e-4 * Vec2(u(rng), u(rng));
    x[i + 2] = 1.5e-3 * u(rng);
  }
  return x;
}

TEST(YarnPenaltyContact, HashedBroadPhaseFindsTheContactsOfAllPairs) {
  const YarnGrid g = patchGrid();
  const yarn::YarnTriangles t = yarn::yarnTriangles(g);
  std::size_t total = 0;
  for (unsigned seed = 0; seed < 5; ++seed) {
    const VecX x = crumpledState(g, seed);
    for (Real gamma : {kGamma, 0.3 * kGamma}) {
      yarn::PenaltyDetection d;
      d.gamma = gamma;
      const auto hashed = yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {});
      const auto all = yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {}, true);
      EXPECT_TRUE(sameContacts(hashed, all)) << "seed " << seed << ": " << hashed.size() << " vs " << all.size();
      d.cell = 0.1 * gamma;  // a tiny cell: boxes spill to the oversized list, the same contacts
      EXPECT_TRUE(sameContacts(yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {}), all)) << seed;
      total += all.size();
    }
  }
  EXPECT_GT(total, 20u);
  std::printf("[          ] %zu contacts over 10 crumpled states\n", total);
}

TEST(YarnPenaltyContact, DetectionIsTheSameOnOneAndTwoThreads) {
  // 70 x 70 crossings (over the 4 096 from which detection runs on all threads), crumpled as above;
  // the second detection carries sides and anchors over from the first.
  const std::vector<Vec2> square = {Vec2(0, 0), Vec2(0.0695, 0), Vec2(0.0695, 0.0695), Vec2(0, 0.0695)};
  const YarnGrid g = layYarnGrid(square, WovenFabric{});
  ASSERT_GE(g.crossings.size(), 4096u);
  const yarn::YarnTriangles t = yarn::yarnTriangles(g);
  const VecX x = crumpledState(g, 3);
  std::mt19937 rng(4);
  std::uniform_real_distribution<Real> u(-1, 1);
  VecX moved = x;
  for (Eigen::Index i = 0; i < moved.size(); i += 5) moved[i + 2] += 2e-4 * u(rng);
  yarn::PenaltyDetection d;
  d.gamma = kGamma;
  auto detect = [&](int threads) {
    test_support::ThreadScope scope(threads);
    const auto first = yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {});
    return std::make_pair(first, yarn::detectPenaltyContacts(t, g.crossings.size(), moved, d, first));
  };
  const auto one = detect(1), two = detect(2);
  EXPECT_GT(one.first.size(), 100u);
  EXPECT_TRUE(sameContacts(one.first, two.first));
  EXPECT_TRUE(sameContacts(one.second, two.second));
  EXPECT_TRUE(sameContacts(one.first, yarn::detectPenaltyContacts(t, g.crossings.size(), x, d, {}, true)));
  std::printf("[          ] %zu and %zu contacts on %zu crossings\n", one.first.size(), one.second.size(),
              g.crossings.size());
}

// ---- In the model ---------------------------------------------------------------------------------

YarnWovenOptions contactOptions() {
  YarnWovenOptions o;
  o.gravity = false;
  o.self_contact.enabled = true;
  return o;
}

// The patch with its upper-right corner crossing pressed into the prism of a far triangle.
VecX pressedState(const YarnWovenModel& m, Real h) {
  const YarnGrid& g = m.sheet().grid;
  VecX x = flatState(g);
  const auto& tri = m.selfContactTriangles().triangles.front();
  Vec3 c = Vec3::Zero();
  for (std::size_t v : tri) c += x.segment<3>(5 * static_cast<Eigen::Index>(v)) / 3;
  x.segment<3>(5 * 35) = c + Vec3(0, 0, h);
  return x;
}

TEST(YarnWovenSelfContact, ModelForcesAndDiagonalBlocksOfAPressedNode) {
  YarnWovenOptions o = contactOptions();
  o.self_contact.friction = 0;
  o.crossing.friction = false;
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = 0;
  YarnWovenOptions off = o;
  off.self_contact.enabled = false;
  const WovenFabric fabric;
  YarnWovenModel m(buildYarnSheet(patchGrid()), fabric, o), m_off(buildYarnSheet(patchGrid()), fabric, off);
  const Real gamma = 4 * fabric.yarn_radius_m, k_p = fabric.stretchStiffness() / (1 / fabric.warp_density_per_m);
  const VecX x = pressedState(m, 0.4 * gamma), v = VecX::Zero(x.size());
  VecX f, f_off;
  ForceJacobians jac = m.makeJacobians(), jac_off = m_off.makeJacobians();
  m.computeForces(x, v, f, &jac);
  m_off.computeForces(x, v, f_off, &jac_off);
  // The pressed node's contact, and others: crossings under its own triangles, stretched over the sheet.
  ASSERT_EQ(contactsOf(35, m.selfContacts()).size(), 1u);
  ASSERT_EQ(contactsOf(35, m.selfContacts())[0].triangle, 0u);
  // The model adds up the kernel's forces and blocks; the pressed node's own: k_p (gamma - d) along +z.
  VecX sum = VecX::Zero(x.size());
  Mat3 block35 = Mat3::Zero();
  for (const yarn::PenaltyContact& c : m.selfContacts()) {
    const auto& tri = m.selfContactTriangles().triangles[c.triangle];
    const PenaltyVector p = yarn::packPenaltyStencil(x, c.node, tri);
    const PenaltyVector g = yarn::penaltyGradient(p, c.side, gamma, k_p);
    const yarn::PenaltyBlocks b = yarn::penaltyStiffnessBlocks(p, c.side, gamma, k_p);
    const std::array<std::size_t, 4> nodes = {c.node, tri[0], tri[1], tri[2]};
    for (std::size_t i = 0; i < 4; ++i) {
      sum.segment<3>(5 * static_cast<Eigen::Index>(nodes[i])) -= g.segment<3>(3 * static_cast<Eigen::Index>(i));
      if (nodes[i] == 35) block35 += b.block[i];
    }
    if (c.node == 35) {
      EXPECT_LT((-g.head<3>() - Vec3(0, 0, k_p * 0.6 * gamma)).norm(), 1e-9 * k_p * gamma);
    }
  }
  EXPECT_LT((f - f_off - sum).norm(), 1e-9 * k_p * gamma);
  Vec3 resultant = Vec3::Zero();
  for (Index k = 0; k < m.numNodes(); ++k) resultant += (f - f_off).segment<3>(5 * k);
  EXPECT_LT(resultant.norm(), 1e-9 * k_p * gamma);  // the triangles take the opposite
  // Forces are minus the energy's gradient (the contact part, central differences on every position).
  for (Eigen::Index d : {Eigen::Index(5 * 35 + 2), Eigen::Index(5 * 35), Eigen::Index(2), Eigen::Index(5 + 2)}) {
    const Real h = 1e-8;
    VecX a = x, b = x;
    a[d] += h;
    b[d] -= h;
    const Real dE = (m.potentialEnergy(a) - m_off.potentialEnergy(a) - m.potentialEnergy(b) + m_off.potentialEnergy(b)) / (2 * h);
    EXPECT_NEAR(f[d] - f_off[d], -dE, 1e-5 * k_p * gamma) << d;
  }
  // The pressed node's diagonal block gains its contacts' blocks, -k_p n n^T = -k_p e_z e_z^T from its own.
  const Real* blk = jac.dfdx.block(m.jacobianPattern().diagonal(35));
  const Real* blk_off = jac_off.dfdx.block(m.jacobianPattern().diagonal(35));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(blk[r * 5 + c] - blk_off[r * 5 + c], block35(r, c), 1e-9 * k_p) << r << c;
  EXPECT_LT(block35(2, 2), -k_p + 1e-9 * k_p);
}

TEST(YarnWovenSelfContact, OptionKeysAreValidatedAndInTheFingerprint) {
  const ClothModelRegistry& r = ClothModelRegistry::instance();
  auto message = [&](const std::map<std::string, std::string>& o) {
    try {
      r.validate(ClothModelSpec("yarn_woven", o));
    } catch (const ClothModelError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(message({{"self_contact", "true"}, {"self_contact_thickness_factor", "3"}, {"self_contact_friction", "0"}}), "accepted");
  EXPECT_NE(message({{"self_contact", "maybe"}}).find("model.self_contact"), std::string::npos);
  for (const char* key : {"self_contact_thickness_factor", "self_contact_stiffness_factor"}) {
    EXPECT_NE(message({{key, "0"}}).find(std::string("model.") + key), std::string::npos) << key;
    EXPECT_NE(message({{key, "nan"}}).find(std::string("model.") + key), std::string::npos) << key;
  }
  for (const char* key : {"self_contact_damping", "self_contact_friction"})
    EXPECT_NE(message({{key, "-1"}}).find(std::string("model.") + key), std::string::npos) << key;
  const auto& d = r.find("yarn_woven");
  const ClothModelFingerprint on = d.fingerprint(r.parseOptions(ClothModelSpec("yarn_woven", {{"self_contact", "true"}})));
  const ClothModelFingerprint off = d.fingerprint(r.parseOptions(ClothModelSpec("yarn_woven", {})));
  EXPECT_NE(on.lines, off.lines);
  EXPECT_GT(on.numbers.size(), off.numbers.size());
  // The C++ API refuses bad factors naming the option.
  YarnWovenOptions o = contactOptions();
  o.self_contact.thickness_factor = -1;
  try {
    YarnWovenModel m(buildYarnSheet(patchGrid()), o.fabric, o);
    ADD_FAILURE() << "accepted";
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("self_contact_thickness_factor"), std::string::npos);
  }
}

TEST(YarnWovenSelfContact, InternalStateCarriesTheContactsAndRefusesMalformedOnes) {
  YarnWovenOptions o = contactOptions();
  YarnWovenModel m(buildYarnSheet(patchGrid()), o.fabric, o), m2(buildYarnSheet(patchGrid()), o.fabric, o);
  const VecX x = pressedState(m, 0.3e-3);
  VecX f;
  m.computeForces(x, VecX::Zero(x.size()), f, nullptr);
  VecX v = VecX::Zero(x.size());
  m.acceptStep(x, v);
  ASSERT_GE(m.selfContacts().size(), 1u);
  const std::vector<Real> s = m.internalState();
  ASSERT_TRUE(m2.setInternalState(s));
  EXPECT_EQ(m2.internalState(), s);
  EXPECT_EQ(m2.potentialEnergy(x), m.potentialEnergy(x));
  std::vector<Real> bad = s;
  bad[bad.size() - 4] = -3;  // side
  EXPECT_FALSE(m2.setInternalState(bad));
  bad = s;
  bad.pop_back();
  EXPECT_FALSE(m2.setInternalState(bad));
  bad = s;
  bad[bad.size() - 6] = 1e6;  // node
  EXPECT_FALSE(m2.setInternalState(bad));
  EXPECT_EQ(m2.internalState(), s);
  // Torn segments come last, after the contacts: both round-trip together.
  std::vector<Real> with_tear = s;
  with_tear.push_back(0);  // segment 0 torn
  with_tear.push_back(1);  // one torn segment
  ASSERT_TRUE(m2.setInternalState(with_tear));
  EXPECT_EQ(m2.tornSegmentCount(), 1u);
  EXPECT_EQ(m2.selfContacts().size(), m.selfContacts().size());
  EXPECT_EQ(m2.internalState(), with_tear);
  ASSERT_TRUE(m2.setInternalState(s));
  EXPECT_EQ(m2.tornSegmentCount(), 0u);
  // A model without self-contact refuses the longer state.
  YarnWovenOptions no = o;
  no.self_contact.enabled = false;
  YarnWovenModel m3(buildYarnSheet(patchGrid()), o.fabric, no);
  EXPECT_FALSE(m3.setInternalState(s));
}

}  // namespace
}  // namespace textile_handling
