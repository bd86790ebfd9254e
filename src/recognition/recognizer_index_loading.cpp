// Loading a TextileRecognizer's state from the drape database: the match indices of the selected
// textiles (one per canonical frame when builds differ), their completeness, the database fingerprint
// that reloadIfChanged() compares, and the cached rest shapes the refinement renders.
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "recognizer_state.h"
#include "textile_handling/db/drape_export.h"

namespace textile_handling {
namespace recognition {
namespace detail {

namespace {

std::shared_ptr<const LoadedIndex> makeLoaded(db::DrapeMatchIndex&& index) {
  auto li = std::make_shared<LoadedIndex>();
  li->index = std::move(index);
  li->views.resize(li->index.hold_points.size());
  for (std::size_t i = 0; i < li->index.matcher.size(); ++i) {
    vision::SilhouetteEntry e = li->index.matcher.entry(i);
    const auto it = li->index.hold_point_of_group.find(e.hold_point_id);
    if (it == li->index.hold_point_of_group.end()) continue;
    li->views[it->second].emplace_back(e.view_angle_deg, std::move(e.mask));
  }
  for (auto& v : li->views) {
    std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    for (std::size_t k = 0; k < v.size(); ++k) {
      const double d = circularDistance(v[k].first, v[(k + 1) % v.size()].first);
      if (v.size() > 1 && d > 1e-9) li->view_step_deg = std::min(li->view_step_deg, d);
    }
  }
  return li;
}

std::vector<double> doneSpacings(const db::HangingDrapeDatabase& db, std::int64_t textile_id) {
  return db.withConnection([&](db::SqlConnection& c) {
    db::SqlStatement st =
        c.prepare("SELECT DISTINCT s.spacing FROM simulations s JOIN textiles t ON t.id = s.textile_id "
                  "WHERE s.textile_id = ?1 AND s.status = 'done' AND s.generation = t.generation ORDER BY s.spacing");
    st.bind(1, textile_id);
    std::vector<double> out;
    while (st.step()) out.push_back(st.getDouble(0));
    return out;
  });
}

}  // namespace

// Everything a reload depends on, as text: textiles and their active generations, the finished
// simulations of those generations (count, id sum and maximum, latest finish time) and their views.
// Rows of staged generations (a resimulation in progress) are invisible to readers and left out.
std::string databaseFingerprint(const db::HangingDrapeDatabase& db) {
  return db.withConnection([](db::SqlConnection& c) {
    db::SqlStatement st = c.prepare(
        "SELECT (SELECT count(*) FROM textiles), (SELECT COALESCE(max(id), 0) FROM textiles), "
        "(SELECT COALESCE(sum(generation), 0) FROM textiles), count(*), COALESCE(sum(s.id), 0), "
        "COALESCE(max(s.id), 0), COALESCE(max(s.finished_at), ''), COALESCE(sum(s.view_count), 0) "
        "FROM simulations s JOIN textiles t ON t.id = s.textile_id WHERE s.status = 'done' AND s.generation = t.generation");
    std::string out;
    if (st.step())
      for (int k = 0; k < 8; ++k) out += (k == 6 ? st.getText(k) : std::to_string(st.getInt(k))) + "|";
    return out;
  });
}

std::shared_ptr<const TextileRecognizer::State> loadState(const db::HangingDrapeDatabase& db, const RecognizerOptions& o) {
  auto st = std::make_shared<TextileRecognizer::State>();
  st->options = o;
  try {
    const std::vector<db::TextileRecord> all = db.textiles();
    std::vector<db::TextileRecord> selected;
    for (const auto& t : all) st->textiles[t.outline.name] = t;
    if (o.textile_id > 0) {
      for (const auto& t : all)
        if (t.id == o.textile_id) selected.push_back(t);
      if (selected.empty())
        fail(RecognitionErrorCode::kUnknownTextile,
             "textile id " + std::to_string(o.textile_id) + " is not in the database '" + db.path() + "'");
    } else if (!o.textile_name.empty()) {
      const auto it = st->textiles.find(o.textile_name);
      if (it == st->textiles.end())
        fail(RecognitionErrorCode::kUnknownTextile, "textile '" + o.textile_name + "' is not in the database '" + db.path() + "'");
      selected.push_back(it->second);
    } else {
      selected = all;
    }
    st->fingerprint = databaseFingerprint(db);
    for (const auto& t : selected) {
      db::MatchIndexOptions mio;
      mio.textile = t.outline.name;
      mio.spacing = o.spacing;
      mio.include_derived = o.include_derived;
      const std::size_t first_index = st->indices.size();
      TextileCompleteness completeness;
      completeness.textile = t.outline.name;
      completeness.stored = db::countStoredViews(db, mio)[t.outline.name];
      try {
        st->indices.push_back(makeLoaded(db::loadDrapeMatchIndex(db, mio)));
      } catch (const db::NotFoundError&) {
        // no finished simulation of this textile (yet)
      } catch (const db::InvalidInputError& e) {
        // Mixed canonical frames (builds with different view settings): one index per spacing.
        bool any = false;
        for (double s : doneSpacings(db, t.id)) {
          if (o.spacing && std::abs(*o.spacing - s) > 1e-9) continue;
          mio.spacing = s;
          try {
            st->indices.push_back(makeLoaded(db::loadDrapeMatchIndex(db, mio)));
            any = true;
          } catch (const db::DrapeDatabaseError& e2) {
            if (dynamic_cast<const db::SqliteError*>(&e2)) throw;
            st->warnings.push_back("textile '" + t.outline.name + "' spacing " + std::to_string(s) + " skipped: " + e2.what());
          }
        }
        if (!any) st->warnings.push_back("textile '" + t.outline.name + "' skipped: " + e.what());
      } catch (const db::BlobFormatError& e) {
        st->warnings.push_back("textile '" + t.outline.name + "' skipped (damaged data): " + e.what());
      }
      for (std::size_t k = first_index; k < st->indices.size(); ++k)
        addCompleteness(st->indices[k]->index, &completeness, &st->skipped);
      noteCompleteness(completeness, o.evidence, &st->problems, &st->result_warnings);
    }
    for (const std::string& line : skippedViewLines(st->skipped)) st->result_warnings.push_back(line);
  } catch (const RecognitionError&) {
    throw;
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, std::string("loading '") + db.path() + "': " + e.what());
  }
  for (const auto& li : st->indices) {
    st->silhouettes += li->index.matcher.size();
    st->hold_points += li->index.hold_points.size();
  }
  return st;
}

std::shared_ptr<const db::HangingDrapeDatabase> openDatabase(const std::string& path) {
  db::DatabaseOpenOptions oo;
  oo.read_only = true;
  oo.create = false;
  try {
    return std::make_shared<const db::HangingDrapeDatabase>(path, oo);
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, "cannot open the drape database '" + path + "': " + e.what());
  }
}

// Grid cells per silhouette triangle: as many as fit in a pixel of the finest loaded canonical frame
// (1 when the mesh is coarser than the pixels).
static int silhouetteStride(const TextileRecognizer::State& st, double spacing_m) {
  double pixel_m = std::numeric_limits<double>::infinity();
  for (const auto& li : st.indices) pixel_m = std::min(pixel_m, li->index.frame.metres_per_pixel);
  if (!std::isfinite(pixel_m) || !(spacing_m > 0)) return 1;
  return std::clamp(static_cast<int>(std::floor(pixel_m / spacing_m + 1e-9)), 1, 8);
}

std::shared_ptr<const TextileRecognizer::StoredShape> loadStoredShape(const db::HangingDrapeDatabase& db,
                                                                      const TextileRecognizer::State& st,
                                                                      std::int64_t simulation_id, const Vec2& expected_hold) {
  using StoredShape = TextileRecognizer::StoredShape;
  std::shared_ptr<const StoredShape> found;
  {
    std::lock_guard<std::mutex> lock(st.cache_mutex);
    const auto it = st.cache.find(simulation_id);
    if (it != st.cache.end()) found = it->second;
  }
  if (!found) {
    auto s = std::make_shared<StoredShape>();
    try {
      db::StoredDrapeMesh m = db::loadDrapeMesh(db, simulation_id);
      s->record = m.record;
      s->textile = m.textile;
      s->positions = std::move(m.positions);
      s->triangles = std::move(m.triangles);
      s->held = m.held_particle;
      std::string err;
      s->grid = ParticleGrid::rasterize(s->textile.outline, s->record.spacing, &err);
      if (s->grid.empty() || 3 * static_cast<Eigen::Index>(s->grid.numActive()) != s->positions.size())
        fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(simulation_id) + ": cannot rebuild its grid " + err);
      s->silhouette_triangles = vision::coarseGridTriangles(s->grid, silhouetteStride(st, s->record.spacing));
    } catch (const RecognitionError&) {
      throw;
    } catch (const std::exception& e) {
      fail(RecognitionErrorCode::kDatabase,
           "loading the rest shape of simulation " + std::to_string(simulation_id) + ": " + e.what() +
               " (has the database changed? reload)");
    }
    std::lock_guard<std::mutex> lock(st.cache_mutex);
    if (st.cache.size() >= st.options.mesh_cache_size) st.cache.clear();
    st.cache[simulation_id] = s;
    found = s;
  }
  if ((found->record.hold - expected_hold).norm() > 1e-9)
    fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(simulation_id) +
                                              " no longer holds the indexed hold point: the database changed; reload");
  return found;
}

}  // namespace detail
}  // namespace recognition
}  // namespace textile_handling
