// The stages of TextileRecognizer::recognize() from the camera images to the ranked candidates:
// geometry and segmentation, canonical masks and the coarse query, the refinement at fine azimuths and
// the ranking (recognizer_stages.h lists the order).
#include <algorithm>
#include <cmath>
#include <set>
#include <sstream>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "recognizer_stages.h"
#include "textile_handling/recognition/point_cloud_segmentation.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace recognition {
namespace detail {

namespace {

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

const std::vector<vision::BitMask>& RecognitionRun::canonical(const vision::CanonicalFrame& f) {
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
}

vision::BitMask renderFor(const RefinementOptions& ro, const VecX& x, const TextileRecognizer::StoredShape& s, double angle,
                          const PreparedImage& im, const vision::CanonicalFrame& f) {
  if (ro.camera_projection) {
    try {
      return vision::renderSilhouette(x, s.silhouette_triangles, s.held, wrapDegrees(angle), im.g.projection(), f);
    } catch (const std::invalid_argument&) {
      // camera inside the textile's reach: fall back to the orthographic projection
    }
  }
  return vision::renderSilhouette(x, s.silhouette_triangles, s.held, wrapDegrees(angle), vision::SilhouetteProjection::orthographic(), f);
}

void checkLoadedState(const RecognitionRun& run, const std::string& database_path) {
  const TextileRecognizer::State& st = run.st;
  const RecognizerOptions& o = run.o;
  if (run.obs.empty()) fail(RecognitionErrorCode::kInvalidImage, "no images given");
  if (st.indices.empty())
    fail(RecognitionErrorCode::kEmptyDatabase,
         "the database '" + database_path + "' has no finished simulations with views" +
             (o.textile_id > 0 ? " for textile id " + std::to_string(o.textile_id)
                               : (o.textile_name.empty() ? std::string() : " for textile '" + o.textile_name + "'")) +
             (st.warnings.empty() ? std::string() : " (" + st.warnings.front() + ")") +
             (st.problems.empty() ? std::string() : " (" + st.problems.front() + ")"));
  if (!st.problems.empty()) {
    std::string all;
    for (const std::string& p : st.problems) all += (all.empty() ? "" : "; ") + p;
    fail(RecognitionErrorCode::kIncompleteDatabase, all);
  }
}

void prepareImages(RecognitionRun& run) {
  const std::vector<CameraObservation>& obs = run.obs;
  std::vector<PreparedImage>& imgs = run.imgs;
  RecognitionResult& res = run.res;
  for (const auto& ob : obs) imgs.push_back(prepare(ob, run.o));
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
  res.segmentation_ms = msSince(run.t_start);
}

vision::MatchOptions coarseMatchOptions(const RecognitionRun& run, const LoadedIndex& li) {
  // The shift range in metres, converted to this index's canonical pixels (docs/database.md).
  vision::MatchOptions mo = run.o.match;
  if (run.o.max_shift_x_m >= 0 && run.o.max_shift_y_m >= 0) {
    const vision::MatchOptions metric = db::metricShiftOptions(li.index.frame, run.o.max_shift_x_m, run.o.max_shift_y_m, mo.top_k);
    mo.max_dx = metric.max_dx;
    mo.max_dy = metric.max_dy;
  }
  return mo;
}

double bestSingleImageScore(RecognitionRun& run, std::size_t i) {
  double best = 0;
  for (const auto& li : run.st.indices) {
    try {
      const db::DrapeQueryResult r = db::queryDrape(li->index, run.canonical(li->index.frame)[i], coarseMatchOptions(run, *li));
      for (const auto& m : r.matches)
        if (m.class_index != db::kForeignClass) best = std::max(best, m.score);
    } catch (const std::invalid_argument&) {
      // an index this image cannot be queried against contributes nothing
    }
  }
  return best;
}

void coarseQuery(RecognitionRun& run) {
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  std::vector<Coarse>& coarse = run.coarse;
  const auto t_query = Clock::now();
  for (const auto& li : run.st.indices) {
    const auto& q = run.canonical(li->index.frame);
    db::DrapeQueryResult r;
    try {
      const vision::MatchOptions mo = coarseMatchOptions(run, *li);
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
  run.coarse_margin_all = coarse.front().m.score - (coarse.size() > 1 ? coarse[1].m.score : 0.0);
  run.res.query_ms = msSince(t_query);
}

void refineClasses(RecognitionRun& run) {
  run.t_refine = Clock::now();
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  const std::vector<Coarse>& coarse = run.coarse;
  const RefinementOptions& ro = run.o.refinement;
  run.n_refine = ro.enabled ? std::min<std::size_t>(static_cast<std::size_t>(ro.classes), coarse.size()) : 0;
  const int R = ro.max_shift_px;
  run.fits.assign(coarse.size(), {});
  for (std::size_t c = 0; c < run.n_refine; ++c) {
    const LoadedIndex& li = *coarse[c].li;
    const auto& q = run.canonical(li.index.frame);
    const db::HoldPointClass& cl = li.index.classes[coarse[c].m.class_index];
    const double half = ro.half_range_deg > 0 ? ro.half_range_deg : 0.5 * std::min(li.view_step_deg, 90.0) + 1.0;
    const int steps = static_cast<int>(std::floor(half / ro.step_deg + 1e-9));
    const int stride = std::max(1, static_cast<int>(std::lround(ro.coarse_step_deg / ro.step_deg)));
    // Cheap pass: every member's best stored base view (small shifts: the hold pixel is known).
    std::vector<MemberFit> members;
    for (std::size_t hp : cl.members) {
      const auto& views = li.views[hp];
      if (views.empty()) continue;
      MemberFit fit;
      fit.hold_point = hp;
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
      fit.coarse_score = best;
      members.push_back(fit);
    }
    // Only the best-matching members are rendered at fine azimuths; they keep the class's order, so a
    // class with no more members than the cap is refined exactly as without it.
    if (ro.members > 0 && members.size() > static_cast<std::size_t>(ro.members)) {
      std::vector<MemberFit> ranked = members;
      std::stable_sort(ranked.begin(), ranked.end(),
                       [](const MemberFit& a, const MemberFit& b) { return a.coarse_score > b.coarse_score; });
      const double cut = ranked[static_cast<std::size_t>(ro.members) - 1].coarse_score;
      std::size_t ties = static_cast<std::size_t>(ro.members);  // slots left for members scoring exactly `cut`
      for (const MemberFit& m : members) ties -= m.coarse_score > cut;
      std::vector<MemberFit> kept;
      for (const MemberFit& m : members)
        if (m.coarse_score > cut || (m.coarse_score == cut && ties > 0 && ties--)) kept.push_back(m);
      members.swap(kept);
    }
    for (MemberFit fit : members) {
      const std::size_t hp = fit.hold_point;
      // Fine azimuths with the camera's projection.
      const auto shape_ptr = run.shape(li.index.hold_points[hp].simulation_id, li.index.hold_points[hp].hold);
      const TextileRecognizer::StoredShape& s = *shape_ptr;
      int best_k = 0;
      auto evaluate = [&](int k) {
        const double a = fit.coarse_angle + k * ro.step_deg;
        double sum = 0;
        int dx = 0, dy = 0;
        for (std::size_t i = 0; i < n; ++i) {
          const vision::BitMask r = renderFor(ro, s.positions, s, a + imgs[i].relative_view_deg, imgs[i], li.index.frame);
          const vision::ShiftedIou si = vision::bestShiftIou(q[i], r, R, R);
          sum += si.score;
          if (i == 0) {
            dx = si.dx;
            dy = si.dy;
          }
        }
        // Ties: the angle nearer to the stored view.
        if (sum / n > fit.score + 1e-12 || (std::abs(sum / n - fit.score) <= 1e-12 && std::abs(k) * ro.step_deg < circularDistance(fit.angle, fit.coarse_angle))) {
          fit.score = sum / n;
          fit.angle = wrapDegrees(a);
          fit.dx = dx;
          fit.dy = dy;
          best_k = k;
        }
      };
      // Coarse to fine: every stride-th azimuth step, then the steps between around the best (the
      // silhouette's IoU changes smoothly with the azimuth, so the best lies next to the best coarse step).
      for (int k = -(steps / stride) * stride; k <= steps; k += stride) evaluate(k);
      const int centre = best_k;
      for (int k = std::max(-steps, centre - stride + 1); k <= std::min(steps, centre + stride - 1); ++k)
        if (k != centre) evaluate(k);
      run.fits[c].push_back(fit);
    }
  }
}

void rankCandidates(RecognitionRun& run) {
  const std::vector<Coarse>& coarse = run.coarse;
  const std::vector<std::vector<MemberFit>>& fits = run.fits;
  std::vector<Candidate>& cands = run.cands;
  // Candidates: refined classes (best member), then the others.
  for (std::size_t c = 0; c < coarse.size(); ++c) {
    const Coarse& co = coarse[c];
    const LoadedIndex& li = *co.li;
    Candidate cd;
    cd.coarse = c;
    HoldCandidate& h = cd.h;
    h.textile_name = co.m.textile;
    const auto t = run.st.textiles.find(co.m.textile);
    h.textile_id = t != run.st.textiles.end() ? t->second.id : 0;
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
  if (run.o.refinement.rerank && run.n_refine > 1)
    std::stable_sort(cands.begin(), cands.begin() + static_cast<long>(run.n_refine),
                     [](const Candidate& a, const Candidate& b) { return a.h.score > b.h.score; });

  // Confidence: the winner's silhouette score minus the runner-up class's (refined scores if both were
  // refined, else the coarse margin).
  run.confidence = run.coarse_margin_all;
  if (cands.size() == 1)
    run.confidence = cands.front().h.score;
  else if (cands[0].h.refined && cands[1].h.refined)
    run.confidence = cands[0].h.score - cands[1].h.score;
}

}  // namespace detail
}  // namespace recognition
}  // namespace textile_handling
