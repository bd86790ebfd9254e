// Yarn tearing in the yarn_woven model (yarn_woven_model.h): after an accepted step, a segment whose
// stretch tension exceeds the threshold breaks. Its stretch and the bending stencils across it stop,
// the crossing terms that need it stop, its material stays as two loose halves lumped on its nodes,
// and its yarn's sliding DOF at both nodes is held (a cut end). docs/yarn_model.md, "Tearing".
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <iterator>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/yarn_kernels.h"
#include "textile_handling/sim/yarn_woven_model.h"
#include "yarn_stencils.h"

namespace textile_handling {

namespace {

constexpr int kB = kYarnDofsPerNode;
constexpr std::size_t kNoSegment = std::numeric_limits<std::size_t>::max();

// A segment stencil's DOFs in the kernels' order (x0, u0, x1, u1).
yarn_stencil::Dofs<2> segmentDofs(const std::array<std::size_t, 12>& dof) {
  yarn_stencil::Dofs<2> d;
  std::copy(dof.begin(), dof.begin() + 8, d.begin());
  return d;
}

// The node pairs of the torn segments, for lookups by the terms that span a segment. A pair of nodes
// is joined by at most one segment (a warp and a weft never join the same two nodes).
class CutSegments {
 public:
  void add(Index a, Index b) { pairs_.push_back(ordered(a, b)); }
  void sort() { std::sort(pairs_.begin(), pairs_.end()); }
  bool contains(Index a, Index b) const { return std::binary_search(pairs_.begin(), pairs_.end(), ordered(a, b)); }

 private:
  static std::pair<Index, Index> ordered(Index a, Index b) {
    return a < b ? std::make_pair(a, b) : std::make_pair(b, a);
  }
  std::vector<std::pair<Index, Index>> pairs_;
};

// The pieces of `intact` split at every cut segment; runs left without a segment are dropped (their
// node keeps no term on that yarn).
std::vector<YarnPiece> splitPieces(const std::vector<YarnPiece>& intact, const CutSegments& cut) {
  std::vector<YarnPiece> out;
  auto emit = [&](const YarnPiece& p, std::size_t first, std::size_t last) {
    if (last == first) return;
    const auto from = static_cast<std::ptrdiff_t>(first), to = static_cast<std::ptrdiff_t>(last + 1);
    YarnPiece run;
    run.warp = p.warp;
    run.line = p.line;
    run.nodes.assign(p.nodes.begin() + from, p.nodes.begin() + to);
    run.arc_length_m.assign(p.arc_length_m.begin() + from, p.arc_length_m.begin() + to);
    run.seam = p.seam;
    if (p.seam) run.slide_offsets.assign(p.slide_offsets.begin() + from, p.slide_offsets.begin() + to);
    out.push_back(std::move(run));
  };
  for (const YarnPiece& p : intact) {
    std::size_t first = 0;
    for (std::size_t k = 0; k + 1 < p.nodes.size(); ++k)
      if (cut.contains(static_cast<Index>(p.nodes[k]), static_cast<Index>(p.nodes[k + 1]))) {
        emit(p, first, k);
        first = k + 1;
      }
    emit(p, first, p.nodes.size() - 1);
  }
  return out;
}

}  // namespace

void validateTearTension(Real tension_n) {
  if (!(tension_n >= 0) || !std::isfinite(tension_n))
    throw SimError("yarn_woven: tear_tension_n " + std::to_string(tension_n) +
                   " N must be finite and >= 0 (0 = no tearing)");
}

Real YarnWovenModel::segmentTension(const VecX& q, const Stencil& s) const {
  const yarn::SegmentVector e = yarn_stencil::gather<2>(q, segmentDofs(s.dof));
  const Real rest = e[7] - e[3];
  // A segment whose material slid out carries no tension (and cannot tear).
  if (!(rest > 0)) return -std::numeric_limits<Real>::infinity();
  return fabric_.stretchStiffness() * ((e.segment<3>(4) - e.segment<3>(0)).norm() / rest - 1);
}

Real YarnWovenModel::maxSegmentTension(const VecX& x) const {
  const VecX q = kernelCoordinates(x);
  Real worst = -std::numeric_limits<Real>::infinity();
  for (const Stencil& s : segments_)
    if (!s.torn) worst = std::max(worst, segmentTension(q, s));
  return worst;
}

std::vector<std::array<Index, 2>> YarnWovenModel::tornSegmentNodes() const {
  std::vector<std::array<Index, 2>> nodes;
  for (std::size_t k : tears_.torn) nodes.push_back({segments_[k].node[0], segments_[k].node[1]});
  return nodes;
}

std::vector<std::size_t> YarnWovenModel::overloadedSegments(const VecX& q) const {
  std::vector<std::size_t> out;
  const Real limit = options_.tear_tension_n * options_.bundle_size;
  if (!(limit > 0)) return out;
  // One tear per run of intact segments and step: a break relieves its yarn's tension within a step
  // (a stretch wave crosses 20 cm of the default yarn in a millisecond), so the yarn's other segments
  // over the limit would not have broken as well.
  std::size_t best = kNoSegment;
  Real best_tension = limit;
  auto endRun = [&] {
    if (best != kNoSegment) out.push_back(best);
    best = kNoSegment;
    best_tension = limit;
  };
  for (std::size_t k = 0; k < segments_.size(); ++k) {
    const Stencil& s = segments_[k];
    // The segments of a piece are consecutive in segments_, each starting at its predecessor's end.
    const bool same_run = k > 0 && !segments_[k - 1].torn && segments_[k - 1].node[1] == s.node[0];
    if (!same_run) endRun();
    if (s.torn) continue;
    const Real tension = segmentTension(q, s);
    if (tension > best_tension) {
      best = k;
      best_tension = tension;
    }
  }
  endRun();
  return out;
}

void YarnWovenModel::tearOverloadedSegments(const VecX& q, VecX& v) {
  const std::vector<std::size_t> tear = overloadedSegments(q);
  if (tear.empty()) return;
  std::vector<std::size_t> torn;
  std::merge(tears_.torn.begin(), tears_.torn.end(), tear.begin(), tear.end(), std::back_inserter(torn));
  tears_.torn = std::move(torn);
  applyTornSegments();
  // A cut end is held from now on: it must not keep the sliding speed it had.
  for (std::size_t k : tear)
    for (std::size_t d : {segments_[k].dof[3], segments_[k].dof[7]}) v[static_cast<Eigen::Index>(d)] = 0;
}

void YarnWovenModel::applyTornSegments() {
  if (!tears_.intact_saved) {
    if (tears_.torn.empty()) return;  // the laid sheet, unchanged
    tears_.intact_pieces = sheet_.grid.pieces;
    tears_.intact_held = sheet_.held_dofs;
    tears_.intact_saved = true;
  }
  CutSegments cut;
  for (Stencil& s : segments_) s.torn = false;
  std::vector<std::size_t> held = tears_.intact_held;
  for (std::size_t k : tears_.torn) {
    Stencil& s = segments_[k];
    s.torn = true;
    cut.add(s.node[0], s.node[1]);
    for (std::size_t d : {s.dof[3], s.dof[7]}) held.push_back(d);  // the segment's sliding DOF at each node
  }
  cut.sort();
  for (Stencil& s : bends_) s.torn = cut.contains(s.node[0], s.node[1]) || cut.contains(s.node[1], s.node[2]);
  for (ShearPair& p : shear_pairs_) p.torn = cut.contains(p.node[0], p.node[1]) || cut.contains(p.node[0], p.node[2]);
  for (ContactPair& p : contacts_) p.torn = cut.contains(p.node[0], p.node[1]);
  sheet_.grid.pieces = splitPieces(tears_.intact_pieces, cut);
  std::sort(held.begin(), held.end());
  held.erase(std::unique(held.begin(), held.end()), held.end());
  sheet_.held_dofs = std::move(held);
  std::fill(held_.begin(), held_.end(), 0);
  for (std::size_t d : sheet_.held_dofs) held_[d] = 1;
  collectSlidingDofs();
}

bool YarnWovenModel::readTornSegments(const std::vector<Real>& state, std::size_t base,
                                      std::vector<std::size_t>* torn) const {
  torn->clear();
  if (state.size() == base) return true;  // nothing torn (also every state written before tearing existed)
  const Real count = state.back();
  if (!(count >= 1) || count != std::floor(count) || count != static_cast<Real>(state.size() - base - 1)) return false;
  for (std::size_t i = base; i + 1 < state.size(); ++i) {
    const Real r = state[i];
    if (!(r >= 0) || r != std::floor(r) || !(r < static_cast<Real>(segments_.size()))) return false;
    const auto k = static_cast<std::size_t>(r);
    if (!torn->empty() && k <= torn->back()) return false;  // ascending, no repeats
    torn->push_back(k);
  }
  return true;
}

void YarnWovenModel::addTornSegmentMass(const VecX& q, Real scale, BlockSparseMatrix& a) const {
  const Real rho = fabric_.linear_density_kg_per_m;
  for (std::size_t k : tears_.torn) {
    const Stencil& s = segments_[k];
    const Real half = 0.5 * rho * (q[static_cast<Eigen::Index>(s.dof[7])] - q[static_cast<Eigen::Index>(s.dof[3])]);
    for (Index node : {s.node[0], s.node[1]})
      for (std::size_t c = 0; c < 3; ++c) diagonalEntry(a, static_cast<std::size_t>(kB * node) + c) += scale * half;
  }
}

void YarnWovenModel::addTornSegmentMassProduct(const VecX& q, const VecX& v, VecX& mv) const {
  const Real rho = fabric_.linear_density_kg_per_m;
  for (std::size_t k : tears_.torn) {
    const Stencil& s = segments_[k];
    const Real half = 0.5 * rho * (q[static_cast<Eigen::Index>(s.dof[7])] - q[static_cast<Eigen::Index>(s.dof[3])]);
    for (Index node : {s.node[0], s.node[1]}) mv.segment<3>(kB * node) += half * v.segment<3>(kB * node);
  }
}

Real YarnWovenModel::tornSegmentWeightEnergy(const VecX& q) const {
  const Real rho = fabric_.linear_density_kg_per_m;
  Real e = 0;
  for (std::size_t k : tears_.torn)
    e += yarn::gravityEnergy(yarn_stencil::gather<2>(q, segmentDofs(segments_[k].dof)), rho, gravity_);
  return e;
}

}  // namespace textile_handling
