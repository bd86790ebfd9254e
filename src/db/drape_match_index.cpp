#include "textile_handling/db/drape_match_index.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <set>
#include <stdexcept>
#include <utility>

#include "textile_handling/db/blob_codec.h"

namespace textile_handling {
namespace db {

std::optional<std::size_t> DrapeMatchIndex::classOf(const std::string& textile, const Vec2& hold) const {
  auto sym = symmetry.find(textile);
  const Vec2 c = sym != symmetry.end() ? sym->second.canonical(hold) : hold;
  std::optional<std::size_t> best;
  double best_d = 1e-3;
  for (std::size_t k = 0; k < classes.size(); ++k) {
    if (classes[k].textile != textile) continue;
    const double d = (classes[k].canonical_hold - c).norm();
    if (d <= best_d) {
      best_d = d;
      best = k;
    }
  }
  return best;
}

std::size_t DrapeMatchIndex::loadedViews(const std::string& textile) const {
  std::size_t n = 0;
  for (std::size_t e = 0; e < entry_class.size(); ++e)
    if (entry_class[e] < classes.size() && classes[entry_class[e]].textile == textile) ++n;
  return n;
}

bool DrapeMatchIndex::classesNeighbour(std::size_t a, std::size_t b, bool diagonal) const {
  if (a >= classes.size() || b >= classes.size()) return false;
  if (a == b) return true;
  if (classes[a].textile != classes[b].textile) return false;
  for (std::size_t i : classes[a].members)
    for (std::size_t j : classes[b].members)
      if (latticeNeighbours(hold_points[i].lattice_i, hold_points[i].lattice_j, hold_points[j].lattice_i,
                            hold_points[j].lattice_j, diagonal))
        return true;
  return false;
}

namespace {

// Lattice indices of the loaded hold points: per textile, the rank of y and of x among the distinct
// coordinates (1 um apart or more) of all loaded hold points of that textile. The stored indices rank
// a hold point within the plan of one build; an index that loads rows of several builds (other
// settings, other hold-point sets) would otherwise mix incompatible rankings and call points
// neighbours that are not.
void assignLatticeIndices(DrapeMatchIndex& index) {
  std::map<std::string, std::vector<double>> xs, ys;
  for (const IndexedHoldPoint& h : index.hold_points) {
    xs[h.textile].push_back(h.hold.x());
    ys[h.textile].push_back(h.hold.y());
  }
  auto distinct = [](std::vector<double>& v) {
    std::sort(v.begin(), v.end());
    std::vector<double> out;
    for (double a : v)
      if (out.empty() || a - out.back() > 1e-6) out.push_back(a);
    v = out;
  };
  auto rank = [](const std::vector<double>& v, double a) {
    // index of the distinct value within 1e-6 (the first one at or above a - 1e-6)
    return static_cast<int>(std::lower_bound(v.begin(), v.end(), a - 1e-6) - v.begin());
  };
  for (auto& [t, v] : xs) distinct(v);
  for (auto& [t, v] : ys) distinct(v);
  for (IndexedHoldPoint& h : index.hold_points) {
    h.lattice_i = rank(ys[h.textile], h.hold.y());
    h.lattice_j = rank(xs[h.textile], h.hold.x());
  }
}

// The selection of finished simulations shared by every query of this file (?1 textile name or '', ?2 = 1
// with a spacing ?3, ?4 = 1 to include mirror-derived rows); s = simulations, t = textiles.
const char* storedViewFilter() {
  // Only the textile's active generation: rows of a resimulation in progress are invisible to readers.
  return "s.status = 'done' AND s.generation = t.generation AND (?1 = '' OR t.name = ?1) "
         "AND (?2 = 0 OR abs(s.spacing - ?3) <= 1e-9) AND (?4 = 1 OR s.source = 'identity')";
}

void bindFilter(SqlStatement& st, const MatchIndexOptions& options) {
  st.bind(1, options.textile)
      .bind(2, options.spacing ? 1 : 0)
      .bind(3, options.spacing ? *options.spacing : 0.0)
      .bind(4, options.include_derived ? 1 : 0);
}

}  // namespace

std::map<std::string, StoredViewCount> countStoredViews(const HangingDrapeDatabase& db, const MatchIndexOptions& options) {
  return db.withConnection([&](SqlConnection& conn) {
    SqlStatement st = conn.prepare(
        std::string("SELECT t.name, count(*), COALESCE(sum(s.view_count), 0) FROM simulations s JOIN textiles t ON "
                    "t.id = s.textile_id WHERE ") +
        storedViewFilter() + " GROUP BY t.name");
    bindFilter(st, options);
    std::map<std::string, StoredViewCount> out;
    while (st.step()) out[st.getText(0)] = StoredViewCount{st.getInt(1), st.getInt(2)};
    return out;
  });
}

DrapeMatchIndex loadDrapeMatchIndex(const HangingDrapeDatabase& db, const MatchIndexOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  DrapeMatchIndex index;
  db.withConnection([&](SqlConnection& conn) {
    const std::string sql =
        std::string(
            "SELECT v.id, v.view_angle_deg, v.projection, v.width_px, v.height_px, v.metres_per_pixel, "
            "v.top_margin_px, v.mask, s.id, s.hold_x, s.hold_y, s.lattice_i, s.lattice_j, s.source, t.name, "
            "t.symmetry, t.symmetry_cx, t.symmetry_cy FROM views v JOIN simulations s ON s.id = v.simulation_id "
            "JOIN textiles t ON t.id = s.textile_id WHERE ") +
        storedViewFilter() + " ORDER BY s.id, v.view_angle_deg";
    SqlStatement st = conn.prepare(sql);
    bindFilter(st, options);
    std::int64_t last_sim = -1;
    std::size_t current = 0;
    bool first = true;
    std::map<std::pair<std::string, std::pair<long long, long long>>, std::size_t> class_of_key;
    while (st.step()) {
      const std::int64_t view_id = st.getInt(0);
      const std::string what = "view " + std::to_string(view_id);
      // The blob is checked (tag, version, size, CRC, padding) and copied straight into the mask. A
      // damaged one costs this view only: it is recorded and the textile's other views still load.
      const int w = static_cast<int>(st.getInt(3)), h = static_cast<int>(st.getInt(4));
      vision::BitMask mask;
      try {
        mask = decodeMask(st.blobData(7), static_cast<std::size_t>(st.blobSize(7)), what);
        if (mask.width() != w || mask.height() != h)
          throw BlobFormatError("mask blob of " + what + " does not match the row's window size");
      } catch (const BlobFormatError& e) {
        index.skipped_views.push_back(SkippedView{view_id, st.getInt(8), st.getText(14), e.what()});
        continue;
      }
      const double mpp = st.getDouble(5), top = st.getDouble(6);
      const std::string projection = st.getText(2);
      if (first) {
        index.frame.width_px = w;
        index.frame.height_px = h;
        index.frame.metres_per_pixel = mpp;
        index.frame.top_margin_px = top;
        index.projection = projection;
        first = false;
      } else if (w != index.frame.width_px || h != index.frame.height_px || mpp != index.frame.metres_per_pixel ||
                 top != index.frame.top_margin_px || projection != index.projection) {
        throw InvalidInputError(
            "the selected views mix canonical frames or projections; select one textile or spacing");
      }
      const std::int64_t sim_id = st.getInt(8);
      if (sim_id != last_sim) {
        IndexedHoldPoint hp;
        hp.simulation_id = sim_id;
        hp.hold = Vec2(st.getDouble(9), st.getDouble(10));
        hp.lattice_i = static_cast<int>(st.getInt(11));
        hp.lattice_j = static_cast<int>(st.getInt(12));
        hp.source = mirrorKindFromString(st.getText(13));
        hp.textile = st.getText(14);
        if (!index.symmetry.count(hp.textile)) {
          TextileSymmetry s;
          const std::string sym = st.getText(15);
          s.mirror_x = sym == "x" || sym == "xy";
          s.mirror_y = sym == "y" || sym == "xy";
          s.cx = st.getDouble(16);
          s.cy = st.getDouble(17);
          index.symmetry[hp.textile] = s;
        }
        const Vec2 canon = index.symmetry[hp.textile].canonical(hp.hold);
        const auto key = std::make_pair(hp.textile, std::make_pair(std::llround(canon.x() * 1e4), std::llround(canon.y() * 1e4)));
        auto it = class_of_key.find(key);
        if (it == class_of_key.end()) {
          HoldPointClass cl;
          cl.textile = hp.textile;
          cl.canonical_hold = canon;
          it = class_of_key.emplace(key, index.classes.size()).first;
          index.classes.push_back(cl);
        }
        hp.class_index = it->second;
        current = index.hold_points.size();
        index.classes[it->second].members.push_back(current);
        index.hold_point_of_group[std::to_string(sim_id)] = current;
        index.hold_points.push_back(hp);
        last_sim = sim_id;
      }
      vision::SilhouetteEntry e;
      e.textile_id = index.hold_points[current].textile;
      e.hold_point_id = std::to_string(sim_id);
      e.view_angle_deg = st.getDouble(1);
      e.mask = std::move(mask);
      index.matcher.add(e);
      index.entry_view_ids.push_back(view_id);
      index.entry_class.push_back(static_cast<std::uint32_t>(index.hold_points[current].class_index));
    }
  });
  if (index.matcher.empty())
    throw NotFoundError("no finished simulations with usable views in '" + db.path() + "'" +
                        (options.textile.empty() ? std::string() : " for textile '" + options.textile + "'") +
                        (index.skipped_views.empty()
                             ? std::string()
                             : " (" + std::to_string(index.skipped_views.size()) + " damaged views skipped, first: " +
                                   index.skipped_views.front().reason + ")"));
  index.stored = countStoredViews(db, options);
  assignLatticeIndices(index);
  index.load_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return index;
}

namespace {


template <typename MatchT, typename Fill>
DrapeQueryResult foldClasses(const DrapeMatchIndex& index, const std::vector<MatchT>& matches, int top_k, Fill fill) {
  // Matches arrive best first; the first match of a class is that class's score.
  // Entries outside the loaded hold points (foreign groups) are classes of their own.
  std::vector<std::pair<const MatchT*, std::size_t>> firsts;  // (match, hold point or kForeignClass)
  std::set<std::size_t> seen;
  std::set<std::pair<std::string, std::string>> seen_foreign;
  const std::size_t want = std::max<std::size_t>(static_cast<std::size_t>(top_k), 2);
  for (const MatchT& m : matches) {
    const auto it = index.hold_point_of_group.find(m.hold_point_id);
    if (it == index.hold_point_of_group.end()) {
      if (!seen_foreign.insert({m.textile_id, m.hold_point_id}).second) continue;
      firsts.emplace_back(&m, kForeignClass);
    } else {
      if (!seen.insert(index.hold_points[it->second].class_index).second) continue;
      firsts.emplace_back(&m, it->second);
    }
    if (firsts.size() >= want) break;
  }
  DrapeQueryResult out;
  for (std::size_t k = 0; k < firsts.size() && static_cast<int>(k) < top_k; ++k) {
    const MatchT& m = *firsts[k].first;
    const std::size_t hp = firsts[k].second;
    DrapeMatch d;
    d.score = m.score;
    if (hp == kForeignClass) {
      d.class_index = kForeignClass;
      d.hold_point = kForeignClass;
      d.textile = m.textile_id;
      fill(m, d);
      out.matches.push_back(d);
      continue;
    }
    const std::size_t cl = index.hold_points[hp].class_index;
    d.class_index = cl;
    d.textile = index.classes[cl].textile;
    d.canonical_hold = index.classes[cl].canonical_hold;
    d.hold_point = hp;
    d.simulation_id = index.hold_points[hp].simulation_id;
    fill(m, d);
    out.matches.push_back(d);
  }
  if (!out.matches.empty()) {
    out.margin = out.matches.front().score - (firsts.size() >= 2 ? firsts[1].first->score : 0.0);
    out.matches.front().margin = out.margin;
  }
  return out;
}


}  // namespace

vision::MatchOptions metricShiftOptions(const vision::CanonicalFrame& frame, double max_dx_m, double max_dy_m,
                                        int top_k) {
  if (!(max_dx_m >= 0) || !(max_dy_m >= 0) || !std::isfinite(max_dx_m) || !std::isfinite(max_dy_m))
    throw InvalidInputError("shift range must be finite and >= 0 m");
  if (top_k < 1) throw InvalidInputError("top_k must be >= 1");
  if (!(frame.metres_per_pixel > 0) || !std::isfinite(frame.metres_per_pixel))
    throw InvalidInputError("frame has no valid metric scale");
  if (max_dx_m > kMaxShiftMetres || max_dy_m > kMaxShiftMetres)
    throw InvalidInputError("shift range must be at most " + std::to_string(kMaxShiftMetres) + " m");
  // Capped in double before the conversion, so that no range overflows an int.
  auto px = [&](double m, int cap) {
    return static_cast<int>(std::min(static_cast<double>(cap), std::ceil(m / frame.metres_per_pixel - 1e-9)));
  };
  vision::MatchOptions o;
  o.max_dx = px(max_dx_m, std::max(0, frame.width_px));
  o.max_dy = px(max_dy_m, std::max(0, frame.height_px));
  o.top_k = top_k;
  return o;
}

namespace {

// The matcher aggregates per class directly (the best entry, or fused member, of any member), so top-k
// classes plus the runner-up for the margin is all it has to find. Entries added to the matcher after
// loading (foreign distractors) are groups of their own.
const std::vector<std::uint32_t>* classGroups(const DrapeMatchIndex& index, std::vector<std::uint32_t>* extended) {
  if (index.entry_class.size() == index.matcher.size()) return &index.entry_class;
  if (index.entry_class.size() > index.matcher.size())
    throw std::invalid_argument("match index: more entry classes than matcher entries");
  *extended = index.entry_class;
  extended->resize(index.matcher.size());
  for (std::size_t e = index.entry_class.size(); e < index.matcher.size(); ++e)
    (*extended)[e] = static_cast<std::uint32_t>(index.classes.size() + index.matcher.groupOf(e));
  return extended;
}

vision::MatchOptions classOptions(const vision::MatchOptions& options, const std::vector<std::uint32_t>* groups) {
  if (options.top_k < 1) throw std::invalid_argument("top_k must be >= 1");
  vision::MatchOptions o = options;
  o.top_k = options.top_k + 1;
  o.group_of_entry = groups;
  return o;
}

}  // namespace

DrapeQueryResult queryDrape(const DrapeMatchIndex& index, const vision::BitMask& mask, const vision::MatchOptions& options) {
  std::vector<std::uint32_t> extended;
  const vision::QueryResult r = index.matcher.query(mask, classOptions(options, classGroups(index, &extended)));
  DrapeQueryResult out = foldClasses(index, r.matches, options.top_k, [](const vision::MatchResult& m, DrapeMatch& d) {
    d.view_angle_deg = m.view_angle_deg;
    d.dx = m.dx;
    d.dy = m.dy;
  });
  out.stats = r.stats;
  return out;
}

DrapeQueryResult queryDrapeFused(const DrapeMatchIndex& index, const std::vector<vision::FusionImage>& images,
                                 const vision::MatchOptions& options) {
  std::vector<std::uint32_t> extended;
  const vision::FusedQueryResult r =
      index.matcher.queryFused(images, classOptions(options, classGroups(index, &extended)));
  DrapeQueryResult out = foldClasses(index, r.matches, options.top_k, [](const vision::FusedMatch& m, DrapeMatch& d) {
    d.view_angle_deg = m.base_view_deg;
    if (!m.images.empty()) {
      d.dx = m.images.front().dx;
      d.dy = m.images.front().dy;
    }
  });
  out.stats = r.stats;
  return out;
}

}  // namespace db
}  // namespace textile_handling
