// A small 5-DOF cloth model for the tests of the open model interface (cloth_model.h): the particle
// model's nodes with two extra "sliding" coordinates (u, w) each, a non-diagonal mass and optional
// coupling between the sliding coordinates and the positions.
//
// Node block [x y z u w]. Mass, constant (so there are no quadratic-velocity terms):
//   M_ii = [[m I3, c m B], [c m B^T, m I2]],  B = [e_x e_y] (3 x 2),
//   M_ij (i, j coupled in the particle pattern, i != j): eps m on the (u, u) entry,
// symmetric positive definite for c < 1 and small eps. The sliding coordinates carry a spring and a
// damper, f_uw = -k (u, w) - d (u', w'); positions carry the particle model's forces. With c = eps = 0
// the positions move exactly like the 3-DOF particle model's; with coupling only the dynamics change,
// the rest shape (an equilibrium) does not.
#pragma once

#include <any>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/particle_cloth_model.h"

namespace textile_handling {
namespace testing_models {

struct SlidingParticleOptions {
  ParticleModelOptions particle;
  Real coupling = 0.3;        ///< c
  Real neighbour_mass = 0.02; ///< eps
  Real spring = 50.0;         ///< k [N/m per unit of u]
  Real damper = 0.5;          ///< d
};

class SlidingParticleModel : public ClothModel {
 public:
  static constexpr int kB = 5;
  SlidingParticleModel(const ParticleTopology& topology, const Material& material, SlidingParticleOptions options)
      : inner_(topology, material, options.particle), o_(options) {
    const Index n = inner_.numNodes();
    const BlockPattern& p3 = inner_.jacobianPattern();
    std::vector<std::pair<Index, Index>> couplings;
    for (Index i = 0; i < n; ++i)
      for (Index k = p3.rowStart()[i]; k < p3.rowStart()[i + 1]; ++k)
        if (p3.column()[k] != i) couplings.emplace_back(i, p3.column()[k]);
    pattern_ = BlockPattern(n, kB, couplings);
    lumped_.resize(n * kB);
    for (Index i = 0; i < n; ++i) lumped_.segment(i * kB, kB).setConstant(inner_.massPerDof()[3 * i]);
    jac3_ = inner_.makeJacobians();
  }

  std::string name() const override { return "test_sliding_particles"; }
  Index numNodes() const override { return inner_.numNodes(); }
  int dofsPerNode() const override { return kB; }
  const BlockPattern& jacobianPattern() const override { return pattern_; }
  bool hasLumpedMass() const override { return o_.coupling == 0 && o_.neighbour_mass == 0; }
  const VecX& massPerDof() const override { return lumped_; }

  void addMassMatrix(const VecX& /*x*/, Real scale, BlockSparseMatrix& a) const override {
    const BlockPattern& p = a.pattern();
    for (Index i = 0; i < numNodes(); ++i) {
      const Real m = lumped_[i * kB];
      for (Index k = p.rowStart()[i]; k < p.rowStart()[i + 1]; ++k) {
        Real* blk = a.block(k);
        const Index j = p.column()[k];
        if (j == i) {
          for (int r = 0; r < kB; ++r) blk[r * kB + r] += scale * m;
          for (int c = 0; c < 2; ++c) {  // c m B: x <-> u, y <-> w
            blk[c * kB + 3 + c] += scale * o_.coupling * m;
            blk[(3 + c) * kB + c] += scale * o_.coupling * m;
          }
        } else {
          blk[3 * kB + 3] += scale * o_.neighbour_mass * 0.5 * (m + lumped_[j * kB]);
        }
      }
    }
  }
  void multiplyMass(const VecX& x, const VecX& v, VecX& mv) const override {
    BlockSparseMatrix m(&pattern_);
    m.setZero();
    addMassMatrix(x, 1.0, m);
    m.multiply(v, mv);
  }
  // solveMass, kineticEnergy, gravitationalEnergy and totalMass: ClothModel's defaults (CG on the
  // assembled mass, 1/2 v^T M v through multiplyMass), which these tests thereby exercise.

  ForceReport computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) override {
    const VecX x3 = positionsOf(x), v3 = positionsOf(v);
    VecX f3;
    const ForceReport rep = inner_.computeForces(x3, v3, f3, jac ? &jac3_ : nullptr);
    f.setZero(numDofs());
    setPositions(f3, f);
    for (Index i = 0; i < numNodes(); ++i)
      f.segment<2>(i * kB + 3) = -o_.spring * x.segment<2>(i * kB + 3) - o_.damper * v.segment<2>(i * kB + 3);
    if (jac) {
      jac->dfdx.setZero();
      jac->dfdv.setZero();
      copyBlocks(jac3_.dfdx, jac->dfdx, -o_.spring);
      copyBlocks(jac3_.dfdv, jac->dfdv, -o_.damper);
    }
    return rep;
  }
  Real potentialEnergy(const VecX& x) const override {
    Real e = inner_.potentialEnergy(positionsOf(x));
    for (Index i = 0; i < numNodes(); ++i) e += 0.5 * o_.spring * x.segment<2>(i * kB + 3).squaredNorm();
    return e;
  }
  Real maxEdgeStretch(const VecX& x) const override { return inner_.maxEdgeStretch(positionsOf(x)); }

 private:
  // The 3 x 3 blocks of the particle model's Jacobian into the position part of the 5 x 5 blocks, and
  // `sliding` on the diagonal of the sliding part of the diagonal blocks.
  void copyBlocks(const BlockSparseMatrix& from, BlockSparseMatrix& to, Real sliding) const {
    const BlockPattern& p3 = from.pattern();
    for (Index i = 0; i < numNodes(); ++i)
      for (Index k = p3.rowStart()[i]; k < p3.rowStart()[i + 1]; ++k) {
        const Index j = p3.column()[k];
        const Real* src = from.block(k);
        Real* dst = to.block(pattern_.find(i, j));
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) dst[r * kB + c] = src[r * 3 + c];
        if (i == j) dst[3 * kB + 3] = dst[4 * kB + 4] = sliding;
      }
  }

  ParticleClothModel inner_;
  SlidingParticleOptions o_;
  BlockPattern pattern_;
  VecX lumped_;
  ForceJacobians jac3_;
};

/// Registers "test_sliding_particles" once (options: the particle model's keys plus coupling,
/// neighbour_mass, spring, damper).
inline void registerSlidingParticleModel() {
  ClothModelRegistry& registry = ClothModelRegistry::instance();
  if (registry.contains("test_sliding_particles")) return;
  ClothModelDescriptor d;
  d.name = "test_sliding_particles";
  d.summary = "test model: particles with two sliding coordinates and a non-diagonal mass";
  d.dofs_per_node = SlidingParticleModel::kB;
  const ClothModelDescriptor particle = registry.find("particle_kes");
  d.option_keys = particle.option_keys;
  for (const char* k : {"coupling", "neighbour_mass", "spring", "damper"}) d.option_keys.emplace_back(k, "number");
  d.parse_options = [particle](const std::map<std::string, std::string>& values) {
    std::map<std::string, std::string> own, rest;
    for (const auto& [k, v] : values)
      (k == "coupling" || k == "neighbour_mass" || k == "spring" || k == "damper" ? own : rest)[k] = v;
    SlidingParticleOptions o;
    o.particle = std::any_cast<ParticleModelOptions>(particle.parse_options(rest));
    ModelOptionReader r("test_sliding_particles", own);
    r.readRealInRange("coupling", 0, 1, true, &o.coupling);
    r.readRealInRange("neighbour_mass", 0, 0.05, false, &o.neighbour_mass);
    r.readReal("spring", 0, true, &o.spring);
    r.readReal("damper", 0, false, &o.damper);
    r.finish();
    return std::any(o);
  };
  d.create = [](const ParticleTopology& t, const Material& m, const std::any& o) {
    return std::unique_ptr<ClothModel>(new SlidingParticleModel(t, m, std::any_cast<const SlidingParticleOptions&>(o)));
  };
  d.fingerprint = [particle](const std::any& o) {
    const auto& s = std::any_cast<const SlidingParticleOptions&>(o);
    ClothModelFingerprint f = particle.fingerprint(std::any(s.particle));
    f.numbers.emplace_back("model_options.coupling", s.coupling);
    f.numbers.emplace_back("model_options.neighbour_mass", s.neighbour_mass);
    f.numbers.emplace_back("model_options.spring", s.spring);
    f.numbers.emplace_back("model_options.damper", s.damper);
    return f;
  };
  registry.add(std::move(d));
}

}  // namespace testing_models
}  // namespace textile_handling
