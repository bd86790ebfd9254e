// Seam yarns (yarn_grid.h, YarnGridOptions::seam_edges): the seam piece laid through the yarn ends of
// a sewn edge, its arc lengths and DOF slots, refused seam edges, the yarn_woven model on a sheet with
// seams (forces against the energy gradient, Jacobians against finite differences, mass, and no crossing
// terms from a seam), and a hanging sheet whose sewn bias edge keeps its length. docs/yarn_model.md,
// "Seams".
#include "yarn_test_support.h"  // first: see there

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../test_support.h"
#include "sim_test_support.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

using sim_test_support::denseMatrix;
using test_support::ThreadScope;

constexpr Real kMm = 1e-3;

std::vector<Vec2> rectangle(Real w, Real h) { return {Vec2(0, 0), Vec2(w, 0), Vec2(w, h), Vec2(0, h)}; }

// A 5.2 x 5.2 mm square with its top-right corner cut along x + y = 7.5 mm (edge 2, from (5.2, 2.3) to
// (2.3, 5.2)): at 1 yarn/mm warp and weft ends alternate along the cut, half a millimetre apart in x.
std::vector<Vec2> cutSquare() {
  return {Vec2(0, 0), Vec2(5.2 * kMm, 0), Vec2(5.2 * kMm, 2.3 * kMm), Vec2(2.3 * kMm, 5.2 * kMm), Vec2(0, 5.2 * kMm)};
}

YarnGridOptions seams(std::vector<std::size_t> edges) {
  YarnGridOptions o;
  o.seam_edges = std::move(edges);
  return o;
}

std::vector<const YarnPiece*> seamPieces(const YarnGrid& g) {
  std::vector<const YarnPiece*> s;
  for (const YarnPiece& p : g.pieces)
    if (p.seam) s.push_back(&p);
  return s;
}

// The ends of g within 1e-12 m of the segment a-b, ordered by their distance from a.
std::vector<std::size_t> endsOn(const YarnGrid& g, const Vec2& a, const Vec2& b) {
  std::vector<std::pair<Real, std::size_t>> on;
  const Vec2 t = (b - a).normalized();
  for (std::size_t e = 0; e < g.ends.size(); ++e) {
    const Vec2 d = g.ends[e] - a;
    if (std::abs(d.x() * t.y() - d.y() * t.x()) < 1e-12) on.emplace_back(d.dot(t), g.crossings.size() + e);
  }
  std::sort(on.begin(), on.end());
  std::vector<std::size_t> nodes;
  for (const auto& [s, n] : on) nodes.push_back(n);
  return nodes;
}

// Whether node n is the end of a warp piece (else of a weft piece).
bool endsAWarp(const YarnGrid& g, std::size_t n) {
  for (const YarnPiece& p : g.pieces)
    if (!p.seam && (p.nodes.front() == n || p.nodes.back() == n)) return p.warp;
  ADD_FAILURE() << "node " << n << " ends no yarn";
  return false;
}

TEST(YarnSeams, OneSeamEdgeGetsOneSeamPieceThroughItsEndsInOrder) {
  const WovenFabric f;  // 1 yarn per mm
  const std::vector<Vec2> rect = rectangle(6 * kMm, 4 * kMm);
  const YarnGrid free = layYarnGrid(rect, f);
  // The top edge (2) runs from (6, 4) to (0, 4) mm: its six weft ends in decreasing x.
  const YarnGrid g = layYarnGrid(rect, f, seams({2}));
  EXPECT_EQ(g.crossings.size(), free.crossings.size());
  EXPECT_EQ(g.ends.size(), free.ends.size());  // the seam shares the ends, it adds no node
  ASSERT_EQ(g.pieces.size(), free.pieces.size() + 1);
  const std::vector<const YarnPiece*> s = seamPieces(g);
  ASSERT_EQ(s.size(), 1u);
  const YarnPiece& seam = *s[0];
  EXPECT_EQ(&seam, &g.pieces.back());  // seams come after the warp and weft pieces
  EXPECT_EQ(seam.line, 2u);
  const std::vector<std::size_t> expected = endsOn(g, rect[2], rect[3]);
  ASSERT_EQ(expected.size(), 6u);
  EXPECT_EQ(seam.nodes, expected);
  ASSERT_EQ(seam.arc_length_m.size(), 6u);
  ASSERT_EQ(seam.slide_offsets.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    const Vec2 p = g.nodePosition(seam.nodes[k]);
    EXPECT_NEAR(p.x(), (5.5 - static_cast<Real>(k)) * kMm, 1e-15);
    EXPECT_NEAR(p.y(), 4 * kMm, 1e-15);
    // Distance from the edge's first vertex (6, 4) mm; weft ends keep it in their unused u.
    EXPECT_NEAR(seam.arc_length_m[k], (0.5 + static_cast<Real>(k)) * kMm, 1e-15);
    EXPECT_EQ(seam.slide_offsets[k], 3);
    EXPECT_EQ(seam.slideOffset(k), 3);
    EXPECT_FALSE(endsAWarp(g, seam.nodes[k]));
  }
  // The sheet: rest arc lengths in the seam's slots, held (sewn), positions as without the seam.
  const YarnSheet sheet = buildYarnSheet(g);
  const YarnSheet free_sheet = buildYarnSheet(free);
  EXPECT_EQ(sheet.held_dofs, free_sheet.held_dofs);
  for (std::size_t k = 0; k < 6; ++k) {
    const std::size_t dof = 5 * seam.nodes[k] + 3;
    EXPECT_EQ(sheet.rest[static_cast<Eigen::Index>(dof)], seam.arc_length_m[k]);
    EXPECT_TRUE(std::binary_search(sheet.held_dofs.begin(), sheet.held_dofs.end(), dof));
  }
  for (std::size_t n = 0; n < sheet.nodeCount(); ++n)
    EXPECT_EQ(sheet.rest.segment<3>(static_cast<Eigen::Index>(5 * n)), free_sheet.rest.segment<3>(static_cast<Eigen::Index>(5 * n)));

  // The right edge (1) has the ends of the four warps, which keep the seam's arc length in their v.
  const YarnGrid right = layYarnGrid(rect, f, seams({1}));
  ASSERT_EQ(seamPieces(right).size(), 1u);
  const YarnPiece& r = *seamPieces(right)[0];
  EXPECT_EQ(r.nodes, endsOn(right, rect[1], rect[2]));
  ASSERT_EQ(r.nodes.size(), 4u);
  for (std::size_t k = 0; k < 4; ++k) {
    EXPECT_NEAR(r.arc_length_m[k], (0.5 + static_cast<Real>(k)) * kMm, 1e-15);
    EXPECT_EQ(r.slide_offsets[k], 4);
  }
}

TEST(YarnSeams, AlternatingWarpAndWeftEndsGetTheirOwnSlots) {
  const WovenFabric f;
  const std::vector<Vec2> cut = cutSquare();
  const YarnGrid g = layYarnGrid(cut, f, seams({2, 0}));
  const std::vector<const YarnPiece*> s = seamPieces(g);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(s[0]->line, 2u);  // in the order of seam_edges
  EXPECT_EQ(s[1]->line, 0u);
  const YarnPiece& diagonal = *s[0];
  const std::vector<std::size_t> on_cut = endsOn(g, cut[2], cut[3]);
  ASSERT_EQ(on_cut.size(), 6u);  // warps at y = 2.5, 3.5, 4.5 mm and wefts at x = 4.5, 3.5, 2.5 mm
  EXPECT_EQ(diagonal.nodes, on_cut);
  for (std::size_t k = 0; k < 6; ++k) {
    // From (5.2, 2.3) mm: the warp end at x = 5 mm first, then a weft end, each sqrt(2) / 2 mm on.
    const bool warp = k % 2 == 0;
    EXPECT_EQ(endsAWarp(g, diagonal.nodes[k]), warp) << k;
    EXPECT_EQ(diagonal.slide_offsets[k], warp ? 4 : 3) << k;
    EXPECT_NEAR(diagonal.arc_length_m[k], std::sqrt(2.0) * (0.2 + 0.5 * static_cast<Real>(k)) * kMm, 1e-15) << k;
  }
  const YarnSheet sheet = buildYarnSheet(g);
  for (std::size_t k = 0; k < 6; ++k)
    EXPECT_EQ(sheet.rest[static_cast<Eigen::Index>(5 * diagonal.nodes[k] + static_cast<std::size_t>(diagonal.slide_offsets[k]))],
              diagonal.arc_length_m[k]);
  // The bottom edge's five weft ends.
  EXPECT_EQ(s[1]->nodes, endsOn(g, cut[0], cut[1]));
  EXPECT_EQ(s[1]->nodes.size(), 5u);
}

TEST(YarnSeams, AnEdgeWithFewerThanTwoEndsGetsNoSeam) {
  const WovenFabric f;
  // 1 x 3 mm: one weft, so the bottom and top edges have one end each; the sides have three.
  const YarnGrid g = layYarnGrid(rectangle(1 * kMm, 3 * kMm), f, seams({0, 1, 2}));
  const std::vector<const YarnPiece*> s = seamPieces(g);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_EQ(s[0]->line, 1u);
  EXPECT_EQ(s[0]->nodes.size(), 3u);
}

TEST(YarnSeams, BadSeamEdgesAndSeamPiecesAreRefusedNamingThem) {
  const WovenFabric f;
  auto message = [&](const std::vector<Vec2>& outline, std::vector<std::size_t> edges) {
    try {
      layYarnGrid(outline, f, seams(std::move(edges)));
    } catch (const SimError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  const std::vector<Vec2> rect = rectangle(4 * kMm, 4 * kMm);
  EXPECT_EQ(message(rect, {0, 3}), "accepted");
  EXPECT_NE(message(rect, {0, 4}).find("seam_edges[1] = 4: the outline has 4 edges (0 to 3)"), std::string::npos)
      << message(rect, {0, 4});
  EXPECT_NE(message(rect, {2, 1, 2}).find("seam_edges[2] = 2 repeats seam_edges[0]"), std::string::npos)
      << message(rect, {2, 1, 2});
  // A hand-made seam through a crossing, or on a slot a yarn already uses, is refused by the sheet.
  YarnGrid g = layYarnGrid(rect, f, seams({0}));
  YarnGrid through = g;
  through.pieces.back().nodes[1] = 0;
  try {
    buildYarnSheet(through);
    ADD_FAILURE() << "accepted";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("runs through crossing 0"), std::string::npos) << e.what();
  }
  YarnGrid clash = g;
  clash.pieces.back().slide_offsets[0] = 4;  // a weft end's v is its own weft's arc length
  try {
    buildYarnSheet(clash);
    ADD_FAILURE() << "accepted";
  } catch (const SimError& e) {
    EXPECT_NE(std::string(e.what()).find("piece " + std::to_string(g.pieces.size() - 1) + " uses the v of node"),
              std::string::npos)
        << e.what();
  }
}

// The cut square with seams on its bottom edge and along the cut, as a yarn_woven model.
YarnWovenModel seamedModel(YarnWovenOptions o, std::vector<std::size_t> edges = {0, 2}) {
  return YarnWovenModel(buildYarnSheet(layYarnGrid(cutSquare(), o.fabric, seams(std::move(edges)))), o.fabric, o);
}

VecX restPositions(const YarnWovenModel& m) {
  VecX x = VecX::Zero(m.numDofs());
  for (Index i = 0; i < m.numNodes(); ++i) x.segment<3>(5 * i) = m.sheet().rest.segment<3>(5 * i);
  return x;
}

// Positions moved by up to 0.15 mm, free sliding DOFs by up to 0.1 mm.
VecX perturbed(const YarnWovenModel& m, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<Real> u(-1, 1);
  VecX x = restPositions(m);
  for (Index d = 0; d < x.size(); ++d)
    if (!m.isHeld(d)) x[d] += (d % 5 < 3 ? 1.5e-4 : 1e-4) * u(rng);
  return x;
}

TEST(YarnSeams, AFlatSeamedSheetFeelsOnlyItsWeight) {
  YarnWovenOptions o;
  YarnWovenModel m = seamedModel(o);
  const VecX x = restPositions(m), v = VecX::Zero(x.size());
  VecX f;
  m.computeForces(x, v, f, nullptr);
  Vec3 total = Vec3::Zero();
  for (Index i = 0; i < m.numNodes(); ++i) total += f.segment<3>(5 * i);
  EXPECT_NEAR(total.z(), -m.totalMass() * kGravity, 1e-12 * m.totalMass() * kGravity);
  EXPECT_LT(total.head<2>().norm(), 1e-12 * m.totalMass() * kGravity);
  // Every seam segment at its rest length: no elastic force anywhere.
  o.gravity = false;
  YarnWovenModel weightless = seamedModel(o);
  weightless.computeForces(x, v, f, nullptr);
  EXPECT_LT(f.cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_NEAR(weightless.maxEdgeStretch(x), 1.0, 1e-12);
}

TEST(YarnSeams, ForcesAreMinusTheEnergyGradientAndSeamsAddNoCrossingTerms) {
  YarnWovenOptions o;
  o.fabric.damping_mass_per_s = o.fabric.damping_stiffness_s = 0;
  o.fabric.sliding_friction = 0;  // friction is not conservative
  o.fabric.young_modulus_pa = 1e5;  // stretch and bending of one order
  YarnWovenModel m = seamedModel(o);
  const VecX x = perturbed(m, 3);
  const VecX v = VecX::Zero(x.size());
  VecX f;
  m.computeForces(x, v, f, nullptr);
  const Real h = 1e-9;
  Real worst = 0, scale = 0;
  for (Index d = 0; d < x.size(); ++d) {
    if (m.isHeld(d)) {
      EXPECT_EQ(f[d], 0) << "held DOF " << d;
      continue;
    }
    VecX a = x, b = x;
    a[d] += h;
    b[d] -= h;
    worst = std::max(worst, std::abs(-(m.potentialEnergy(a) - m.potentialEnergy(b)) / (2 * h) - f[d]));
    scale = std::max(scale, std::abs(f[d]));
  }
  EXPECT_GT(scale, 1e-4);
  EXPECT_LT(worst, 1e-6 * scale);

  // The seams add exactly their yarns' stretch, bending and gravity (same nodes, same DOFs): no shear
  // pair, contact or sliding friction. Friction on, so a crossing term from a seam would show.
  YarnWovenOptions with_friction = o;
  with_friction.fabric.sliding_friction = 0.3;
  YarnWovenModel seamed = seamedModel(with_friction), free = seamedModel(with_friction, {});
  ASSERT_EQ(seamed.numDofs(), free.numDofs());
  YarnGrid seams_only = seamed.sheet().grid;
  seams_only.pieces.erase(std::remove_if(seams_only.pieces.begin(), seams_only.pieces.end(),
                                         [](const YarnPiece& p) { return !p.seam; }),
                          seams_only.pieces.end());
  ASSERT_EQ(seams_only.pieces.size(), 2u);
  const YarnSheet seam_sheet = buildYarnSheet(seams_only);
  const VecX q = seamed.kernelCoordinates(x);
  VecX seam_gradient;
  const Real seam_energy = yarnSheetEnergy(seam_sheet, with_friction.fabric, q, Vec3(0, 0, -kGravity), &seam_gradient);
  VecX fs, ff;
  seamed.computeForces(x, v, fs, nullptr);
  free.computeForces(x, v, ff, nullptr);
  for (std::size_t d : seamed.sheet().held_dofs) seam_gradient[static_cast<Eigen::Index>(d)] = 0;
  EXPECT_GT(seam_gradient.cwiseAbs().maxCoeff(), 1e-3 * scale);
  EXPECT_LT((fs - ff + seam_gradient).cwiseAbs().maxCoeff(), 1e-12 * fs.cwiseAbs().maxCoeff());
  EXPECT_NEAR(seamed.potentialEnergy(x) - free.potentialEnergy(x), seam_energy, 1e-12 * std::abs(seamed.potentialEnergy(x)));
}

TEST(YarnSeams, JacobiansMatchFiniteDifferences) {
  YarnWovenOptions o;
  o.exact_hessian = true;
  o.fabric.young_modulus_pa = 1e5;
  YarnWovenModel m = seamedModel(o);
  const VecX x = perturbed(m, 7);
  const Eigen::MatrixXd dfdx =
      yarn_test_support::expectJacobiansMatchFiniteDifferences(m, x, VecX::Zero(x.size()), 1e-9, 1e-3, 1e-5, 1e-7).dfdx;
  // Two neighbouring ends on the bottom seam are coupled only through the seam.
  const YarnPiece& bottom = *seamPieces(m.sheet().grid)[0];
  ASSERT_EQ(bottom.line, 0u);
  const Index a = static_cast<Index>(bottom.nodes[1]), b = static_cast<Index>(bottom.nodes[2]);
  EXPECT_GT(dfdx.block(5 * a, 5 * b, 3, 3).cwiseAbs().maxCoeff(), 1e-3 * dfdx.cwiseAbs().maxCoeff());
}

TEST(YarnSeams, MassIsPositiveDefiniteAndCarriesTheSeams) {
  const YarnWovenOptions o;
  const YarnWovenModel m = seamedModel(o), free = seamedModel(o, {});
  const VecX x = perturbed(m, 5);
  const Eigen::MatrixXd M = yarn_test_support::expectSymmetricPositiveDefiniteMass(m, x);
  // The seams' yarn: the bottom edge's from x = 0.5 to 4.5 mm and the cut's 2.5 sqrt(2) mm.
  const Real seam_length = 4 * kMm + 2.5 * std::sqrt(2.0) * kMm;
  EXPECT_NEAR(m.totalMass() - free.totalMass(), o.fabric.linear_density_kg_per_m * seam_length, 1e-18);
  VecX u = VecX::Zero(x.size());
  for (Index i = 0; i < m.numNodes(); ++i) u[5 * i + 2] = 1;
  EXPECT_NEAR(m.kineticEnergy(x, u), 0.5 * m.totalMass(), 1e-12 * m.totalMass());
}


struct EdgeFigures {
  Real max_gap_ratio = 0;  ///< largest distance between neighbouring ends on the edge over its flat value
  Real max_bow = 0;        ///< largest distance of an end on the edge from the line through its first and last [m]
};

// Hangs `outline` (the default fabric, 1 yarn/mm) for one second from the first and last yarn ends on
// its edge `edge`, with or without a seam there, and measures the ends along that edge.
EdgeFigures hangFromEdge(const std::vector<Vec2>& outline, std::size_t edge, bool sewn) {
  YarnWovenOptions o;
  YarnWovenModel m(buildYarnSheet(layYarnGrid(outline, o.fabric, sewn ? seams({edge}) : YarnGridOptions())), o.fabric, o);
  const YarnGrid& g = m.sheet().grid;
  const VecX x0 = restPositions(m);
  const std::vector<std::size_t> ends = endsOn(g, outline[edge], outline[(edge + 1) % outline.size()]);
  PinnedNodes pins;
  for (std::size_t n : {ends.front(), ends.back()}) {
    pins.nodes.push_back(static_cast<Index>(n));
    pins.anchors.push_back(x0.segment<3>(5 * static_cast<Eigen::Index>(n)));
  }
  DrapeSimulation sim(m, pins, yarn_test_support::fixedSteps(IntegratorType::kSemiImplicitEuler, 1e-3, 1.0), x0, VecX::Zero(x0.size()));
  const RunResult r = sim.run();
  EXPECT_FALSE(r.diverged) << r.divergence_reason;
  const VecX& x = sim.state();
  auto at = [](const VecX& s, std::size_t n) { return Vec3(s.segment<3>(5 * static_cast<Eigen::Index>(n))); };
  EdgeFigures e;
  for (std::size_t k = 0; k + 1 < ends.size(); ++k)
    e.max_gap_ratio = std::max(e.max_gap_ratio, (at(x, ends[k + 1]) - at(x, ends[k])).norm() /
                                                    (at(x0, ends[k + 1]) - at(x0, ends[k])).norm());
  const Vec3 a = at(x, ends.front()), t = (at(x, ends.back()) - a).normalized();
  for (std::size_t n : ends) e.max_bow = std::max(e.max_bow, (at(x, n) - a).cross(t).norm());
  std::printf("%s: %zu ends on the edge, largest gap %.5f times its flat value, largest bow %.1f um\n",
              sewn ? "sewn" : "free", ends.size(), e.max_gap_ratio, e.max_bow / 1e-6);
  return e;
}

TEST(YarnSeams, ASewnBiasEdgeKeepsItsLengthWhileAFreeOneStretches) {
  ThreadScope threads(1);
  // A square of side 4.3 sqrt(2) mm turned by 45 degrees against the yarns, hung from the two ends of
  // its lower-right edge (1): that bias edge carries the sheet's weight. Free, its yarn ends are held
  // together only through the crossings, which shear, and the edge stretches (observed: largest gap
  // 1.064 times its flat value, an end 0.17 mm off the line between the pins); sewn, the seam yarn
  // keeps them at their spacing (1.00001, 0.01 mm).
  const Real a = 4.3 * kMm;
  const std::vector<Vec2> diamond = {Vec2(0, a), Vec2(a, 0), Vec2(2 * a, a), Vec2(a, 2 * a)};
  const EdgeFigures free = hangFromEdge(diamond, 1, false), sewn = hangFromEdge(diamond, 1, true);
  EXPECT_GT(free.max_gap_ratio, 1.03);
  EXPECT_LT(sewn.max_gap_ratio, 1.001);
  EXPECT_GT(free.max_bow, 5 * sewn.max_bow);
}

}  // namespace
}  // namespace textile_handling
