// The ClothModel defaults: lumped mass operations, the CG mass solve for non-lumped models, and the
// position gather/scatter of the DOF layout contract (cloth_model.h).
#include "textile_handling/sim/cloth_model.h"

#include <cmath>

#include <Eigen/LU>

#include "textile_handling/sim/integrators.h"

namespace textile_handling {

void ClothModel::addMassMatrix(const VecX& /*x*/, Real scale, BlockSparseMatrix& a) const {
  const BlockPattern& p = a.pattern();
  const int b = p.blockSize();
  const VecX& m = massPerDof();
  for (Index i = 0; i < p.numNodes(); ++i) {
    Real* blk = a.block(p.diagonal(i));
    for (int r = 0; r < b; ++r) blk[r * b + r] += scale * m[i * b + r];
  }
}

void ClothModel::multiplyMass(const VecX& /*x*/, const VecX& v, VecX& mv) const { mv = massPerDof().cwiseProduct(v); }

bool ClothModel::solveMass(const VecX& x, const VecX& f, const std::vector<char>& node_pinned, VecX& a) const {
  if (!hasLumpedMass()) return massSolveByConjugateGradients(*this, x, f, node_pinned, a);
  a = f;
  a.array() /= massPerDof().array();
  const int b = dofsPerNode();
  for (Index i = 0; i < static_cast<Index>(node_pinned.size()); ++i)
    if (node_pinned[i]) a.segment(i * b, b).setZero();
  return true;
}

Real ClothModel::kineticEnergy(const VecX& x, const VecX& v) const {
  if (hasLumpedMass()) return 0.5 * (massPerDof().array() * v.array().square()).sum();
  VecX mv;
  multiplyMass(x, v, mv);
  return 0.5 * deterministicDot(v, mv);
}

Real ClothModel::gravitationalEnergy(const VecX& x) const {
  const int b = dofsPerNode();
  const VecX& m = massPerDof();
  Real e = 0;
  for (Index i = 0; i < numNodes(); ++i) e += m[i * b + 2] * kGravity * x[i * b + 2];
  return e;
}

Real ClothModel::totalMass() const {
  const int b = dofsPerNode();
  Real total = 0;
  for (Index i = 0; i < numNodes(); ++i) total += massPerDof()[i * b];
  return total;
}

VecX ClothModel::positionsOf(const VecX& x) const {
  const int b = dofsPerNode();
  if (b == 3) return x;
  VecX p(3 * static_cast<Eigen::Index>(numNodes()));
  for (Index i = 0; i < numNodes(); ++i) p.segment<3>(3 * i) = x.segment<3>(static_cast<Eigen::Index>(i) * b);
  return p;
}

void ClothModel::setPositions(const VecX& p, VecX& x) const {
  const int b = dofsPerNode();
  if (b == 3) {
    x = p;
    return;
  }
  for (Index i = 0; i < numNodes(); ++i) x.segment<3>(static_cast<Eigen::Index>(i) * b) = p.segment<3>(3 * i);
}

bool massSolveByConjugateGradients(const ClothModel& model, const VecX& x, const VecX& f,
                                   const std::vector<char>& node_pinned, VecX& a) {
  const BlockPattern& p = model.jacobianPattern();
  const int b = p.blockSize();
  const Index n = p.numNodes();
  BlockSparseMatrix m(&p);
  m.setZero();
  model.addMassMatrix(x, 1.0, m);
  auto pinned = [&](Index i) { return i < static_cast<Index>(node_pinned.size()) && node_pinned[i]; };
  auto filter = [&](VecX& y) {
    for (Index i = 0; i < n; ++i)
      if (pinned(i)) y.segment(i * b, b).setZero();
  };
  // Block-Jacobi preconditioner: inverses of the free nodes' diagonal mass blocks.
  std::vector<Eigen::MatrixXd> inv(n);
  for (Index i = 0; i < n; ++i) {
    if (pinned(i)) continue;
    Eigen::Map<const Eigen::Matrix<Real, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> blk(m.block(p.diagonal(i)), b, b);
    Eigen::FullPivLU<Eigen::MatrixXd> lu(blk);
    if (!lu.isInvertible()) return false;
    inv[i] = lu.inverse();
  }
  auto precondition = [&](const VecX& r, VecX& z) {
    z.setZero(r.size());
    for (Index i = 0; i < n; ++i)
      if (!pinned(i)) z.segment(i * b, b) = inv[i] * r.segment(i * b, b);
  };
  VecX r = f;
  filter(r);
  a.setZero(f.size());
  const Real stop = 1e-12 * std::max(std::sqrt(deterministicDot(r, r)), 1e-300);
  VecX z, q, mq;
  precondition(r, z);
  q = z;
  Real rz = deterministicDot(r, z);
  for (Index it = 0; it <= model.numDofs(); ++it) {
    if (std::sqrt(deterministicDot(r, r)) <= stop) return true;
    m.multiply(q, mq);
    filter(mq);
    const Real qmq = deterministicDot(q, mq);
    if (!(qmq > 0) || !(rz > 0)) return false;
    const Real alpha = rz / qmq;
    a += alpha * q;
    r -= alpha * mq;
    precondition(r, z);
    const Real rz_new = deterministicDot(r, z);
    q = z + (rz_new / rz) * q;
    rz = rz_new;
  }
  return false;
}

}  // namespace textile_handling
