// The stages of TextileRecognizer::recognize() after the ranking: the depth fit that chooses the
// winner's member, azimuth and chirality, the result's fields, the grasp poses (with the shape fit to
// depth) and the evidence checks (recognizer_stages.h lists the order).
#include <algorithm>
#include <cmath>
#include <limits>

#include "recognizer_stages.h"
#include "textile_handling/sim/timing.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace recognition {
namespace detail {

namespace {

using StoredShape = TextileRecognizer::StoredShape;

// Truncated mean |predicted - measured| depth [m] of shape `x` (stored shape `s`) at base view
// `base_angle` in image `depth_image`, over the segmented pixels both cover; -1 if fewer than
// depth_min_pixels pixels compare.
double depthResidual(const RecognitionRun& run, std::size_t depth_image, const VecX& x, const StoredShape& s,
                     double base_angle) {
  const RefinementOptions& ro = run.o.refinement;
  const std::vector<PreparedImage>& imgs = run.imgs;
  const PreparedImage& im = imgs[depth_image];
  const VecX ph = placeInHoldFrame(x, s.held, run.rotationFor(base_angle, depth_image));
  VecX pc(ph.size());
  const auto& k = im.g.intrinsics;
  for (Eigen::Index v = 0; v < ph.size() / 3; ++v) pc.segment<3>(3 * v) = im.g.holdToCamera(ph.segment<3>(3 * v));
  const cv::Rect box = vision::projectedBox(pc, k, 2);
  if (box.empty()) return -1;
  const int ix0 = box.x, iy0 = box.y;
  const vision::ShadedImage img = vision::renderDepthCrop(pc, s.triangles, k, box, false);
  std::vector<float> diffs;
  for (int y = 0; y < img.depth.rows; ++y) {
    const float* pd = img.depth.ptr<float>(y);
    const float* md = im.depth_m.ptr<float>(y + iy0);
    const std::uint8_t* mk = im.mask.ptr<std::uint8_t>(y + iy0);
    for (int col = 0; col < img.depth.cols; ++col)
      if (mk[col + ix0] && std::isfinite(pd[col]) && std::isfinite(md[col + ix0]))
        diffs.push_back(std::abs(pd[col] - md[col + ix0]));
  }
  if (static_cast<int>(diffs.size()) < ro.depth_min_pixels) return -1;
  double sum = 0;
  for (float d : diffs) sum += std::min(static_cast<double>(d), ro.depth_truncation_m);
  return sum / static_cast<double>(diffs.size());
}

// Mean best-shift IoU over the images of shape `x` at base view `base` against the canonical masks `wq`.
double silhouetteScore(const RecognitionRun& run, const std::vector<vision::BitMask>& wq, const vision::CanonicalFrame& frame,
                       const VecX& x, const StoredShape& s, double base) {
  const RefinementOptions& ro = run.o.refinement;
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  const int R = ro.max_shift_px;
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i)
    sum += vision::bestShiftIou(wq[i], renderFor(ro, x, s, base + imgs[i].relative_view_deg, imgs[i], frame), R, R).score;
  return sum / static_cast<double>(n);
}

// Median depthResidual over `depth_images` of those with a residual (the mean of the middle two for an
// even count): one odd image among three does not move it. -1 if none has one.
double medianDepthResidual(const RecognitionRun& run, const std::vector<std::size_t>& depth_images, const VecX& x,
                           const StoredShape& s, double base_angle) {
  std::vector<double> r;
  for (std::size_t i : depth_images) {
    const double v = depthResidual(run, i, x, s, base_angle);
    if (v >= 0) r.push_back(v);
  }
  if (r.empty()) return -1.0;
  std::sort(r.begin(), r.end());
  const std::size_t m = r.size() / 2;
  return r.size() % 2 ? r[m] : 0.5 * (r[m - 1] + r[m]);
}

// One member of the winning class, as stored and (consider_reflections) mirrored front-to-back, at
// azimuths within depth_yaw_range_deg whose silhouette score stays within depth_score_slack of the
// member's best: the lowest cost (1 - IoU) + depth_weight_per_m * residual (median over `depth_images`). Updates `f` and returns
// true with the cost in *cost if some azimuth had a depth residual; false (f unchanged) otherwise.
bool fitMemberByDepth(const RecognitionRun& run, const std::vector<std::size_t>& depth_images, const LoadedIndex& wli,
                      const std::vector<vision::BitMask>& wq, MemberFit& f, double* cost) {
  const RefinementOptions& ro = run.o.refinement;
  const auto sp = run.shape(wli.index.hold_points[f.hold_point].simulation_id, wli.index.hold_points[f.hold_point].hold);
  auto silhouetteAt = [&](const VecX& x, double base) { return silhouetteScore(run, wq, wli.index.frame, x, *sp, base); };
  const double floor_iou = f.score - ro.depth_score_slack;
  const double centre0 = f.angle;
  double m_cost = std::numeric_limits<double>::infinity(), m_res = -1, m_angle = f.angle, m_iou = f.score;
  bool m_reflected = false;
  for (int refl = 0; refl < (ro.consider_reflections ? 2 : 1); ++refl) {
    const VecX x = refl ? reflectAcrossView(sp->positions, sp->held, centre0) : sp->positions;
    double local_cost = std::numeric_limits<double>::infinity(), local_angle = centre0;
    auto consider = [&](double a, double iou) {
      if (iou < floor_iou) return;
      const double r = medianDepthResidual(run, depth_images, x, *sp, a);
      if (r < 0) return;
      const double c = (1.0 - iou) + ro.depth_weight_per_m * r;
      if (c < local_cost - 1e-12) {
        local_cost = c;
        local_angle = a;
      }
      if (c < m_cost - 1e-12) {
        m_cost = c;
        m_res = r;
        m_angle = wrapDegrees(a);
        m_iou = iou;
        m_reflected = refl != 0;
      }
    };
    consider(centre0, refl ? silhouetteAt(x, centre0) : f.score);
    const int coarse_steps = static_cast<int>(std::floor(ro.depth_yaw_range_deg / ro.depth_yaw_step_deg + 1e-9));
    for (int j = -coarse_steps; j <= coarse_steps; ++j)
      if (j != 0) consider(centre0 + j * ro.depth_yaw_step_deg, silhouetteAt(x, centre0 + j * ro.depth_yaw_step_deg));
    if (ro.depth_yaw_step_deg > ro.step_deg && std::isfinite(local_cost)) {
      const double c = local_angle;
      const int fine = static_cast<int>(std::floor(0.5 * ro.depth_yaw_step_deg / ro.step_deg + 1e-9));
      for (int j = -fine; j <= fine; ++j)
        if (j != 0) consider(c + j * ro.step_deg, silhouetteAt(x, c + j * ro.step_deg));
    }
  }
  if (m_res < 0) return false;
  f.depth_residual = m_res;
  f.angle = m_angle;
  f.score = m_iou;
  f.reflected = m_reflected;
  f.reflection_view = centre0;
  *cost = m_cost;
  return true;
}

}  // namespace

void fitDepth(RecognitionRun& run) {
  const RefinementOptions& ro = run.o.refinement;
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  RecognitionResult& res = run.res;
  // Depth: choose among the winner's near-best members by the fit of predicted to measured depth.
  Candidate& win = run.cands.front();
  const LoadedIndex& wli = *run.coarse[win.coarse].li;
  std::vector<std::size_t> depth_images;  // the first image with depth, or all of them (depth_all_images)
  for (std::size_t i = 0; i < n; ++i)
    if (!imgs[i].depth_m.empty() && (depth_images.empty() || ro.depth_all_images)) depth_images.push_back(i);
  auto& wfits = run.fits[win.coarse];
  const auto& wq = run.canonical(wli.index.frame);
  if (!wfits.empty() && !depth_images.empty() && ro.use_depth) {
    const double top = wfits[win.member].score;
    std::size_t best = wfits.size();
    double best_cost = std::numeric_limits<double>::infinity();
    int evaluated = 0;
    for (std::size_t k = 0; k < wfits.size(); ++k) {
      MemberFit& f = wfits[k];
      if (f.score < top - ro.depth_member_slack) continue;
      double m_cost = 0;
      if (!fitMemberByDepth(run, depth_images, wli, wq, f, &m_cost)) continue;
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
  } else if (!depth_images.empty() && ro.use_depth) {
    const auto sp = run.shape(win.h.simulation_id, win.h.hold_point);
    win.h.depth_residual_m = depthResidual(run, depth_images.front(), sp->positions, *sp, win.h.view_angle_deg);
  }
  res.refine_ms = msSince(run.t_refine);
}

void assembleResult(RecognitionRun& run) {
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  const std::vector<Candidate>& cands = run.cands;
  RecognitionResult& res = run.res;
  const HoldCandidate& w = cands.front().h;
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
  res.rotation_deg = signedWrap(run.rotationFor(w.view_angle_deg, 0));
  res.score = w.score;
  res.depth_residual_m = w.depth_residual_m;
  res.reflected = w.reflected;
  res.reflection_view_deg = w.reflection_view_deg;
  res.coarse_margin = run.coarse_margin_all;
  res.confidence = run.confidence;
  for (std::size_t k = 0; k < cands.size() && static_cast<int>(k) < run.o.match.top_k; ++k) res.top_k.push_back(cands[k].h);

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
}

namespace {

// Every image judges the answer: its own coverage by the winner, and their mean (a fused winner balances
// the images, so the first alone may be covered less while the pair is explained well). An image covered
// much worse than the best one contradicts the others: it halves the confidence and makes the match weak
// for the per-point trust (grasp_point_trust.h: not for points several images agree on).
void measureImageCoverage(RecognitionRun& run, const std::vector<vision::BitMask>& matched) {
  RecognitionResult& res = run.res;
  res.image_coverage.clear();
  double sum = 0;
  for (std::size_t i = 0; i < matched.size(); ++i) {
    res.image_coverage.push_back(silhouetteCoverage(res.query_masks[i], matched[i], run.o.refinement.max_shift_px));
    sum += res.image_coverage.back();
  }
  res.coverage = matched.empty() ? 0.0 : sum / matched.size();
  res.image_regret.clear();
  if (matched.size() >= 2) {
    const LoadedIndex& wli = *run.coarse[run.cands.front().coarse].li;
    const vision::MatchOptions mo = coarseMatchOptions(run, wli);
    for (std::size_t i = 0; i < matched.size(); ++i)
      res.image_regret.push_back(bestSingleImageScore(run, i) -
                                 vision::bestShiftIou(res.query_masks[i], matched[i], mo.max_dx, mo.max_dy).score);
  }
  res.contradicting_images = run.left_out_contradicting;
  for (bool c : contradictingImages(res.image_coverage, res.image_regret, run.o.evidence)) res.contradicting_images += c;
  for (int k = 0; k < res.contradicting_images; ++k) res.confidence *= 0.5;
  if (res.contradicting_images > run.left_out_contradicting)
    res.warnings.push_back(std::to_string(res.contradicting_images) + " of " + std::to_string(matched.size()) +
                           " images are explained worse than the best by more than evidence.contradiction_gap, or match another "
                           "shape alone better than the winner by more than evidence.contradiction_regret: "
                           "confidence halved, grasp points less trusted");
}

// Corners moved to the images' outline corners, then every point's error bound and safe flag.
void locateAndTrust(const RecognitionRun& run, const std::vector<GraspPointView>& seen, std::vector<GraspPose>* poses) {
  const RecognizerOptions& o = run.o;
  std::vector<Vec3> predicted;
  std::vector<bool> corner, observed;
  for (const GraspPose& gp : *poses) {
    predicted.push_back(gp.position);
    corner.push_back(gp.kind == "corner" || gp.on_outline_vertex);
    observed.push_back(gp.observation.observed());
  }
  const std::vector<GraspPointLocation> located = locateGraspPoints(predicted, corner, observed, seen, o.localisation);
  for (std::size_t i = 0; i < poses->size(); ++i) {
    GraspPose& gp = (*poses)[i];
    const GraspPointLocation& L = located[i];
    gp.evidence = L.evidence;
    gp.located_shift_m = L.shift_m;
    gp.located_images = L.images;
    gp.disagreeing_images = L.disagreeing_images;
    gp.disagreement_m = L.disagreement_m;
    gp.label_margin_m = L.label_margin_m;
    gp.tip_angle_deg = L.tip_angle_deg;
    gp.tip_roughness_m = L.tip_roughness_m;
    if (locatedFromData(L.evidence)) {
      gp.position = L.position;
      gp.position_camera = run.imgs[0].g.holdToCamera(gp.position);
      gp.observation = observeGraspPoint(gp.position, seen, o.observation);
    }
    gp.uncertainty_m = graspPointUncertainty(L, run.res.score, run.res.contradicting_images, o.trust);
    gp.safe = gp.uncertainty_m <= o.trust.safe_bound_m;
  }
}

}  // namespace

void addGraspPoses(RecognitionRun& run) {
  const RecognizerOptions& o = run.o;
  const std::vector<PreparedImage>& imgs = run.imgs;
  const std::size_t n = imgs.size();
  RecognitionResult& res = run.res;
  const HoldCandidate& w = run.cands.front().h;
  const LoadedIndex& wli = *run.coarse[run.cands.front().coarse].li;
  // Grasp poses and the matched silhouette.
  const auto sp = run.shape(w.simulation_id, w.hold_point);
  try {
    const VecX x = w.reflected ? reflectAcrossView(sp->positions, sp->held, w.reflection_view_deg) : sp->positions;
    const double rot0 = run.rotationFor(w.view_angle_deg, 0);
    // Image i sees the shape turned by rotationFor(view, i) about the hold axis, the common frame (the
    // first image's hold frame H) by rot0: a point p of H is cameraRotation(i) p + hold_i in camera i.
    const auto cameraRotation = [&](std::size_t i) -> Mat3 {
      return imgs[i].g.rotation_camera_hold * rotationZ(run.rotationFor(w.view_angle_deg, i) - rot0);
    };
    // Every image as the observation check and the shape fit see it (the poses are in the first image's H).
    std::vector<GraspPointView> seen;
    for (std::size_t i = 0; i < n; ++i) {
      GraspPointView v;
      v.mask = imgs[i].mask;
      v.depth = imgs[i].depth_m;
      v.intrinsics = imgs[i].g.intrinsics;
      v.rotation = cameraRotation(i);
      v.translation = imgs[i].g.hold_camera;
      seen.push_back(v);
    }
    // The images with depth.
    std::vector<DepthView> views;
    if (o.shape_fit.enabled && !imgs[0].depth_m.empty()) {
      for (const GraspPointView& v : seen) {
        if (v.depth.empty()) continue;
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
    // The winner rendered for every image, and how well it explains each.
    res.frame = wli.index.frame;
    res.query_masks = run.canonical(wli.index.frame);
    res.matched_mask = renderFor(o.refinement, x, *sp, w.view_angle_deg, imgs[0], wli.index.frame);
    std::vector<vision::BitMask> matched = {res.matched_mask};
    for (std::size_t i = 1; i < n; ++i)
      matched.push_back(renderFor(o.refinement, x, *sp, w.view_angle_deg + imgs[i].relative_view_deg, imgs[i], wli.index.frame));
    measureImageCoverage(run, matched);
    // Which points the images show (every image, depth or not), where the data place them, and how far
    // to trust them.
    for (GraspPose& gp : res.grasp_poses) gp.observation = observeGraspPoint(gp.position, seen, o.observation);
    locateAndTrust(run, seen, &res.grasp_poses);
  } catch (const RecognitionError& e) {
    // The stored shape or mesh is inconsistent (options were validated): the database is at fault.
    fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(w.simulation_id) + ": " + e.what());
  } catch (const std::invalid_argument& e) {  // vision::VisionError from the renderer
    fail(RecognitionErrorCode::kDatabase, "simulation " + std::to_string(w.simulation_id) + ": " + e.what());
  }
}

void checkResultEvidence(RecognitionRun& run) {
  RecognitionResult& res = run.res;
  res.colour_fraction = run.imgs[0].colour_fraction;
  checkEvidence(res.score, res.coverage, run.o.evidence);
  res.skipped_views = run.st.skipped.size();
  res.warnings.insert(res.warnings.begin(), run.st.result_warnings.begin(), run.st.result_warnings.end());
  res.total_ms = msSince(run.t_start);
}

}  // namespace detail
}  // namespace recognition
}  // namespace textile_handling
