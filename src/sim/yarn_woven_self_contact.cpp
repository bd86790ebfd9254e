// The yarn_woven model's penalty self-contact on extruded triangles (yarn_woven_model.h; kernels and
// detection in yarn_penalty_contact.h; docs/yarn_model.md, "Collisions"). Contacts are detected at the
// first state the model sees and after every accepted step (lagged, like F_n), never within a step, so
// the forces stay smooth inside a step; their forces are evaluated at every force evaluation.
#include <cmath>
#include <string>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {

namespace {
constexpr int kB = kYarnDofsPerNode;
// Values per contact in the internal state: node, triangle, side, anchor (3).
constexpr std::size_t kContactValues = 6;
}  // namespace

std::string yarnSelfContactErrors(const YarnSelfContactOptions& o) {
  auto bad = [](Real v, bool strict) { return !std::isfinite(v) || (strict ? !(v > 0) : !(v >= 0)); };
  if (bad(o.thickness_factor, true)) return "self_contact_thickness_factor must be finite and > 0";
  if (bad(o.stiffness_factor, true)) return "self_contact_stiffness_factor must be finite and > 0";
  if (bad(o.damping, false)) return "self_contact_damping must be finite and >= 0";
  if (!std::isfinite(o.friction)) return "self_contact_friction must be finite";
  return "";
}

void YarnWovenModel::buildSelfContact() {
  const YarnSelfContactOptions& o = options_.self_contact;
  if (!o.enabled) return;
  const std::string errors = yarnSelfContactErrors(o);
  if (!errors.empty()) throw SimError("yarn_woven: " + errors);
  triangles_ = yarn::yarnTriangles(sheet_.grid);
  gamma_ = o.thickness_factor * fabric_.yarn_radius_m;
  k_p_ = o.stiffness_factor * fabric_.stretchStiffness() / spacing_;
  const std::size_t crossings = sheet_.grid.crossings.size();
  const Real node_mass = crossings > 0 ? total_mass_ / static_cast<Real>(crossings) : 0;
  d_p_ = o.damping * 2 * std::sqrt(k_p_ * node_mass);
  mu_p_ = o.friction >= 0 ? o.friction : fabric_.sliding_friction;
}

void YarnWovenModel::detectSelfContacts(const VecX& x) {
  if (!options_.self_contact.enabled) return;
  yarn::PenaltyDetection d;
  d.gamma = gamma_;
  self_contacts_ = yarn::detectPenaltyContacts(triangles_, sheet_.grid.crossings.size(), x, d, self_contacts_);
  self_contacts_detected_ = true;
}

void YarnWovenModel::addSelfContactForces(const VecX& x, const VecX& v, VecX* f, BlockSparseMatrix* dfdx,
                                          BlockSparseMatrix* dfdv) const {
  // The stick spring of the contact friction is as stiff as the penalty (k_t = k_p).
  const Real k_t = k_p_;
  auto addBlock = [&](BlockSparseMatrix* a, std::size_t node, const Mat3& m) {
    Real* blk = a->block(pattern_.diagonal(static_cast<Index>(node)));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) blk[r * kB + c] += m(r, c);
  };
  for (const yarn::PenaltyContact& c : self_contacts_) {
    const auto& tri = triangles_.triangles[c.triangle];
    const std::array<std::size_t, 4> nodes = {c.node, tri[0], tri[1], tri[2]};
    const yarn::PenaltyVector p = yarn::packPenaltyStencil(x, c.node, tri);
    if (yarn::penaltyDistance(p, c.side, gamma_) <= 0) continue;
    const yarn::PenaltyFriction fr = mu_p_ > 0 ? yarn::penaltyFriction(p, c.anchor, c.side, gamma_, k_p_, k_t, mu_p_)
                                               : yarn::PenaltyFriction{};
    if (f) {
      const yarn::PenaltyVector pv = yarn::packPenaltyStencil(v, c.node, tri);
      const yarn::PenaltyVector force = -yarn::penaltyGradient(p, c.side, gamma_, k_p_) +
                                        yarn::penaltyDampingForce(p, pv, c.side, gamma_, d_p_) + fr.force;
      for (std::size_t i = 0; i < 4; ++i) f->segment<3>(static_cast<Eigen::Index>(kB * nodes[i])) += force.segment<3>(3 * static_cast<Eigen::Index>(i));
    }
    if (dfdx) {
      const yarn::PenaltyBlocks k = yarn::penaltyStiffnessBlocks(p, c.side, gamma_, k_p_);
      for (std::size_t i = 0; i < 4; ++i) addBlock(dfdx, nodes[i], k.block[i] + fr.blocks.block[i]);
    }
    if (dfdv) {
      const yarn::PenaltyBlocks d = yarn::penaltyDampingBlocks(p, c.side, gamma_, d_p_);
      for (std::size_t i = 0; i < 4; ++i) addBlock(dfdv, nodes[i], d.block[i]);
    }
  }
}

Real YarnWovenModel::selfContactEnergy(const VecX& x) const {
  Real e = 0;
  for (const yarn::PenaltyContact& c : self_contacts_)
    e += yarn::penaltyEnergy(yarn::packPenaltyStencil(x, c.node, triangles_.triangles[c.triangle]), c.side, gamma_, k_p_);
  return e;
}

void YarnWovenModel::acceptSelfContacts(const VecX& x) {
  if (!options_.self_contact.enabled) return;
  if (mu_p_ > 0)
    for (yarn::PenaltyContact& c : self_contacts_)
      c.anchor = yarn::penaltyFrictionAnchor(yarn::packPenaltyStencil(x, c.node, triangles_.triangles[c.triangle]), c.anchor,
                                             c.side, gamma_, k_p_, k_p_, mu_p_);
  detectSelfContacts(x);
}

void YarnWovenModel::appendSelfContactState(std::vector<Real>& s) const {
  if (!options_.self_contact.enabled) return;
  s.push_back(self_contacts_detected_ ? 1 : 0);
  s.push_back(static_cast<Real>(self_contacts_.size()));
  for (const yarn::PenaltyContact& c : self_contacts_) {
    s.push_back(static_cast<Real>(c.node));
    s.push_back(static_cast<Real>(c.triangle));
    s.push_back(c.side);
    s.insert(s.end(), c.anchor.begin(), c.anchor.end());
  }
}

bool YarnWovenModel::readSelfContactState(const std::vector<Real>& s, std::size_t from,
                                          std::vector<yarn::PenaltyContact>* contacts, bool* detected,
                                          std::size_t* end) const {
  contacts->clear();
  *detected = false;
  *end = from;
  if (!options_.self_contact.enabled) return true;
  if (s.size() < from + 2 || (s[from] != 0 && s[from] != 1)) return false;
  const Real count = s[from + 1];
  if (!(count >= 0) || count != std::floor(count) ||
      static_cast<Real>(s.size() - from - 2) < kContactValues * count)
    return false;
  const std::size_t stop = from + 2 + kContactValues * static_cast<std::size_t>(count);
  auto isIndex = [](Real r, std::size_t size) { return r >= 0 && r == std::floor(r) && r < static_cast<Real>(size); };
  for (std::size_t k = from + 2; k < stop; k += kContactValues) {
    yarn::PenaltyContact c;
    if (!isIndex(s[k], sheet_.grid.crossings.size()) || !isIndex(s[k + 1], triangles_.triangles.size())) return false;
    if (s[k + 2] != 1 && s[k + 2] != -1) return false;
    c.node = static_cast<std::size_t>(s[k]);
    c.triangle = static_cast<std::size_t>(s[k + 1]);
    c.side = static_cast<int>(s[k + 2]);
    c.anchor = {s[k + 3], s[k + 4], s[k + 5]};
    contacts->push_back(c);
  }
  *detected = s[from] == 1;
  *end = stop;
  return true;
}

}  // namespace textile_handling
