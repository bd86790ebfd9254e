// Contact-force feedback of the proximity stage into the implicit solve. See docs/collision.md.
#include "textile_handling/sim/contact_force_model.h"
#include "textile_handling/sim/sim_errors.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>
#include <memory>

namespace textile_handling {

ContactForceModel::ContactForceModel(std::unique_ptr<ClothModel> base, SelfCollisionPass& pass)
    : owned_(std::move(base)), base_(*owned_), pass_(pass) {
  if (base_.numNodes() != pass_.triangles().num_vertices || base_.dofsPerNode() != 3)
    throw SimError("ContactForceModel: the model does not match the self-collision pass");
  pass_.force_feedback_ = true;
}

ContactForceModel::ContactForceModel(ClothModel& base, SelfCollisionPass& pass) : base_(base), pass_(pass) {
  if (base_.numNodes() != pass_.triangles().num_vertices || base_.dofsPerNode() != 3)
    throw SimError("ContactForceModel: the model does not match the self-collision pass");
  pass_.force_feedback_ = true;
}

std::unique_ptr<ClothModel> withContactForces(std::unique_ptr<ClothModel> model, SelfCollisionPass& pass) {
  const SelfCollisionOptions& o = pass.options();
  if (!model || o.version != SelfCollisionVersion::kRollback || !o.proximity || !o.contact_forces) return model;
  if (model->dofsPerNode() != 3 || model->numNodes() != pass.triangles().num_vertices) return model;
  if (const auto* c = dynamic_cast<const ContactForceModel*>(model.get()))
    if (&c->pass() == &pass) return model;  // already wrapped for this pass
  return std::make_unique<ContactForceModel>(std::move(model), pass);
}

ForceReport ContactForceModel::computeForces(const VecX& x, const VecX& v, VecX& f, ForceJacobians* jac) {
  const ForceReport r = base_.computeForces(x, v, f, jac);
  const VecX& a = pass_.contactAccelerations();
  if (a.size() == f.size()) {
    base_.multiplyMass(x, a, ma_);  // m a for a lumped mass, M(x) a otherwise
    f += ma_;
  }
  return r;
}

// Layout: base state, contact accelerations (A values), pairs (5 values each: key high 31 bits, key
// low 32 bits, acceleration x, y, z), then A, the number of pairs and the base state's size.
std::vector<Real> ContactForceModel::internalState() const {
  std::vector<Real> s = base_.internalState();
  const size_t base_size = s.size();
  const VecX& a = pass_.contact_accel_;
  s.insert(s.end(), a.data(), a.data() + a.size());
  std::vector<std::pair<std::uint64_t, Vec3>> mem(pass_.contact_memory_.begin(), pass_.contact_memory_.end());
  std::sort(mem.begin(), mem.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
  for (const auto& m : mem) {
    s.push_back(static_cast<Real>(m.first >> 32));
    s.push_back(static_cast<Real>(m.first & 0xffffffffULL));
    s.push_back(m.second.x());
    s.push_back(m.second.y());
    s.push_back(m.second.z());
  }
  s.push_back(static_cast<Real>(a.size()));
  s.push_back(static_cast<Real>(mem.size()));
  s.push_back(static_cast<Real>(base_size));
  return s;
}

bool ContactForceModel::setInternalState(const std::vector<Real>& state) {
  if (state.empty()) {  // a state written without contact forces (e.g. by the bare model)
    if (!base_.setInternalState(state)) return false;
    pass_.resetContactForces();
    return true;
  }
  if (state.size() < 3) return false;
  const Real na = state[state.size() - 3], nm = state[state.size() - 2], nb = state[state.size() - 1];
  const size_t n3 = static_cast<size_t>(3 * base_.numNodes());
  if (!(na == 0 || na == static_cast<Real>(n3)) || !(nm >= 0) || !(nb >= 0) || nm != std::floor(nm) || nb != std::floor(nb))
    return false;
  const size_t A = static_cast<size_t>(na), M = static_cast<size_t>(nm), B = static_cast<size_t>(nb);
  if (B + A + 5 * M + 3 != state.size()) return false;
  std::unordered_map<std::uint64_t, Vec3> mem;
  for (size_t k = 0; k < M; ++k) {
    const Real* e = state.data() + B + A + 5 * k;
    if (!(e[0] >= 0 && e[0] < 2147483648.0 && e[1] >= 0 && e[1] < 4294967296.0) || e[0] != std::floor(e[0]) ||
        e[1] != std::floor(e[1]) || !std::isfinite(e[2]) || !std::isfinite(e[3]) || !std::isfinite(e[4]))
      return false;
    const std::uint64_t key = (static_cast<std::uint64_t>(e[0]) << 32) | static_cast<std::uint64_t>(e[1]);
    mem.emplace(key, Vec3(e[2], e[3], e[4]));
  }
  VecX a(static_cast<Index>(A));
  for (size_t k = 0; k < A; ++k) {
    if (!std::isfinite(state[B + k])) return false;
    a[static_cast<Index>(k)] = state[B + k];
  }
  if (!base_.setInternalState(std::vector<Real>(state.begin(), state.begin() + static_cast<std::ptrdiff_t>(B))))
    return false;
  pass_.contact_memory_ = std::move(mem);
  pass_.contact_accel_ = std::move(a);
  return true;
}

}  // namespace textile_handling
