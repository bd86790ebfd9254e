#include "textile_handling/db/drape_match_evaluation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "textile_handling/sim/timing.h"
#include "textile_handling/vision/mask_cv.h"

namespace textile_handling {
namespace db {

cv::Mat segmentAgainstBackground(const cv::Mat& bgr, const SegmentationOptions& o) {
  if (bgr.empty() || bgr.type() != CV_8UC3) throw std::invalid_argument("segmentation needs a non-empty CV_8UC3 image");
  if (!(o.threshold >= 0) || !std::isfinite(o.threshold) || o.open_radius_px < 0)
    throw std::invalid_argument("segmentation: threshold must be finite and >= 0, radius >= 0");
  cv::Mat mask(bgr.size(), CV_8UC1);
  const double t2 = o.threshold * o.threshold;
  for (int y = 0; y < bgr.rows; ++y) {
    const cv::Vec3b* p = bgr.ptr<cv::Vec3b>(y);
    std::uint8_t* m = mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < bgr.cols; ++x) {
      double d2 = 0;
      for (int c = 0; c < 3; ++c) {
        const double d = static_cast<double>(p[x][c]) - o.background_bgr[static_cast<std::size_t>(c)];
        d2 += d * d;
      }
      m[x] = d2 > t2 ? 255 : 0;
    }
  }
  if (o.open_radius_px > 0) {
    const cv::Mat k = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * o.open_radius_px + 1, 2 * o.open_radius_px + 1));
    cv::morphologyEx(mask, mask, cv::MORPH_OPEN, k);
  }
  if (o.largest_component) {
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
    if (n > 2) {
      int best = 1;
      for (int l = 2; l < n; ++l)
        if (stats.at<int>(l, cv::CC_STAT_AREA) > stats.at<int>(best, cv::CC_STAT_AREA)) best = l;
      mask = labels == best;
    }
  }
  return mask;
}

HeldOutShape heldOutShapeFromMesh(const StoredDrapeMesh& mesh, const std::string& variant) {
  HeldOutShape s;
  s.textile = mesh.textile.outline.name;
  s.hold = mesh.record.hold;
  s.variant = variant;
  s.positions = mesh.positions;
  s.triangles = mesh.triangles;
  s.held_particle = mesh.held_particle;
  return s;
}

vision::BitMask renderHeldOutQuery(const HeldOutShape& shape, double azimuth_deg, const QueryRenderOptions& o,
                                   const vision::CanonicalFrame& frame, std::uint64_t seed) {
  if (shape.held_particle < 0 || 3 * shape.held_particle >= shape.positions.size())
    throw std::invalid_argument("held-out shape has no valid held particle");
  const Vec3 hold = shape.positions.segment<3>(3 * shape.held_particle);
  std::mt19937_64 rng(seed);
  if (o.mode == QueryRenderMode::kSilhouetteNoise) {
    vision::BitMask m = vision::renderSilhouette(shape.positions, shape.triangles, hold, azimuth_deg,
                                                 vision::SilhouetteProjection::orthographic(), frame);
    const vision::BitMask orig = m;
    std::uniform_real_distribution<double> u(0, 1);
    for (int y = 0; y < m.height(); ++y)
      for (int x = 0; x < m.width(); ++x) {
        const bool v = orig.get(x, y);
        bool boundary = false;
        const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
        for (int k = 0; k < 4; ++k)
          if (nx[k] >= 0 && ny[k] >= 0 && nx[k] < m.width() && ny[k] < m.height() && orig.get(nx[k], ny[k]) != v)
            boundary = true;
        if (boundary && u(rng) < o.flip_probability) m.set(x, y, !v);
      }
    return m;
  }
  vision::ShadedRenderOptions r;
  r.intrinsics = o.intrinsics;
  r.camera = vision::cameraPoseForView(hold, azimuth_deg, o.camera_distance, o.camera_height);
  r.noise_sigma = o.noise_sigma;
  r.background = vision::BackgroundType::kUniform;
  r.background_bgr = o.segmentation.background_bgr;
  r.seed = seed;
  r.render_depth = false;
  r.render_mask = false;
  const vision::ShadedImage img = vision::renderShaded(shape.positions, shape.triangles, r);
  const cv::Mat mask = segmentAgainstBackground(img.bgr, o.segmentation);
  Vec2 hold_px;
  double depth = 0;
  if (!vision::projectPoint(o.intrinsics, r.camera, hold, &hold_px, &depth))
    throw std::invalid_argument("hold point behind the camera");
  std::normal_distribution<double> n(0.0, o.hold_pixel_sigma_px);
  if (o.hold_pixel_sigma_px > 0) hold_px += Vec2(n(rng), n(rng));
  return vision::canonicaliseCameraMask(mask, hold_px, vision::metresPerPixelAtDepth(o.intrinsics, depth), frame);
}

double MatchEvaluation::meanQueryMs() const {
  if (query_ms.empty()) return 0;
  double s = 0;
  for (double v : query_ms) s += v;
  return s / static_cast<double>(query_ms.size());
}

double MatchEvaluation::percentileQueryMs(double p) const {
  if (query_ms.empty()) return 0;
  std::vector<double> v = query_ms;
  std::sort(v.begin(), v.end());
  // Nearest-rank percentile.
  const double rank = std::ceil(p / 100.0 * static_cast<double>(v.size()));
  const std::size_t k = static_cast<std::size_t>(std::clamp(rank - 1.0, 0.0, static_cast<double>(v.size() - 1)));
  return v[k];
}

namespace {

void count(const DrapeMatchIndex& index, const DrapeQueryResult& r, std::size_t truth, double ms, MatchEvaluation& e) {
  ++e.queries;
  e.query_ms.push_back(ms);
  if (r.matches.empty()) {
    e.confusion[{truth, kForeignClass}]++;
    return;
  }
  const std::size_t pred = r.matches.front().class_index;
  e.confusion[{truth, pred}]++;
  // Top-5 looks at the whole list, also when a foreign entry (a distractor) won.
  for (std::size_t k = 0; k < r.matches.size() && k < 5; ++k)
    if (r.matches[k].class_index == truth) {
      ++e.top5;
      break;
    }
  if (pred == kForeignClass) return;
  if (pred == truth) ++e.exact;
  if (index.classesNeighbour(truth, pred, false)) ++e.within_one;
  if (index.classesNeighbour(truth, pred, true)) ++e.within_one_diagonal;
}

}  // namespace

std::vector<HeldOutPair> renderHeldOutPairs(const DrapeMatchIndex& index, const std::vector<HeldOutShape>& shapes,
                                            const EvaluationOptions& o) {
  if (o.pairs_per_shape < 1) throw std::invalid_argument("pairs_per_shape must be >= 1");
  if (!(o.stored_step_deg > 2 * o.min_offset_deg) || o.min_offset_deg < 0)
    throw std::invalid_argument("need 0 <= min_offset_deg < stored_step_deg / 2");
  if (!(o.max_pair_angle_deg >= o.min_pair_angle_deg)) throw std::invalid_argument("need min <= max pair angle");
  std::vector<HeldOutPair> pairs;
  std::vector<std::uint64_t> seeds;
  std::mt19937_64 rng(o.seed);
  const int slots = static_cast<int>(std::lround(360.0 / o.stored_step_deg));
  std::uniform_int_distribution<int> slot(0, std::max(0, slots - 1));
  std::uniform_real_distribution<double> off(o.min_offset_deg, o.stored_step_deg - o.min_offset_deg);
  std::uniform_real_distribution<double> turn(o.min_pair_angle_deg, o.max_pair_angle_deg);
  for (std::size_t s = 0; s < shapes.size(); ++s) {
    const auto truth = index.classOf(shapes[s].textile, shapes[s].hold);
    if (!truth)
      throw std::invalid_argument("held-out hold point (" + std::to_string(shapes[s].hold.x()) + ", " +
                                  std::to_string(shapes[s].hold.y()) + ") of '" + shapes[s].textile +
                                  "' is not a hold point of the database");
    for (int k = 0; k < o.pairs_per_shape; ++k) {
      HeldOutPair p;
      p.shape = s;
      p.truth_class = *truth;
      // One draw per statement: the order of the draws must not depend on the compiler's order of
      // evaluating the operands of one expression (unspecified in C++).
      const int first_slot = slot(rng);
      const double first_offset = off(rng);
      p.a1 = first_slot * o.stored_step_deg + first_offset;
      // The second azimuth also falls between stored views: turn, then re-draw the offset in that slot.
      const double a2 = p.a1 + turn(rng);
      p.a2 = std::floor(a2 / o.stored_step_deg) * o.stored_step_deg + off(rng);
      pairs.push_back(std::move(p));
      seeds.push_back(rng());
    }
  }
  std::vector<std::string> errors(pairs.size());
#pragma omp parallel for schedule(dynamic)
  for (long k = 0; k < static_cast<long>(pairs.size()); ++k) {
    HeldOutPair& p = pairs[static_cast<std::size_t>(k)];
    const std::uint64_t seed = seeds[static_cast<std::size_t>(k)];
    try {
      p.m1 = renderHeldOutQuery(shapes[p.shape], std::fmod(p.a1, 360.0), o.render, index.frame, seed);
      p.m2 = renderHeldOutQuery(shapes[p.shape], std::fmod(p.a2, 360.0), o.render, index.frame, seed + 1);
    } catch (const std::exception& e) {
      errors[static_cast<std::size_t>(k)] = e.what();
    }
  }
  for (const auto& e : errors)
    if (!e.empty()) throw std::invalid_argument("rendering a held-out query failed: " + e);
  return pairs;
}

std::pair<MatchEvaluation, MatchEvaluation> evaluatePairs(const DrapeMatchIndex& index,
                                                          const std::vector<HeldOutPair>& pairs,
                                                          const EvaluationOptions& o) {
  MatchEvaluation single, fused;
  single.experiment = "single_view";
  fused.experiment = "two_view";
  using Clock = std::chrono::steady_clock;
  for (const HeldOutPair& p : pairs) {
    for (const vision::BitMask* m : {&p.m1, &p.m2}) {
      if (m->count() == 0) {  // nothing segmented: a failed query
        ++single.queries;
        single.confusion[{p.truth_class, kForeignClass}]++;
        continue;
      }
      const auto t0 = Clock::now();
      const DrapeQueryResult r = queryDrape(index, *m, o.match);
      count(index, r, p.truth_class, msSince(t0), single);
    }
    if (p.m1.count() == 0 || p.m2.count() == 0) {
      ++fused.queries;
      fused.confusion[{p.truth_class, kForeignClass}]++;
      continue;
    }
    std::vector<vision::FusionImage> imgs(2);
    imgs[0].mask = p.m1;
    imgs[0].relative_view_deg = 0;
    imgs[1].mask = p.m2;
    imgs[1].relative_view_deg = p.a2 - p.a1;
    const auto t0 = Clock::now();
    const DrapeQueryResult r = queryDrapeFused(index, imgs, o.match);
    count(index, r, p.truth_class, msSince(t0), fused);
  }
  return {single, fused};
}

std::pair<MatchEvaluation, MatchEvaluation> evaluateHeldOut(const DrapeMatchIndex& index,
                                                            const std::vector<HeldOutShape>& shapes,
                                                            const EvaluationOptions& options) {
  return evaluatePairs(index, renderHeldOutPairs(index, shapes, options), options);
}

}  // namespace db
}  // namespace textile_handling
