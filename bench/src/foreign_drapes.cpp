#include "textile_handling/bench/foreign_drapes.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "textile_handling/sim/material.h"
#include "textile_handling/db/textile_symmetry.h"
#include "textile_handling/recognition/grasp_poses.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace bench {

namespace {

// A random point of the textile: on the outline (a vertex or a point of an edge) with probability
// edge_share, otherwise uniform inside (rejection sampling in the bounding box).
Vec2 randomHoldPoint(const TextileOutline& t, double edge_share, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const std::vector<Vec2>& poly = t.outline;
  if (u(rng) < edge_share) {
    const std::size_t k = rng() % poly.size();
    if (u(rng) < 0.3) return poly[k];  // a corner
    return poly[k] + u(rng) * (poly[(k + 1) % poly.size()] - poly[k]);
  }
  Vec2 lo = poly.front(), hi = poly.front();
  for (const Vec2& p : poly) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  for (;;) {
    const Vec2 p(lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y()));
    if (pointInPolygon(poly, p, 0.0)) return p;
  }
}

}  // namespace

std::vector<ForeignDrapeVariant> foreignDrapeVariants(const ForeignDrapeSetOptions& o) {
  db::DrapeBuildConfig base;
  base.textile = presetTextile("towel");
  base.use_symmetry = false;        // every held-out hold point is simulated where it is
  base.bracket_hold_points = false;
  base.views.count = 1;             // the rows are only used as shapes
  base.settings.max_time = o.max_time_s;
  // A drape that still creeps at the time cap is a drape a camera could see: kept (rest_reached false,
  // reported) rather than retried with smaller steps, which bounds the set's cost.
  base.require_rest = false;
  base.retry_with_smaller_steps = false;
  base.workers = o.workers;
  base.spacing = 0.01;
  std::vector<ForeignDrapeVariant> out;
  auto add = [&](const std::string& name, const std::string& what, const std::function<void(db::DrapeBuildConfig&)>& f) {
    ForeignDrapeVariant v;
    v.name = name;
    v.description = what;
    v.config = base;
    f(v.config);
    v.config.textile.name = "towel_" + name;
    out.push_back(std::move(v));
  };
  add("choi_ko", "Choi-Ko model (buckling, hysteresis), d = 1 cm, flat start",
      [](db::DrapeBuildConfig& c) { c.model = db::DrapeBuildConfig::defaultModelSpec("choi_ko"); });
  add("stiff_light", "bending x1.5, shear x0.5, areal density x0.8, d = 1 cm, flat start", [](db::DrapeBuildConfig& c) {
    c.material = scaledMaterial(c.material, 1.5, 0.5, 0.8, "cotton_stiff_light");
  });
  add("soft_heavy", "bending x0.5, shear x1.5, areal density x1.2, d = 1 cm, start tilted 45 deg about the textile's y axis",
      [](db::DrapeBuildConfig& c) {
        c.material = scaledMaterial(c.material, 0.5, 1.5, 1.2, "cotton_soft_heavy");
        c.start_tilt_deg = 45;
        c.start_tilt_axis_deg = 90;
      });
  add("fine_collision", "d = 0.8 cm, self-collision on, start tilted -60 deg about the textile's x axis",
      [](db::DrapeBuildConfig& c) {
        c.spacing = 0.008;
        c.self_collision = true;
        c.start_tilt_deg = -60;
      });
  add("choi_ko_collision", "Choi-Ko, self-collision on, d = 1 cm, start tilted 30 deg about a diagonal",
      [](db::DrapeBuildConfig& c) {
        c.model = db::DrapeBuildConfig::defaultModelSpec("choi_ko");
        c.self_collision = true;
        c.start_tilt_deg = 30;
        c.start_tilt_axis_deg = 35;
      });
  // Last, so that the earlier variants keep the hold points they had before it existed.
  add("heap", "picked from a heap: three random folds, lifted 85 deg by the hold point; d = 0.8 cm",
      [](db::DrapeBuildConfig& c) {
        c.spacing = 0.008;
        c.start_heap = HeapStart{3, 7, 85};
      });
  // The thesis experiment's kind of held-out shape (drape_db bench): the database's own model, material
  // and start at another resolution, held anywhere; the easy case, kept as a reference row.
  add("thesis", "the database's model, material and flat start at d = 0.8 cm (the thesis experiment's held-out kind)",
      [](db::DrapeBuildConfig& c) { c.spacing = 0.008; });
  std::mt19937_64 rng(o.seed);
  for (ForeignDrapeVariant& v : out)
    for (int k = 0; k < o.holds_per_variant; ++k) v.config.hold_points.push_back(randomHoldPoint(v.config.textile, o.edge_share, rng));
  return out;
}

std::vector<ForeignDrape> buildForeignDrapes(const std::string& path, const std::vector<ForeignDrapeVariant>& variants,
                                             int* failed, const std::function<void(const std::string&)>& log) {
  db::HangingDrapeDatabase hdb(path);
  std::vector<ForeignDrape> out;
  int failures = 0;
  for (const ForeignDrapeVariant& v : variants) {
    if (log) log("held-out variant " + v.name + ": " + v.description);
    db::DrapeDatabaseBuilder builder(hdb, v.config);
    const db::DrapeBuildReport rep = builder.build();
    failures += rep.failed_now;
    for (const std::string& f : rep.failures)
      if (log) log("  failed: " + f);
    const auto textile = hdb.findTextile(v.config.textile.name);
    if (!textile) continue;
    const std::string params = db::DrapeDatabaseBuilder::parametersText(v.config);
    std::string error;
    const ParticleGrid grid = ParticleGrid::rasterize(v.config.textile, v.config.spacing, &error);
    for (const db::SimulationRecord& s : hdb.simulations(textile->id, db::SimulationStatus::kDone)) {
      if (s.parameters != params) continue;
      ForeignDrape d;
      d.variant = v.name;
      d.rest_reached = s.rest_reached;
      d.mesh = db::loadDrapeMesh(hdb, s.id);
      d.grid = grid;
      d.hold = grid.activePosition(d.mesh.held_particle);
      out.push_back(std::move(d));
    }
  }
  if (failed) *failed = failures;
  return out;
}

ForeignView renderForeignView(const ForeignDrape& drape, double azimuth_deg, const ForeignViewOptions& o,
                              std::uint64_t seed) {
  const Vec3 hold = drape.mesh.positions.segment<3>(3 * drape.mesh.held_particle);
  const Vec3 eye = hold - o.camera_distance_m * vision::viewDirection(azimuth_deg) + Vec3(0, 0, -o.camera_drop_m);
  vision::ShadedRenderOptions ro;
  ro.intrinsics = o.intrinsics;
  ro.camera = vision::CameraPose::lookAt(eye, hold + Vec3(0, 0, -o.camera_drop_m));
  ro.noise_sigma = o.noise_sigma;
  ro.seed = seed;
  ro.render_depth = o.depth;
  const vision::ShadedImage img = vision::renderShaded(drape.mesh.positions, drape.mesh.triangles, ro);
  ForeignView v;
  v.camera = ro.camera;
  v.observation.image = img.bgr;
  if (o.depth) {
    cv::Mat depth = img.depth.clone();
    if (o.depth_noise_m > 0) {
      cv::Mat noise(depth.size(), CV_32FC1);
      cv::RNG rng(seed * 7919 + 17);
      rng.fill(noise, cv::RNG::NORMAL, 0.0, o.depth_noise_m);
      depth += noise;  // NaN (no return) stays NaN
    }
    v.observation.depth = depth;
  }
  v.observation.intrinsics = ro.intrinsics;
  v.observation.hold_camera = ro.camera.toCamera(hold);
  v.observation.up_camera = ro.camera.rotation.transpose() * Vec3::UnitZ();
  return v;
}

double mirrorDistance(const ForeignDrape& drape, const Vec2& p) {
  const db::TextileSymmetry sym = db::detectSymmetry(drape.mesh.textile.outline, 1e-6);
  double best = (p - drape.hold).norm();
  for (db::MirrorKind m : sym.mirrors()) best = std::min(best, (sym.apply(m, p) - drape.hold).norm());
  return best;
}

ForeignScore scoreRecognition(const ForeignDrape& drape, const vision::CameraPose& camera,
                              const recognition::RecognitionResult& r) {
  ForeignScore s;
  s.success = true;
  s.score = r.score;
  s.confidence = r.confidence;
  s.contradicting_images = r.contradicting_images;
  for (double g : r.image_regret) s.max_image_regret = std::max(s.max_image_regret, g);
  if (r.contradicting_images > 0) s.coverage_gap = -1;  // overwritten if the answer still rests on every image
  if (r.image_coverage.size() >= 2)
    s.coverage_gap = *std::max_element(r.image_coverage.begin(), r.image_coverage.end()) -
                     *std::min_element(r.image_coverage.begin(), r.image_coverage.end());
  s.processing_ms = r.total_ms;
  s.segmentation_ms = r.segmentation_ms;
  s.query_ms = r.query_ms;
  s.refine_ms = r.refine_ms;
  const db::TextileSymmetry sym = db::detectSymmetry(drape.mesh.textile.outline, 1e-6);
  std::vector<db::MirrorKind> group = {db::MirrorKind::kIdentity};
  for (db::MirrorKind m : sym.mirrors()) group.push_back(m);
  // The truth in the first camera's frame at a textile point.
  auto truthAt = [&](const Vec2& q) {
    return camera.toCamera(recognition::sampleRestShape(drape.grid, drape.mesh.positions, q).position);
  };
  // The corner that hangs lowest in the truth (textile frame).
  Vec2 lowest = Vec2::Zero();
  double lowest_z = std::numeric_limits<double>::infinity();
  for (const auto& np : drape.mesh.textile.outline.named_points) {
    if (np.kind != "corner") continue;
    const double z = recognition::sampleRestShape(drape.grid, drape.mesh.positions, np.position).position.z();
    if (z < lowest_z) {
      lowest_z = z;
      lowest = np.position;
    }
  }
  // The truth's corners and particles in the camera frame, once (every reported corner is compared with
  // all of them under every mirror).
  std::vector<Vec3> truth_corners, truth_particles;
  for (const auto& np : drape.mesh.textile.outline.named_points)
    if (np.kind == "corner") truth_corners.push_back(truthAt(np.position));
  for (Eigen::Index i = 0; i + 2 < drape.mesh.positions.size(); i += 3)
    truth_particles.push_back(camera.toCamera(drape.mesh.positions.segment<3>(i)));
  auto nearest = [](const std::vector<Vec3>& points, const Vec3& p) {
    double best = std::numeric_limits<double>::infinity();
    for (const Vec3& q : points) best = std::min(best, (p - q).norm());
    return best;
  };
  const double best_hold = mirrorDistance(drape, r.hold_point);  // the mirrors are isometries and involutions
  s.hold_error_m = best_hold;
  for (const recognition::HoldCandidate& c : r.top_k)
    s.candidates.push_back({c.hold_point, mirrorDistance(drape, c.hold_point), c.score, c.refined});
  double best_mean = std::numeric_limits<double>::infinity();
  for (db::MirrorKind g : group) {
    if ((sym.apply(g, drape.hold) - r.hold_point).norm() > best_hold + 0.01) continue;
    ForeignScore c = s;
    c.corner_names.clear();
    c.corner_error_m.clear();
    c.corner_poses.clear();
    c.corner_any_truth_corner_m.clear();
    c.corner_truth_surface_m.clear();
    double sum = 0, best = std::numeric_limits<double>::infinity(), worst = 0, low = -1;
    for (const recognition::GraspPose& p : r.grasp_poses) {
      if (p.kind != "corner") continue;
      // The reported corner at textile point q is, under the mirror g that maps the truth's labelling to
      // the reported one, the truth's point g(q) (mirrors are involutions).
      const Vec2 truth_q = sym.apply(g, p.textile_position);
      const double e = (p.position_camera - truthAt(truth_q)).norm();
      c.corner_names.push_back(p.name);
      c.corner_error_m.push_back(e);
      c.corner_poses.push_back(p);
      c.corner_any_truth_corner_m.push_back(nearest(truth_corners, p.position_camera));
      c.corner_truth_surface_m.push_back(nearest(truth_particles, p.position_camera));
      sum += e;
      best = std::min(best, e);
      worst = std::max(worst, e);
      if ((truth_q - lowest).norm() < 1e-6) low = e;
    }
    if (c.corner_error_m.empty()) continue;
    const double mean = sum / c.corner_error_m.size();
    if (mean < best_mean) {
      best_mean = mean;
      c.best_corner_error_m = best;
      c.max_corner_error_m = worst;
      c.lowest_corner_error_m = low;
      s = c;
    }
  }
  return s;
}

}  // namespace bench
}  // namespace textile_handling
