// Fusion of several images of one textile taken from known relative view angles: each group's score
// combines the best matches of every image at consistent stored views. See docs/vision.md.
#include "textile_handling/vision/silhouette_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "silhouette_matcher_access.h"

namespace textile_handling {
namespace vision {

using namespace matcher_detail;

namespace {

double normaliseAngle(double a) {
  double r = std::fmod(a, 360.0);
  if (r < 0) r += 360.0;
  if (r >= 360.0) r -= 360.0;
  return r;
}

double circularDistance(double a, double b) {
  const double d = std::abs(normaliseAngle(a) - normaliseAngle(b));
  return std::min(d, 360.0 - d);
}

}  // namespace

FusedQueryResult SilhouetteMatcher::queryFused(const std::vector<FusionImage>& images,
                                               const MatchOptions& options) const {
  validateOptions(options, "SilhouetteMatcher::queryFused");
  if (images.empty()) throw InvalidArgumentError("SilhouetteMatcher::queryFused", "images", "no images");
  MatcherAccess acc(*this, options);
  for (std::size_t i = 0; i < images.size(); ++i) {
    const std::string what = "SilhouetteMatcher::queryFused (image " + std::to_string(i) + ")";
    acc.validateQuery(images[i].mask, what.c_str());
    if (images[i].mask.count() == 0) throw InvalidArgumentError(what, "mask", "mask has no foreground pixels");
    if (!std::isfinite(images[i].relative_view_deg)) throw InvalidArgumentError(what, "relative_view_deg", "relative view angle is not finite");
  }
  const std::size_t m = images.size();
  const std::size_t n = meta_.size();
  FusedQueryResult result;
  result.stats.entries = m * n;

  // Distinct stored views of every group, ascending in [0, 360).
  struct View {
    double angle;
    std::vector<std::uint32_t> entries;
  };
  std::vector<std::vector<View>> views(groups_.size());
  for (std::size_t g = 0; g < groups_.size(); ++g) {
    std::vector<std::uint32_t> es = groups_[g].entries;
    std::sort(es.begin(), es.end(), [this](std::uint32_t a, std::uint32_t b) {
      const double x = normaliseAngle(meta_[a].view_angle_deg), y = normaliseAngle(meta_[b].view_angle_deg);
      return x != y ? x < y : a < b;
    });
    for (std::uint32_t e : es) {
      const double a = normaliseAngle(meta_[e].view_angle_deg);
      if (views[g].empty() || std::abs(views[g].back().angle - a) > 1e-9)
        views[g].push_back(View{a, {e}});
      else
        views[g].back().entries.push_back(e);
    }
  }
  auto nearestView = [&views](std::size_t g, double target) {
    const auto& vs = views[g];
    std::size_t best = 0;
    double bd = std::numeric_limits<double>::infinity();
    for (std::size_t v = 0; v < vs.size(); ++v) {
      const double d = circularDistance(vs[v].angle, target);
      if (d < bd - 1e-9) {
        bd = d;
        best = v;
      }
    }
    return best;
  };

  // Per (image, entry) state: 0 = area bound, 1 = projection bound, 2 = exact.
  struct PairState {
    std::uint8_t level = 0;
    double ub = 0;  // upper bound, or the exact score at level 2
    int dx = 0, dy = 0;
  };
  std::vector<PairState> st(m * n);
  std::vector<QueryPrep> preps;
  preps.reserve(m);
  for (std::size_t i = 0; i < m; ++i) preps.push_back(acc.prepare(images[i].mask));
  Scratch scratch;

  auto exactPair = [&](std::size_t i, std::size_t e) {
    PairState& ps = st[i * n + e];
    if (ps.level == 2) return;
    if (options.exhaustive) {
      const SilhouetteEntry en = entry(e);
      const ShiftedIou r = bestShiftIou(images[i].mask, en.mask, options.max_dx, options.max_dy);
      ++result.stats.evaluated;
      result.stats.shifts_evaluated += static_cast<std::uint64_t>(2 * options.max_dx + 1) * (2 * options.max_dy + 1);
      ps = PairState{2, r.score, r.score > 0 ? r.dx : 0, r.score > 0 ? r.dy : 0};
      return;
    }
    EntryOutcome o;
    if (area_[e] == 0) {
      o.kind = EntryOutcome::kAreaPruned;
    } else {
      const int pb = acc.projectionBound(preps[i], e, 0.0, scratch);
      if (pb == 0) {
        o.kind = EntryOutcome::kProjectionPruned;
      } else {
        acc.exactSearch(preps[i], e, 0.0, scratch, o, result.stats);
      }
    }
    if (o.kind == EntryOutcome::kFound)
      ps = PairState{2, o.score, o.dx, o.dy};
    else
      ps = PairState{2, 0.0, 0, 0};
  };
  auto projectionPair = [&](std::size_t i, std::size_t e) {
    PairState& ps = st[i * n + e];
    if (ps.level >= 1) return;
    const int pb = area_[e] == 0 ? 0 : acc.projectionBound(preps[i], e, -1.0, scratch);
    ps.level = 1;
    ps.ub = std::min(ps.ub, iouFromCounts(pb, preps[i].area, area_[e]));
  };
  for (std::size_t i = 0; i < m; ++i)
    for (std::size_t e = 0; e < n; ++e) st[i * n + e].ub = acc.areaBound(preps[i], e);

  // Candidates (group, base view) with their nearest views per image.
  struct Candidate {
    int g;
    int v;
    double bound;
    std::vector<int> near;  // view index per image
  };
  std::vector<Candidate> cands;
  for (std::size_t g = 0; g < groups_.size(); ++g)
    for (std::size_t v = 0; v < views[g].size(); ++v) {
      Candidate c{static_cast<int>(g), static_cast<int>(v), 0.0, std::vector<int>(m)};
      for (std::size_t i = 0; i < m; ++i)
        c.near[i] = static_cast<int>(nearestView(g, views[g][v].angle + images[i].relative_view_deg));
      cands.push_back(std::move(c));
    }
  // Fused value of a candidate from the current per-pair values (bounds or exact scores); also the
  // per-image best entries when all are exact.
  auto fusedValue = [&](const Candidate& c, std::vector<std::uint32_t>* pick) {
    double sum = 0;
    for (std::size_t i = 0; i < m; ++i) {
      const View& vw = views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])];
      double bi = -1;
      std::uint32_t be = 0;
      for (std::uint32_t e : vw.entries) {
        const double u = st[i * n + e].ub;
        if (u > bi) {
          bi = u;
          be = e;
        }
      }
      if (pick) (*pick)[i] = be;
      sum += bi;
    }
    return sum / static_cast<double>(m);
  };
  for (auto& c : cands) c.bound = fusedValue(c, nullptr);
  std::vector<std::size_t> order(cands.size());
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(),
                   [&cands](std::size_t a, std::size_t b) { return cands[a].bound > cands[b].bound; });

  // Ranking groups: the member groups themselves, or the caller's coarser groups (group_of_entry). A
  // candidate is always one member group at one base view (the images are compared with that member's
  // views, which keeps what the known relative turn reveals); a coarse group scores its best member.
  std::vector<int> coarse(groups_.size());
  std::size_t num_coarse = groups_.size();
  if (options.group_of_entry) {
    const std::vector<std::uint32_t>& ge = *options.group_of_entry;
    if (ge.size() != n)
      throw InvalidArgumentError("SilhouetteMatcher::queryFused", "group_of_entry", "group_of_entry has " + std::to_string(ge.size()) +
                                  " values for " + std::to_string(n) + " entries");
    num_coarse = 0;
    for (std::size_t g = 0; g < groups_.size(); ++g) {
      const std::uint32_t c0 = ge[groups_[g].entries.front()];
      for (std::uint32_t e : groups_[g].entries)
        if (ge[e] != c0)
          throw InvalidArgumentError(
              "SilhouetteMatcher::queryFused", "group_of_entry", "group_of_entry splits the entries of one (textile, hold point)");
      coarse[g] = static_cast<int>(c0);
      num_coarse = std::max<std::size_t>(num_coarse, static_cast<std::size_t>(c0) + 1);
    }
  } else {
    std::iota(coarse.begin(), coarse.end(), 0);
  }
  struct FusedBest {
    double score = -1;
    int g = 0;  // member group
    int v = 0;
    std::vector<std::uint32_t> pick;
  };
  std::vector<FusedBest> best(num_coarse);
  auto better = [](double s1, int g1, int v1, double s2, int g2, int v2) {
    return s1 > s2 || (s1 == s2 && (g1 < g2 || (g1 == g2 && v1 < v2)));
  };
  auto groupBefore = [&](int c1, int c2) {
    const FusedBest &b1 = best[static_cast<std::size_t>(c1)], &b2 = best[static_cast<std::size_t>(c2)];
    return better(b1.score, b1.g, b1.v, b2.score, b2.g, b2.v);
  };
  const std::size_t K = options.exhaustive ? num_coarse : static_cast<std::size_t>(std::max(options.top_k, 2));
  std::vector<int> top;
  auto threshold = [&]() { return top.size() < K ? 0.0 : best[static_cast<std::size_t>(top.back())].score; };

  for (std::size_t oi : order) {
    Candidate& c = cands[oi];
    const double t = threshold();
    if (!options.exhaustive && (c.bound < t || c.bound <= 0)) break;
    const int cg = coarse[static_cast<std::size_t>(c.g)];
    FusedBest& gb = best[static_cast<std::size_t>(cg)];
    if (!options.exhaustive) {
      const double floor = std::max(t, gb.score);
      if (c.bound < floor) continue;
      for (std::size_t i = 0; i < m; ++i)
        for (std::uint32_t e : views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])].entries)
          projectionPair(i, e);
      if (fusedValue(c, nullptr) < floor) continue;
    }
    for (std::size_t i = 0; i < m; ++i)
      for (std::uint32_t e : views[static_cast<std::size_t>(c.g)][static_cast<std::size_t>(c.near[i])].entries)
        exactPair(i, e);
    std::vector<std::uint32_t> pick(m);
    const double f = fusedValue(c, &pick);
    if (!(f > 0)) continue;
    if (gb.score >= 0 && !better(f, c.g, c.v, gb.score, gb.g, gb.v)) continue;
    gb.score = f;
    gb.g = c.g;
    gb.v = c.v;
    gb.pick = pick;
    if (std::find(top.begin(), top.end(), cg) == top.end()) {
      if (top.size() >= K && !groupBefore(cg, top.back())) continue;
      top.push_back(cg);
    }
    std::sort(top.begin(), top.end(), groupBefore);
    if (top.size() > K) top.pop_back();
  }

  // Work counters over (image, entry) pairs.
  for (const PairState& ps : st) {
    if (ps.level == 0) ++result.stats.pruned_area;
    if (ps.level == 1) ++result.stats.pruned_projection;
  }

  const std::size_t k = std::min(top.size(), static_cast<std::size_t>(options.top_k));
  const double s0 = top.empty() ? 0.0 : best[static_cast<std::size_t>(top[0])].score;
  const double s1 = top.size() > 1 ? best[static_cast<std::size_t>(top[1])].score : 0.0;
  for (std::size_t r = 0; r < k; ++r) {
    const FusedBest& gb = best[static_cast<std::size_t>(top[r])];
    const int g = gb.g;
    FusedMatch fm;
    fm.textile_id = groups_[static_cast<std::size_t>(g)].textile_id;
    fm.hold_point_id = groups_[static_cast<std::size_t>(g)].hold_point_id;
    fm.base_view_deg = views[static_cast<std::size_t>(g)][static_cast<std::size_t>(gb.v)].angle;
    fm.score = gb.score;
    fm.margin = gb.score - (r == 0 ? s1 : s0);
    for (std::size_t i = 0; i < m; ++i) {
      const std::uint32_t e = gb.pick[i];
      const PairState& ps = st[i * n + e];
      fm.images.push_back(FusedImageMatch{normaliseAngle(meta_[e].view_angle_deg), e, ps.dx, ps.dy, ps.ub});
    }
    result.matches.push_back(std::move(fm));
  }
  result.margin = s0 - s1;
  return result;
}
}  // namespace vision
}  // namespace textile_handling
