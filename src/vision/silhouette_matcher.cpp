// Silhouette database (the packed store: words, projections, areas, bounding boxes, groups) and the
// single-image query: entries visited by decreasing area bound, each pruned or searched exactly.
// See docs/vision.md.
#include "textile_handling/vision/silhouette_matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "silhouette_matcher_access.h"

namespace textile_handling {
namespace vision {

using namespace matcher_detail;

namespace {

constexpr int kMaxSide = 8192;

}  // namespace

std::size_t SilhouetteMatcher::add(const SilhouetteEntry& entry) {
  const BitMask& mk = entry.mask;
  if (mk.empty()) throw InvalidArgumentError("SilhouetteMatcher::add", "mask", "mask is empty (0 pixels wide or high)");
  if (mk.width() > kMaxSide || mk.height() > kMaxSide)
    throw LimitExceededError("SilhouetteMatcher::add", "mask", "masks larger than 8192 px per side are not supported");
  if (!std::isfinite(entry.view_angle_deg))
    throw InvalidArgumentError("SilhouetteMatcher::add", "view_angle_deg", "view angle is not finite");
  if (meta_.empty()) {
    width_ = mk.width();
    height_ = mk.height();
    words_per_row_ = mk.wordsPerRow();
    rows_padded_ = roundUp8(height_);
    cols_padded_ = roundUp8(width_);
    bytes_ = height_ <= 255;
    cols_padded16_ = roundUp16(width_);
  } else if (mk.width() != width_ || mk.height() != height_) {
    std::ostringstream os;
    os << "mask is " << mk.width() << "x" << mk.height() << " but the database holds "
       << width_ << "x" << height_ << " silhouettes";
    throw InvalidArgumentError("SilhouetteMatcher::add", "mask", os.str());
  }
  const std::size_t idx = meta_.size();
  const auto key = std::make_pair(entry.textile_id, entry.hold_point_id);
  auto it = group_index_.find(key);
  int g;
  if (it == group_index_.end()) {
    g = static_cast<int>(groups_.size());
    group_index_.emplace(key, g);
    groups_.push_back(Group{entry.textile_id, entry.hold_point_id, {}});
  } else {
    g = it->second;
  }
  groups_[static_cast<std::size_t>(g)].entries.push_back(static_cast<std::uint32_t>(idx));
  meta_.push_back(Meta{entry.textile_id, entry.hold_point_id, entry.view_angle_deg, g});
  words_.insert(words_.end(), mk.words().begin(), mk.words().end());
  const std::int64_t area = mk.count();
  area_.push_back(static_cast<std::int32_t>(area));
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  mk.boundingBox(&x0, &y0, &x1, &y1);
  for (int v : {x0, y0, x1, y1}) bbox_.push_back(static_cast<std::int16_t>(v));
  const std::vector<int> rc = mk.rowCounts(), cc = mk.colCounts();
  const std::size_t r0 = row_counts_.size(), c0 = col_counts_.size();
  row_counts_.resize(r0 + static_cast<std::size_t>(rows_padded_), 0);
  col_counts_.resize(c0 + static_cast<std::size_t>(cols_padded_), 0);
  for (int y = 0; y < height_; ++y) row_counts_[r0 + static_cast<std::size_t>(y)] = static_cast<std::int16_t>(rc[static_cast<std::size_t>(y)]);
  for (int x = 0; x < width_; ++x) col_counts_[c0 + static_cast<std::size_t>(x)] = static_cast<std::int16_t>(cc[static_cast<std::size_t>(x)]);
  if (bytes_) {
    const std::size_t c8 = col_counts8_.size();
    col_counts8_.resize(c8 + static_cast<std::size_t>(cols_padded16_), 0);
    for (int x = 0; x < width_; ++x) col_counts8_[c8 + static_cast<std::size_t>(x)] = static_cast<std::uint8_t>(cc[static_cast<std::size_t>(x)]);
  }
  // Keep by_area_ sorted by (area, index); new entries have the largest index.
  const auto pos = std::upper_bound(by_area_.begin(), by_area_.end(), area,
                                    [this](std::int64_t a, std::uint32_t e) { return a < area_[e]; });
  by_area_.insert(pos, static_cast<std::uint32_t>(idx));
  return idx;
}

void SilhouetteMatcher::reserve(std::size_t n) {
  meta_.reserve(n);
  area_.reserve(n);
  by_area_.reserve(n);
  bbox_.reserve(4 * n);
  if (width_ > 0) {
    words_.reserve(n * static_cast<std::size_t>(height_) * words_per_row_);
    row_counts_.reserve(n * static_cast<std::size_t>(rows_padded_));
    col_counts_.reserve(n * static_cast<std::size_t>(cols_padded_));
    if (bytes_) col_counts8_.reserve(n * static_cast<std::size_t>(cols_padded16_));
  }
}

void SilhouetteMatcher::clear() { *this = SilhouetteMatcher(); }

SilhouetteEntry SilhouetteMatcher::entry(std::size_t i) const {
  if (i >= meta_.size()) throw IndexOutOfRangeError("SilhouetteMatcher::entry: index out of range");
  SilhouetteEntry e;
  e.textile_id = meta_[i].textile_id;
  e.hold_point_id = meta_[i].hold_point_id;
  e.view_angle_deg = meta_[i].view_angle_deg;
  e.mask = BitMask(width_, height_);
  const std::size_t n = static_cast<std::size_t>(height_) * words_per_row_;
  for (int y = 0; y < height_; ++y)
    std::copy_n(&words_[i * n + static_cast<std::size_t>(y) * words_per_row_], words_per_row_, e.mask.row(y));
  return e;
}

QueryResult SilhouetteMatcher::query(const BitMask& mask, const MatchOptions& options) const {
  validateOptions(options, "SilhouetteMatcher::query");
  MatcherAccess acc(*this, options);
  acc.validateQuery(mask, "SilhouetteMatcher::query");
  const std::int64_t qa = mask.count();
  if (qa == 0) throw InvalidArgumentError("SilhouetteMatcher::query", "mask", "query mask has no foreground pixels");

  // Aggregation groups: (textile, hold point) by default, or the caller's coarser grouping.
  const std::vector<std::uint32_t>* custom = options.group_of_entry;
  std::size_t num_groups = groups_.size();
  if (custom) {
    if (custom->size() != meta_.size())
      throw InvalidArgumentError("SilhouetteMatcher::query", "group_of_entry", "group_of_entry has " + std::to_string(custom->size()) +
                                  " values for " + std::to_string(meta_.size()) + " entries");
    num_groups = 0;
    for (std::uint32_t g : *custom) num_groups = std::max<std::size_t>(num_groups, static_cast<std::size_t>(g) + 1);
  }
  auto groupOfEntry = [&](std::size_t e) {
    return custom ? static_cast<int>((*custom)[e]) : meta_[e].group;
  };

  QueryResult result;
  result.stats.entries = meta_.size();
  std::vector<GroupBest> best(num_groups);
  const std::size_t K = static_cast<std::size_t>(std::max(options.top_k, 2));
  std::vector<int> top;  // group ids, best first, at most K (exhaustive: all)

  auto groupBefore = [&best](int g1, int g2) {
    return betterEntry(best[static_cast<std::size_t>(g1)].score, best[static_cast<std::size_t>(g1)].entry,
                       best[static_cast<std::size_t>(g2)].score, best[static_cast<std::size_t>(g2)].entry);
  };

  if (options.exhaustive) {
    for (std::size_t e = 0; e < meta_.size(); ++e) {
      const SilhouetteEntry en = entry(e);
      const ShiftedIou r = bestShiftIou(mask, en.mask, options.max_dx, options.max_dy);
      ++result.stats.evaluated;
      result.stats.shifts_evaluated += static_cast<std::uint64_t>(2 * options.max_dx + 1) * (2 * options.max_dy + 1);
      if (!(r.score > 0)) continue;
      GroupBest& gb = best[static_cast<std::size_t>(groupOfEntry(e))];
      if (gb.score < 0 || betterEntry(r.score, static_cast<std::uint32_t>(e), gb.score, gb.entry))
        gb = GroupBest{r.score, static_cast<std::uint32_t>(e), r.dx, r.dy};
    }
    for (std::size_t g = 0; g < num_groups; ++g)
      if (best[g].score > 0) top.push_back(static_cast<int>(g));
    std::sort(top.begin(), top.end(), groupBefore);
  } else {
    const QueryPrep q = acc.prepare(mask);
    Scratch scratch;
    auto threshold = [&]() { return top.size() < K ? 0.0 : best[static_cast<std::size_t>(top.back())].score; };
    auto offer = [&](int g, double score, std::uint32_t e, int dx, int dy) {
      GroupBest& gb = best[static_cast<std::size_t>(g)];
      if (gb.score >= 0 && !betterEntry(score, e, gb.score, gb.entry)) return;
      gb = GroupBest{score, e, dx, dy};
      if (std::find(top.begin(), top.end(), g) == top.end()) {
        if (top.size() >= K && !groupBefore(g, top.back())) return;
        top.push_back(g);
      }
      std::sort(top.begin(), top.end(), groupBefore);
      if (top.size() > K) top.pop_back();
    };

    // Visit entries in decreasing order of the area bound min(a, b) / max(a, b): expand from the
    // query's area in the area-sorted index, always taking the side with the larger bound.
    const std::size_t n = by_area_.size();
    std::size_t right = static_cast<std::size_t>(
        std::lower_bound(by_area_.begin(), by_area_.end(), qa,
                         [this](std::uint32_t e, std::int64_t a) { return area_[e] < a; }) -
        by_area_.begin());
    std::ptrdiff_t left = static_cast<std::ptrdiff_t>(right) - 1;
    std::size_t visited = 0;
    while (left >= 0 || right < n) {
      const double bl = left >= 0 ? acc.areaBound(q, by_area_[static_cast<std::size_t>(left)]) : -1.0;
      const double br = right < n ? acc.areaBound(q, by_area_[right]) : -1.0;
      const bool take_right = br >= bl;
      const std::size_t e = take_right ? by_area_[right] : by_area_[static_cast<std::size_t>(left)];
      const double bound = take_right ? br : bl;
      const double t = threshold();
      if (bound < t || bound <= 0) break;  // every remaining entry has a smaller bound
      if (take_right)
        ++right;
      else
        --left;
      ++visited;
      const int g = groupOfEntry(e);
      const double floor = std::max(t, best[static_cast<std::size_t>(g)].score);
      const EntryOutcome o = acc.evaluate(q, e, floor, scratch, result.stats);
      if (o.kind == EntryOutcome::kFound) offer(g, o.score, static_cast<std::uint32_t>(e), o.dx, o.dy);
    }
    result.stats.pruned_area += n - visited;
  }

  const std::size_t k = std::min(top.size(), static_cast<std::size_t>(options.top_k));
  const double s0 = top.empty() ? 0.0 : best[static_cast<std::size_t>(top[0])].score;
  const double s1 = top.size() > 1 ? best[static_cast<std::size_t>(top[1])].score : 0.0;
  for (std::size_t i = 0; i < k; ++i) {
    const GroupBest& gb = best[static_cast<std::size_t>(top[i])];
    const Meta& mt = meta_[gb.entry];
    MatchResult r;
    r.textile_id = mt.textile_id;
    r.hold_point_id = mt.hold_point_id;
    r.view_angle_deg = mt.view_angle_deg;
    r.dx = gb.dx;
    r.dy = gb.dy;
    r.score = gb.score;
    r.margin = gb.score - (i == 0 ? s1 : s0);
    r.entry = gb.entry;
    result.matches.push_back(std::move(r));
  }
  result.margin = s0 - s1;
  return result;
}
}  // namespace vision
}  // namespace textile_handling
