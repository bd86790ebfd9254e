#include "textile_handling/recognition/textile_recognizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <sstream>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "textile_handling/db/drape_export.h"
#include "textile_handling/recognition/point_cloud_segmentation.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/timing.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace recognition {

// ---------------------------------------------------------------------------------------------------
// Loaded state

namespace {

struct LoadedIndex {
  db::DrapeMatchIndex index;
  /// Stored views per hold point (index into index.hold_points), sorted by angle.
  std::vector<std::vector<std::pair<double, vision::BitMask>>> views;
  double view_step_deg = 360.0;  ///< smallest spacing of stored view angles
};

using Clock = std::chrono::steady_clock;

[[noreturn]] void fail(RecognitionErrorCode c, const std::string& what) { throw RecognitionError(c, what); }

double circularDistance(double a, double b) {
  const double d = std::abs(wrapDegrees(a) - wrapDegrees(b));
  return std::min(d, 360.0 - d);
}

double signedWrap(double a) {  // (-180, 180]
  a = wrapDegrees(a);
  return a > 180.0 ? a - 360.0 : a;
}

}  // namespace

struct TextileRecognizer::State {
  RecognizerOptions options;
  std::vector<std::shared_ptr<const LoadedIndex>> indices;
  std::map<std::string, db::TextileRecord> textiles;  // all textiles, by name
  std::string fingerprint;
  std::size_t silhouettes = 0, hold_points = 0;
  std::vector<std::string> warnings;
  std::vector<db::SkippedView> skipped;       // damaged views left out
  std::vector<std::string> problems;          // completeness problems: every result is kIncompleteDatabase
  std::vector<std::string> result_warnings;   // carried by every result
  mutable std::mutex cache_mutex;  // rest shapes loaded on demand
  mutable std::map<std::int64_t, std::shared_ptr<const StoredShape>> cache;
};

struct TextileRecognizer::StoredShape {
  db::SimulationRecord record;
  db::TextileRecord textile;
  VecX positions;
  std::vector<vision::Triangle> triangles;
  ParticleGrid grid;
  Index held = -1;
};

void RecognizerOptions::validate() const {
  auto bad = [](const std::string& what) { fail(RecognitionErrorCode::kInvalidOptions, what); };
  if (textile_id < 0) bad("textile_id must be >= 0 (0 = all textiles)");
  if (spacing && (!(*spacing > 0) || !std::isfinite(*spacing))) bad("spacing must be finite and > 0");
  if (match.top_k < 1 || match.max_dx < 0 || match.max_dy < 0) bad("match: top_k must be >= 1 and shift ranges >= 0");
  const RefinementOptions& r = refinement;
  if (r.classes < 1) bad("refinement.classes must be >= 1");
  if (r.max_shift_px < 0 || r.max_shift_px > 64) bad("refinement.max_shift_px must be in 0..64");
  if (!(r.step_deg > 0 && r.step_deg <= 30)) bad("refinement.step_deg must be in (0, 30]");
  if (!(r.half_range_deg >= 0 && r.half_range_deg <= 180)) bad("refinement.half_range_deg must be in [0, 180]");
  if (!(r.depth_score_slack >= 0 && r.depth_score_slack <= 1)) bad("refinement.depth_score_slack must be in [0, 1]");
  if (!(r.depth_yaw_range_deg >= 0 && r.depth_yaw_range_deg <= 180) || !(r.depth_yaw_step_deg > 0 && r.depth_yaw_step_deg <= 30))
    bad("refinement.depth_yaw_range_deg must be in [0, 180] and depth_yaw_step_deg in (0, 30]");
  if (r.depth_min_pixels < 1) bad("refinement.depth_min_pixels must be >= 1");
  if ((max_shift_x_m >= 0) != (max_shift_y_m >= 0) || !std::isfinite(max_shift_x_m) || !std::isfinite(max_shift_y_m))
    bad("max_shift_x_m and max_shift_y_m must both be finite and >= 0 (metric ranges), or both < 0 (pixel ranges of match)");
  const ShapeFitOptions& sf = shape_fit;
  if (sf.iterations < 1 || sf.iterations > 100) bad("shape_fit.iterations must be in 1..100");
  if (!(sf.edge_weight > 0) || !std::isfinite(sf.edge_weight)) bad("shape_fit.edge_weight must be finite and > 0");
  if (!(sf.anchor_weight >= 0) || !std::isfinite(sf.anchor_weight) || !(sf.silhouette_weight >= 0) ||
      !std::isfinite(sf.silhouette_weight))
    bad("shape_fit.anchor_weight and silhouette_weight must be finite and >= 0");
  if (!(sf.visibility_slack_m > 0) || !(sf.max_correspondence_m > 0) || !std::isfinite(sf.max_correspondence_m) ||
      !std::isfinite(sf.visibility_slack_m))
    bad("shape_fit.visibility_slack_m and max_correspondence_m must be finite and > 0");
  if (sf.uncovered_step_px < 1 || sf.uncovered_step_px > 64) bad("shape_fit.uncovered_step_px must be in 1..64");
  if (!(r.depth_truncation_m > 0) || !std::isfinite(r.depth_truncation_m)) bad("refinement.depth_truncation_m must be finite and > 0");
  if (!(r.depth_member_slack >= 0 && r.depth_member_slack <= 1) || !(r.depth_weight_per_m >= 0) || !std::isfinite(r.depth_weight_per_m))
    bad("refinement.depth_member_slack must be in [0, 1] and depth_weight_per_m finite and >= 0");
  if (mesh_cache_size < 1) bad("mesh_cache_size must be >= 1");
  if (!(grasp.boundary_tolerance_m >= 0) || !std::isfinite(grasp.boundary_tolerance_m))
    bad("grasp.boundary_tolerance_m must be finite and >= 0");
  if (canonicalisation.max_canvas_px < 16) bad("canonicalisation.max_canvas_px must be >= 16");
  if (max_image_pixels < 1) bad("max_image_pixels must be >= 1");
  evidence.validate();
  if (!std::isfinite(canonicalisation.clear_above_hold_m)) bad("canonicalisation.clear_above_hold_m must be finite");
  segmentation.validate();
}

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
  return db.withConnection([&](db::SqliteConnection& c) {
    db::SqliteStatement st =
        c.prepare("SELECT DISTINCT s.spacing FROM simulations s JOIN textiles t ON t.id = s.textile_id "
                  "WHERE s.textile_id = ?1 AND s.status = 'done' AND s.generation = t.generation ORDER BY s.spacing");
    st.bind(1, textile_id);
    std::vector<double> out;
    while (st.step()) out.push_back(st.getDouble(0));
    return out;
  });
}

// Everything a reload depends on, as text: textiles and their active generations, the finished
// simulations of those generations (count, id sum and maximum, latest finish time) and their views.
// Rows of staged generations (a resimulation in progress) are invisible to readers and left out.
std::string databaseFingerprint(const db::HangingDrapeDatabase& db) {
  return db.withConnection([](db::SqliteConnection& c) {
    db::SqliteStatement st = c.prepare(
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

}  // namespace

TextileRecognizer::TextileRecognizer(const std::string& path, RecognizerOptions options)
    : TextileRecognizer(openDatabase(path), std::move(options)) {}

TextileRecognizer::TextileRecognizer(std::shared_ptr<const db::HangingDrapeDatabase> database, RecognizerOptions options)
    : db_(std::move(database)), options_(std::move(options)) {
  if (!db_) fail(RecognitionErrorCode::kDatabase, "no database given");
  options_.validate();
  state_ = loadState(*db_, options_);
}

TextileRecognizer::~TextileRecognizer() = default;

void TextileRecognizer::reload() {
  RecognizerOptions o = options();
  auto st = loadState(*db_, o);
  std::lock_guard<std::mutex> lock(mutex_);
  state_ = std::move(st);
}

bool TextileRecognizer::reloadIfChanged() {
  const auto st = state();
  std::string now;
  try {
    now = databaseFingerprint(*db_);
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, std::string("reading the database: ") + e.what());
  }
  if (now == st->fingerprint) return false;
  reload();
  return true;
}

void TextileRecognizer::setTextileFilter(std::int64_t textile_id) {
  RecognizerOptions o = options();
  o.textile_id = textile_id;
  o.textile_name.clear();
  o.validate();
  auto st = loadState(*db_, o);  // throws kUnknownTextile, keeping the old filter
  std::lock_guard<std::mutex> lock(mutex_);
  options_ = o;
  state_ = std::move(st);
}

RecognizerOptions TextileRecognizer::options() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return options_;
}

std::shared_ptr<const TextileRecognizer::State> TextileRecognizer::state() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return state_;
}

bool TextileRecognizer::ready() const { return state()->silhouettes > 0; }
std::size_t TextileRecognizer::silhouetteCount() const { return state()->silhouettes; }
std::size_t TextileRecognizer::holdPointCount() const { return state()->hold_points; }
std::vector<std::string> TextileRecognizer::loadWarnings() const { return state()->warnings; }
std::vector<db::SkippedView> TextileRecognizer::skippedViews() const { return state()->skipped; }
std::vector<std::string> TextileRecognizer::resultWarnings() const { return state()->result_warnings; }

std::vector<db::TextileRecord> TextileRecognizer::textiles() const {
  std::vector<db::TextileRecord> out;
  for (const auto& [name, t] : state()->textiles) out.push_back(t);
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  return out;
}

db::TextileRecord TextileRecognizer::textile(std::int64_t id) const {
  for (const auto& [name, t] : state()->textiles)
    if (t.id == id) return t;
  try {
    return db_->textile(id);  // added since the last load
  } catch (const db::NotFoundError&) {
    fail(RecognitionErrorCode::kUnknownTextile, "textile id " + std::to_string(id) + " is not in the database");
  } catch (const std::exception& e) {
    fail(RecognitionErrorCode::kDatabase, e.what());
  }
}

std::shared_ptr<const TextileRecognizer::StoredShape> TextileRecognizer::shape(const State& st, std::int64_t simulation_id,
                                                                            const Vec2& expected_hold) const {
  std::shared_ptr<const StoredShape> found;
  {
    std::lock_guard<std::mutex> lock(st.cache_mutex);
    const auto it = st.cache.find(simulation_id);
    if (it != st.cache.end()) found = it->second;
  }
  if (!found) {
    auto s = std::make_shared<StoredShape>();
    try {
      db::StoredDrapeMesh m = db::loadDrapeMesh(*db_, simulation_id);
      s->record = m.record;
      s->textile = m.textile;
      s->positions = std::move(m.positions);
      s->triangles = std::move(m.triangles);
      s->held = m.held_particle;
      std::string err;
      s->grid = ParticleGrid::rasterize(s->textile.outline, s->record.spacing, &err);
      if (s->grid.empty() || 3 * static_cast<Eigen::Index>(s->grid.numActive()) != s->positions.size())
        fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(simulation_id) + ": cannot rebuild its grid " + err);
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

// ---------------------------------------------------------------------------------------------------
// Recognition

namespace {

struct PreparedImage {
  HoldGeometry g;
  cv::Mat mask;      // CV_8UC1 255 = textile
  cv::Mat depth_m;   // CV_32FC1 metres (NaN = none) or empty
  bool used_depth = false;
  double relative_view_deg = 0;
  double colour_fraction = -1;
};

// Sparse depth image (nearest point per pixel) of a cloud, for the depth check.
cv::Mat depthFromPoints(const std::vector<Vec3>& pts, const vision::PinholeIntrinsics& k) {
  cv::Mat d(k.height, k.width, CV_32FC1, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  for (const Vec3& p : pts) {
    if (!p.allFinite() || !(p.z() > 1e-6)) continue;
    const int u = static_cast<int>(std::lround(k.fx * p.x() / p.z() + k.cx));
    const int v = static_cast<int>(std::lround(k.fy * p.y() / p.z() + k.cy));
    if (u < 0 || v < 0 || u >= d.cols || v >= d.rows) continue;
    float& z = d.at<float>(v, u);
    if (!(z <= p.z())) z = static_cast<float>(p.z());
  }
  return d;
}

PreparedImage prepare(const CameraObservation& obs, const RecognizerOptions& o) {
  // Sizes first: nothing is converted or allocated for an image beyond the pixel limit.
  checkPixelLimit(obs.image.cols, obs.image.rows, o.max_image_pixels, "the image");
  checkPixelLimit(obs.depth.cols, obs.depth.rows, o.max_image_pixels, "the depth image");
  checkPixelLimit(obs.intrinsics.width, obs.intrinsics.height, o.max_image_pixels, "the camera (intrinsics size)");
  PreparedImage p;
  p.g = computeHoldGeometry(obs.intrinsics, obs.hold_camera, obs.up_camera, obs.heading_camera, o.geometry);
  const cv::Size size(p.g.intrinsics.width, p.g.intrinsics.height);
  if (!obs.depth.empty()) {
    p.depth_m = depthToMetres(obs.depth);
    if (p.depth_m.size() != size)
      fail(RecognitionErrorCode::kInvalidDepth, "the depth image is " + std::to_string(p.depth_m.cols) + " x " +
                                                    std::to_string(p.depth_m.rows) + " px, the colour camera's is " +
                                                    std::to_string(size.width) + " x " + std::to_string(size.height));
  } else if (!obs.points.empty()) {
    p.depth_m = depthFromPoints(obs.points, p.g.intrinsics);
  }
  if (!obs.mask.empty()) {
    if (obs.mask.type() != CV_8UC1 || obs.mask.size() != size)
      fail(RecognitionErrorCode::kInvalidImage, "a given mask must be CV_8UC1 of the camera's image size");
    if (!obs.image.empty()) (void)toBgr8(obs.image, obs.encoding);
    cv::compare(obs.mask, 0, p.mask, cv::CMP_NE);
    return p;
  }
  cv::Mat cluster;
  int points = 0;
  if (o.segmentation.depth_mode != DepthMode::kColourOnly) {
    if (!obs.depth.empty())
      cluster = depthClusterMask(obs.depth, p.g, o.segmentation.depth, &points);
    else if (!obs.points.empty())
      cluster = pointCloudClusterMask(obs.points, p.g, o.segmentation.depth, &points);
  }
  const SegmentationResult seg = segmentTextile(obs.image, obs.encoding, p.g, o.segmentation, cluster, points);
  checkColourFraction(seg.colour_fraction, o.evidence);
  p.mask = seg.mask;
  p.used_depth = seg.used_depth;
  p.colour_fraction = seg.colour_fraction;
  return p;
}

struct Coarse {
  std::shared_ptr<const LoadedIndex> li;
  db::DrapeMatch m;
};

struct MemberFit {
  std::size_t hold_point = 0;
  double angle = 0;          // base angle (first image)
  double coarse_angle = 0;
  double score = -1;
  int dx = 0, dy = 0;
  double depth_residual = -1;
  bool reflected = false;
  double reflection_view = 0;
};

std::string frameKey(const vision::CanonicalFrame& f) {
  std::ostringstream os;
  os.precision(17);
  os << f.width_px << "x" << f.height_px << "@" << f.metres_per_pixel << "/" << f.top_margin_px << "/" << f.coverage_threshold;
  return os.str();
}

std::size_t nearestView(const std::vector<std::pair<double, vision::BitMask>>& views, double angle) {
  std::size_t best = 0;
  double bd = 1e9;
  for (std::size_t k = 0; k < views.size(); ++k) {
    const double d = circularDistance(views[k].first, angle);
    if (d < bd - 1e-9) {
      bd = d;
      best = k;
    }
  }
  return best;
}

}  // namespace

RecognitionResult TextileRecognizer::recognize(const CameraObservation& observation) const {
  return recognize(std::vector<CameraObservation>{observation});
}

RecognitionResult TextileRecognizer::recognize(const std::vector<CameraObservation>& obs) const {
  const auto t_start = Clock::now();
  const auto st = state();
  const RecognizerOptions& o = st->options;
  if (obs.empty()) fail(RecognitionErrorCode::kInvalidImage, "no images given");
  if (st->indices.empty())
    fail(RecognitionErrorCode::kEmptyDatabase,
         "the database '" + db_->path() + "' has no finished simulations with views" +
             (o.textile_id > 0 ? " for textile id " + std::to_string(o.textile_id)
                               : (o.textile_name.empty() ? std::string() : " for textile '" + o.textile_name + "'")) +
             (st->warnings.empty() ? std::string() : " (" + st->warnings.front() + ")") +
             (st->problems.empty() ? std::string() : " (" + st->problems.front() + ")"));
  if (!st->problems.empty()) {
    std::string all;
    for (const std::string& p : st->problems) all += (all.empty() ? "" : "; ") + p;
    fail(RecognitionErrorCode::kIncompleteDatabase, all);
  }

  RecognitionResult res;
  // ---- geometry, segmentation ----
  std::vector<PreparedImage> imgs;
  for (const auto& ob : obs) imgs.push_back(prepare(ob, o));
  const std::size_t n = imgs.size();
  if (n > 1) {
    const bool explicit_rel = std::all_of(obs.begin(), obs.end(), [](const auto& x) { return x.relative_view_deg.has_value(); });
    const bool headings = std::all_of(imgs.begin(), imgs.end(), [](const auto& x) { return x.g.has_heading; });
    for (std::size_t i = 0; i < n; ++i) {
      if (explicit_rel) {
        const double r = *obs[i].relative_view_deg - *obs[0].relative_view_deg;
        if (!std::isfinite(r)) fail(RecognitionErrorCode::kInvalidGeometry, "relative_view_deg is not finite");
        imgs[i].relative_view_deg = r;
      } else if (headings) {
        imgs[i].relative_view_deg = signedWrap(imgs[i].g.camera_azimuth_deg - imgs[0].g.camera_azimuth_deg);
      } else {
        fail(RecognitionErrorCode::kInvalidGeometry,
             "several images need relative_view_deg on every image or a heading reference (fixed to the gripper) on "
             "every image");
      }
    }
  }
  for (const auto& im : imgs) {
    res.geometry.push_back(im.g);
    res.relative_view_deg.push_back(im.relative_view_deg);
    res.image_masks.push_back(im.mask);
    res.depth_used = res.depth_used || im.used_depth;
  }
  res.segmentation_ms = msSince(t_start);

  // ---- canonical masks and coarse query per index ----
  const auto t_query = Clock::now();
  std::map<std::string, std::vector<vision::BitMask>> canon;
  auto canonical = [&](const vision::CanonicalFrame& f) -> const std::vector<vision::BitMask>& {
    const std::string key = frameKey(f);
    auto it = canon.find(key);
    if (it != canon.end()) return it->second;
    std::vector<vision::BitMask> masks;
    for (const auto& im : imgs) {
      vision::BitMask m = canonicaliseObservationMask(im.mask, im.g, f, o.canonicalisation);
      if (m.count() == 0)
        fail(RecognitionErrorCode::kSegmentationFailed,
             "the segmented textile lies outside the canonical window below the hold point (is the hold point right?)");
      masks.push_back(std::move(m));
    }
    return canon.emplace(key, std::move(masks)).first->second;
  };
  std::vector<Coarse> coarse;
  double coarse_margin_all = 0;
  for (const auto& li : st->indices) {
    const auto& q = canonical(li->index.frame);
    db::DrapeQueryResult r;
    try {
      // The shift range in metres, converted to this index's canonical pixels (docs/database.md).
      vision::MatchOptions mo = o.match;
      if (o.max_shift_x_m >= 0 && o.max_shift_y_m >= 0) {
        const vision::MatchOptions metric = db::metricShiftOptions(li->index.frame, o.max_shift_x_m, o.max_shift_y_m, mo.top_k);
        mo.max_dx = metric.max_dx;
        mo.max_dy = metric.max_dy;
      }
      if (n == 1) {
        r = db::queryDrape(li->index, q[0], mo);
      } else {
        std::vector<vision::FusionImage> f;
        for (std::size_t i = 0; i < n; ++i) f.push_back({q[i], imgs[i].relative_view_deg});
        r = db::queryDrapeFused(li->index, f, mo);
      }
    } catch (const std::invalid_argument& e) {
      fail(RecognitionErrorCode::kNoMatch, std::string("query: ") + e.what());
    }
    for (const auto& m : r.matches)
      if (m.class_index != db::kForeignClass) coarse.push_back({li, m});
  }
  std::stable_sort(coarse.begin(), coarse.end(), [](const Coarse& a, const Coarse& b) { return a.m.score > b.m.score; });
  {  // one entry per (textile, canonical hold point)
    std::set<std::pair<std::string, std::pair<long long, long long>>> seen;
    std::vector<Coarse> kept;
    for (auto& c : coarse) {
      const auto key = std::make_pair(c.m.textile, std::make_pair(std::llround(c.m.canonical_hold.x() * 1e4),
                                                                  std::llround(c.m.canonical_hold.y() * 1e4)));
      if (seen.insert(key).second) kept.push_back(c);
    }
    coarse.swap(kept);
  }
  if (coarse.empty() || !(coarse.front().m.score > 0))
    fail(RecognitionErrorCode::kNoMatch, "no stored silhouette overlaps the segmented textile");
  coarse_margin_all = coarse.front().m.score - (coarse.size() > 1 ? coarse[1].m.score : 0.0);
  res.query_ms = msSince(t_query);

  // ---- refinement ----
  const auto t_refine = Clock::now();
  const RefinementOptions& ro = o.refinement;
  const std::size_t n_refine = ro.enabled ? std::min<std::size_t>(static_cast<std::size_t>(ro.classes), coarse.size()) : 0;
  const int R = ro.max_shift_px;
  std::vector<std::vector<MemberFit>> fits(coarse.size());
  auto renderFor = [&](const VecX& x, const StoredShape& s, double angle, const PreparedImage& im,
                       const vision::CanonicalFrame& f) {
    if (ro.camera_projection) {
      try {
        return vision::renderSilhouette(x, s.triangles, s.held, wrapDegrees(angle), im.g.projection(), f);
      } catch (const std::invalid_argument&) {
        // camera inside the textile's reach: fall back to the orthographic projection
      }
    }
    return vision::renderSilhouette(x, s.triangles, s.held, wrapDegrees(angle), vision::SilhouetteProjection::orthographic(), f);
  };
  for (std::size_t c = 0; c < n_refine; ++c) {
    const LoadedIndex& li = *coarse[c].li;
    const auto& q = canonical(li.index.frame);
    const db::HoldPointClass& cl = li.index.classes[coarse[c].m.class_index];
    const double half = ro.half_range_deg > 0 ? ro.half_range_deg : 0.5 * std::min(li.view_step_deg, 90.0) + 1.0;
    const int steps = static_cast<int>(std::floor(half / ro.step_deg + 1e-9));
    for (std::size_t hp : cl.members) {
      const auto& views = li.views[hp];
      if (views.empty()) continue;
      MemberFit fit;
      fit.hold_point = hp;
      // Best stored base view (small shifts: the hold pixel is known).
      double best = -1;
      for (const auto& [a, mask0] : views) {
        double sum = 0;
        for (std::size_t i = 0; i < n; ++i) {
          const auto& v = views[nearestView(views, a + imgs[i].relative_view_deg)].second;
          sum += vision::bestShiftIou(q[i], v, R, R).score;
        }
        if (sum / n > best + 1e-12) {
          best = sum / n;
          fit.coarse_angle = a;
        }
      }
      // Fine azimuths with the camera's projection.
      const auto shape_ptr = shape(*st, li.index.hold_points[hp].simulation_id, li.index.hold_points[hp].hold);
      const StoredShape& s = *shape_ptr;
      for (int k = -steps; k <= steps; ++k) {
        const double a = fit.coarse_angle + k * ro.step_deg;
        double sum = 0;
        int dx = 0, dy = 0;
        for (std::size_t i = 0; i < n; ++i) {
          const vision::BitMask r = renderFor(s.positions, s, a + imgs[i].relative_view_deg, imgs[i], li.index.frame);
          const vision::ShiftedIou si = vision::bestShiftIou(q[i], r, R, R);
          sum += si.score;
          if (i == 0) {
            dx = si.dx;
            dy = si.dy;
          }
        }
        // Ties: the angle nearer to the stored view (k = 0 first, then |k| increasing by scan order).
        if (sum / n > fit.score + 1e-12 || (std::abs(sum / n - fit.score) <= 1e-12 && std::abs(k) * ro.step_deg < circularDistance(fit.angle, fit.coarse_angle))) {
          fit.score = sum / n;
          fit.angle = wrapDegrees(a);
          fit.dx = dx;
          fit.dy = dy;
        }
      }
      fits[c].push_back(fit);
    }
  }

  // Candidates: refined classes (best member), then the others.
  struct Cand {
    std::size_t coarse = 0;
    HoldCandidate h;
    std::size_t member = 0;  // index into fits[coarse]
  };
  std::vector<Cand> cands;
  for (std::size_t c = 0; c < coarse.size(); ++c) {
    const Coarse& co = coarse[c];
    const LoadedIndex& li = *co.li;
    Cand cd;
    cd.coarse = c;
    HoldCandidate& h = cd.h;
    h.textile_name = co.m.textile;
    const auto t = st->textiles.find(co.m.textile);
    h.textile_id = t != st->textiles.end() ? t->second.id : 0;
    h.class_index = co.m.class_index;
    h.canonical_hold = co.m.canonical_hold;
    for (std::size_t hp : li.index.classes[co.m.class_index].members) h.equivalent_hold_points.push_back(li.index.hold_points[hp].hold);
    h.coarse_score = co.m.score;
    h.coarse_view_angle_deg = co.m.view_angle_deg;
    std::size_t hp = co.m.hold_point;
    if (!fits[c].empty()) {
      std::size_t best = 0;
      for (std::size_t k = 1; k < fits[c].size(); ++k)
        if (fits[c][k].score > fits[c][best].score + 1e-12) best = k;
      const MemberFit& f = fits[c][best];
      cd.member = best;
      hp = f.hold_point;
      h.view_angle_deg = f.angle;
      h.dx = f.dx;
      h.dy = f.dy;
      h.score = f.score;
      h.refined = true;
    } else {
      h.view_angle_deg = co.m.view_angle_deg;
      h.dx = co.m.dx;
      h.dy = co.m.dy;
      h.score = co.m.score;
    }
    const db::IndexedHoldPoint& ih = li.index.hold_points[hp];
    h.hold_point = ih.hold;
    h.lattice_i = ih.lattice_i;
    h.lattice_j = ih.lattice_j;
    h.member_source = ih.source;
    h.simulation_id = ih.simulation_id;
    cands.push_back(std::move(cd));
  }
  if (ro.rerank && n_refine > 1)
    std::stable_sort(cands.begin(), cands.begin() + static_cast<long>(n_refine),
                     [](const Cand& a, const Cand& b) { return a.h.score > b.h.score; });

  // Confidence: the winner's silhouette score minus the runner-up class's (refined scores if both were
  // refined, else the coarse margin).
  double confidence = coarse_margin_all;
  if (cands.size() == 1)
    confidence = cands.front().h.score;
  else if (cands[0].h.refined && cands[1].h.refined)
    confidence = cands[0].h.score - cands[1].h.score;

  // Depth: choose among the winner's near-best members by the fit of predicted to measured depth.
  Cand& win = cands.front();
  const LoadedIndex& wli = *coarse[win.coarse].li;
  std::size_t depth_image = n;
  for (std::size_t i = 0; i < n; ++i)
    if (!imgs[i].depth_m.empty()) {
      depth_image = i;
      break;
    }
  auto rotationFor = [&](double base_angle, std::size_t i) {
    return imgs[i].g.camera_azimuth_deg - (base_angle + imgs[i].relative_view_deg);
  };
  auto depthResidual = [&](const VecX& x, const StoredShape& s, double base_angle) -> double {
    const PreparedImage& im = imgs[depth_image];
    const VecX ph = placeInHoldFrame(x, s.held, rotationFor(base_angle, depth_image));
    VecX pc(ph.size());
    const auto& k = im.g.intrinsics;
    double x0 = 1e18, y0 = 1e18, x1 = -1e18, y1 = -1e18;
    for (Eigen::Index v = 0; v < ph.size() / 3; ++v) {
      const Vec3 p = im.g.holdToCamera(ph.segment<3>(3 * v));
      pc.segment<3>(3 * v) = p;
      if (!(p.z() > 0.01)) continue;
      const double u = k.fx * p.x() / p.z() + k.cx, w = k.fy * p.y() / p.z() + k.cy;
      x0 = std::min(x0, u);
      x1 = std::max(x1, u);
      y0 = std::min(y0, w);
      y1 = std::max(y1, w);
    }
    const int ix0 = std::max(0, static_cast<int>(std::floor(x0)) - 2), iy0 = std::max(0, static_cast<int>(std::floor(y0)) - 2);
    const int ix1 = std::min(k.width - 1, static_cast<int>(std::ceil(x1)) + 2), iy1 = std::min(k.height - 1, static_cast<int>(std::ceil(y1)) + 2);
    if (ix1 < ix0 || iy1 < iy0) return -1;
    vision::ShadedRenderOptions rop;
    rop.intrinsics = vision::PinholeIntrinsics{k.fx, k.fy, k.cx - ix0, k.cy - iy0, ix1 - ix0 + 1, iy1 - iy0 + 1};
    rop.noise_sigma = 0;
    rop.render_mask = false;
    rop.render_depth = true;
    const vision::ShadedImage img = vision::renderShaded(pc, s.triangles, rop);
    std::vector<float> diffs;
    for (int y = 0; y < img.depth.rows; ++y) {
      const float* pd = img.depth.ptr<float>(y);
      const float* md = im.depth_m.ptr<float>(y + iy0);
      const std::uint8_t* mk = im.mask.ptr<std::uint8_t>(y + iy0);
      for (int x = 0; x < img.depth.cols; ++x)
        if (mk[x + ix0] && std::isfinite(pd[x]) && std::isfinite(md[x + ix0])) diffs.push_back(std::abs(pd[x] - md[x + ix0]));
    }
    if (static_cast<int>(diffs.size()) < ro.depth_min_pixels) return -1;
    double sum = 0;
    for (float d : diffs) sum += std::min(static_cast<double>(d), ro.depth_truncation_m);
    return sum / static_cast<double>(diffs.size());
  };
  auto& wfits = fits[win.coarse];
  const auto& wq = canonical(wli.index.frame);
  auto silhouetteScore = [&](const VecX& x, const StoredShape& s, double base) {
    double sum = 0;
    for (std::size_t i = 0; i < n; ++i)
      sum += vision::bestShiftIou(wq[i], renderFor(x, s, base + imgs[i].relative_view_deg, imgs[i], wli.index.frame), R, R).score;
    return sum / static_cast<double>(n);
  };
  if (!wfits.empty() && depth_image < n && ro.use_depth) {
    // Members within depth_member_slack of the best one, as stored and (consider_reflections) mirrored
    // front-to-back, at azimuths within depth_yaw_range_deg whose silhouette score stays within
    // depth_score_slack of the member's best: the lowest cost (1 - IoU) + depth_weight_per_m * residual.
    const double top = wfits[win.member].score;
    std::size_t best = wfits.size();
    double best_cost = std::numeric_limits<double>::infinity();
    int evaluated = 0;
    for (std::size_t k = 0; k < wfits.size(); ++k) {
      MemberFit& f = wfits[k];
      if (f.score < top - ro.depth_member_slack) continue;
      const auto sp = shape(*st, wli.index.hold_points[f.hold_point].simulation_id, wli.index.hold_points[f.hold_point].hold);
      const double floor_iou = f.score - ro.depth_score_slack;
      const double centre0 = f.angle;
      double m_cost = std::numeric_limits<double>::infinity(), m_res = -1, m_angle = f.angle, m_iou = f.score;
      bool m_reflected = false;
      for (int refl = 0; refl < (ro.consider_reflections ? 2 : 1); ++refl) {
        const VecX x = refl ? reflectAcrossView(sp->positions, sp->held, centre0) : sp->positions;
        double local_cost = std::numeric_limits<double>::infinity(), local_angle = centre0;
        auto consider = [&](double a, double iou) {
          if (iou < floor_iou) return;
          const double r = depthResidual(x, *sp, a);
          if (r < 0) return;
          const double cost = (1.0 - iou) + ro.depth_weight_per_m * r;
          if (cost < local_cost - 1e-12) {
            local_cost = cost;
            local_angle = a;
          }
          if (cost < m_cost - 1e-12) {
            m_cost = cost;
            m_res = r;
            m_angle = wrapDegrees(a);
            m_iou = iou;
            m_reflected = refl != 0;
          }
        };
        consider(centre0, refl ? silhouetteScore(x, *sp, centre0) : f.score);
        const int coarse_steps = static_cast<int>(std::floor(ro.depth_yaw_range_deg / ro.depth_yaw_step_deg + 1e-9));
        for (int j = -coarse_steps; j <= coarse_steps; ++j)
          if (j != 0) consider(centre0 + j * ro.depth_yaw_step_deg, silhouetteScore(x, *sp, centre0 + j * ro.depth_yaw_step_deg));
        if (ro.depth_yaw_step_deg > ro.step_deg && std::isfinite(local_cost)) {
          const double c = local_angle;
          const int fine = static_cast<int>(std::floor(0.5 * ro.depth_yaw_step_deg / ro.step_deg + 1e-9));
          for (int j = -fine; j <= fine; ++j)
            if (j != 0) consider(c + j * ro.step_deg, silhouetteScore(x, *sp, c + j * ro.step_deg));
        }
      }
      if (m_res < 0) continue;
      f.depth_residual = m_res;
      f.angle = m_angle;
      f.score = m_iou;
      f.reflected = m_reflected;
      f.reflection_view = centre0;
      ++evaluated;
      if (m_cost < best_cost) {
        best_cost = m_cost;
        best = k;
      }
    }
    if (best < wfits.size()) {
      res.depth_decided = ro.consider_reflections || evaluated >= 2;
      win.member = best;
      const MemberFit& f = wfits[best];
      const db::IndexedHoldPoint& ih = wli.index.hold_points[f.hold_point];
      win.h.hold_point = ih.hold;
      win.h.lattice_i = ih.lattice_i;
      win.h.lattice_j = ih.lattice_j;
      win.h.member_source = ih.source;
      win.h.simulation_id = ih.simulation_id;
      win.h.view_angle_deg = f.angle;
      win.h.score = f.score;
      win.h.depth_residual_m = f.depth_residual;
      win.h.reflected = f.reflected;
      win.h.reflection_view_deg = f.reflection_view;
    }
  } else if (depth_image < n && ro.use_depth) {
    const auto sp = shape(*st, win.h.simulation_id, win.h.hold_point);
    win.h.depth_residual_m = depthResidual(sp->positions, *sp, win.h.view_angle_deg);
  }
  res.refine_ms = msSince(t_refine);

  // ---- result ----
  const HoldCandidate& w = win.h;
  res.textile_id = w.textile_id;
  res.textile_name = w.textile_name;
  res.hold_point = w.hold_point;
  res.canonical_hold_point = w.canonical_hold;
  res.equivalent_hold_points = w.equivalent_hold_points;
  res.lattice_i = w.lattice_i;
  res.lattice_j = w.lattice_j;
  res.simulation_id = w.simulation_id;
  res.view_angle_deg = w.view_angle_deg;
  res.camera_azimuth_deg = imgs[0].g.camera_azimuth_deg;
  res.rotation_deg = signedWrap(rotationFor(w.view_angle_deg, 0));
  res.score = w.score;
  res.depth_residual_m = w.depth_residual_m;
  res.reflected = w.reflected;
  res.reflection_view_deg = w.reflection_view_deg;
  res.coarse_margin = coarse_margin_all;
  res.confidence = confidence;
  for (std::size_t k = 0; k < cands.size() && static_cast<int>(k) < o.match.top_k; ++k) res.top_k.push_back(cands[k].h);

  // Front/back ambiguity: one view direction explains a shape and its mirror image across the vertical
  // plane perpendicular to the view equally well (orthographic silhouettes are identical). A second view
  // direction or a depth decision resolves it.
  {
    bool second_direction = false;
    for (std::size_t i = 1; i < n; ++i) {
      const double r = std::fmod(std::abs(imgs[i].relative_view_deg), 180.0);
      if (std::min(r, 180.0 - r) > 5.0) second_direction = true;
    }
    res.front_back_ambiguous = !second_direction && !res.depth_decided;
  }

  // Grasp poses and the matched silhouette.
  const auto sp = shape(*st, w.simulation_id, w.hold_point);
  try {
    const VecX x = w.reflected ? reflectAcrossView(sp->positions, sp->held, w.reflection_view_deg) : sp->positions;
    const double rot0 = rotationFor(w.view_angle_deg, 0);
    // The images with depth (the first one's hold frame is the common frame of the fit).
    std::vector<DepthView> views;
    if (o.shape_fit.enabled && !imgs[0].depth_m.empty()) {
      for (std::size_t i = 0; i < n; ++i) {
        if (imgs[i].depth_m.empty()) continue;
        // Image i sees the shape turned by rotationFor(view, i) about the hold axis, the common frame by
        // rot0: a point p of the common frame is R_i Rz(rot_i - rot0) p + hold_i in camera i.
        DepthView v;
        v.depth = imgs[i].depth_m;
        v.mask = imgs[i].mask;
        v.intrinsics = imgs[i].g.intrinsics;
        v.rotation = imgs[i].g.rotation_camera_hold * rotationZ(rotationFor(w.view_angle_deg, i) - rot0);
        v.translation = imgs[i].g.hold_camera;
        views.push_back(v);
        if (!o.shape_fit.fuse_views) break;
      }
    }
    if (!views.empty()) {
      // Deform the matched shape onto the measured surfaces, then read the poses from it (in H already:
      // rotation 0 about the held particle, which the fit keeps at the hold point).
      const HoldGeometry& g0 = imgs[0].g;
      const VecX ph = placeInHoldFrame(x, sp->held, rot0);
      const VecX xh = fitShapeToDepthViews(ph, sp->triangles, sp->held, views, o.shape_fit, &res.shape_fit);
      res.grasp_poses = computeGraspPoses(sp->textile.outline, sp->grid, xh, sp->held, 0.0, g0, o.grasp);
    } else {
      res.grasp_poses = computeGraspPoses(sp->textile.outline, sp->grid, x, sp->held, rot0, imgs[0].g, o.grasp);
    }
    res.frame = wli.index.frame;
    res.query_masks = canonical(wli.index.frame);
    res.matched_mask = renderFor(x, *sp, w.view_angle_deg, imgs[0], wli.index.frame);
  } catch (const std::invalid_argument& e) {
    fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(w.simulation_id) + ": " + e.what());
  }
  res.colour_fraction = imgs[0].colour_fraction;
  res.coverage = silhouetteCoverage(res.query_masks.front(), res.matched_mask, R);
  checkEvidence(res.score, res.coverage, o.evidence);
  res.skipped_views = st->skipped.size();
  res.warnings = st->result_warnings;
  res.total_ms = msSince(t_start);
  return res;
}

cv::Mat TextileRecognizer::debugImage(const CameraObservation& obs, const RecognitionResult& r) const {
  if (r.geometry.empty() || r.simulation_id <= 0)
    fail(RecognitionErrorCode::kInvalidOptions, "debugImage needs the result of a successful recognize()");
  const HoldGeometry& g = r.geometry.front();
  cv::Mat out;
  if (!obs.image.empty())
    out = toBgr8(obs.image, obs.encoding).clone();
  else
    out = cv::Mat(g.intrinsics.height, g.intrinsics.width, CV_8UC3, cv::Scalar(0, 0, 0));
  if (out.cols != g.intrinsics.width || out.rows != g.intrinsics.height)
    fail(RecognitionErrorCode::kInvalidImage, "the observation does not match the result's camera");
  if (!r.image_masks.empty() && r.image_masks[0].size() == out.size()) {
    cv::Mat tint(out.size(), CV_8UC3, cv::Scalar(0, 200, 0));
    cv::Mat blended;
    cv::addWeighted(out, 0.6, tint, 0.4, 0, blended);
    blended.copyTo(out, r.image_masks[0]);
  }
  // Matched shape rendered into the camera.
  const auto sp = shape(*state(), r.simulation_id, r.hold_point);
  const VecX x = r.reflected ? reflectAcrossView(sp->positions, sp->held, r.reflection_view_deg) : sp->positions;
  const VecX ph = placeInHoldFrame(x, sp->held, r.rotation_deg);
  VecX pc(ph.size());
  for (Eigen::Index v = 0; v < ph.size() / 3; ++v) pc.segment<3>(3 * v) = g.holdToCamera(ph.segment<3>(3 * v));
  vision::ShadedRenderOptions rop;
  rop.intrinsics = g.intrinsics;
  rop.noise_sigma = 0;
  rop.render_depth = false;
  rop.render_mask = true;
  const vision::ShadedImage img = vision::renderShaded(pc, sp->triangles, rop);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(img.mask, contours, cv::RETR_LIST, cv::CHAIN_APPROX_SIMPLE);
  cv::drawContours(out, contours, -1, cv::Scalar(0, 0, 255), 2);
  auto project = [&](const Vec3& p, cv::Point* px) {
    if (!(p.z() > 1e-6)) return false;
    *px = cv::Point(static_cast<int>(std::lround(g.intrinsics.fx * p.x() / p.z() + g.intrinsics.cx)),
                    static_cast<int>(std::lround(g.intrinsics.fy * p.y() / p.z() + g.intrinsics.cy)));
    return true;
  };
  for (const GraspPose& gp : r.grasp_poses) {
    cv::Point a, b;
    if (!project(gp.position_camera, &a)) continue;
    const cv::Scalar colour = gp.kind == "corner" ? cv::Scalar(255, 0, 255) : cv::Scalar(255, 255, 0);
    cv::circle(out, a, 5, colour, 2);
    if (project(gp.position_camera + 0.05 * gp.rotation_camera.col(2), &b)) cv::line(out, a, b, cv::Scalar(255, 0, 0), 1);
    cv::putText(out, gp.name, a + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.4, colour, 1);
  }
  cv::Point h;
  if (project(g.hold_camera, &h)) cv::drawMarker(out, h, cv::Scalar(0, 255, 255), cv::MARKER_CROSS, 14, 2);
  std::ostringstream os;
  os.precision(3);
  os << r.textile_name << "  hold (" << r.hold_point.x() << ", " << r.hold_point.y() << ") m  view " << r.view_angle_deg
     << " deg  score " << r.score << "  conf " << r.confidence;
  cv::putText(out, os.str(), cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3);
  cv::putText(out, os.str(), cv::Point(8, 20), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(255, 255, 255), 1);
  return out;
}

std::vector<std::size_t> chooseFusionPartners(double yaw_deg, const std::vector<double>& earlier_yaws_deg, int max_views,
                                              double min_separation_deg) {
  std::vector<std::size_t> chosen;
  std::vector<double> yaws{yaw_deg};
  for (std::size_t k = 0; k < earlier_yaws_deg.size() && static_cast<int>(yaws.size()) < max_views; ++k) {
    bool distinct = true;  // the partner must differ from every image already chosen
    for (double y : yaws) distinct = distinct && std::fabs(std::remainder(earlier_yaws_deg[k] - y, 360.0)) >= min_separation_deg;
    if (!distinct) continue;
    chosen.push_back(k);
    yaws.push_back(earlier_yaws_deg[k]);
  }
  return chosen;
}

}  // namespace recognition
}  // namespace textile_handling
