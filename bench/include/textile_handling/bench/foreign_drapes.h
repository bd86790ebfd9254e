// Recognition on drapes the database did not make (`foreign_drape_bench`, docs/recognition.md,
// "Foreign drapes"): held-out towels simulated with another cloth model, other materials, other
// resolutions, self-collision on, tilted starts, held anywhere on the textile (not at lattice points);
// rendered with colour, depth and noise; recognised with one image and with two images a known gripper
// turn apart; scored against the truth in the first camera's frame. Part of the benchmark library
// (bench/), not of the recognition core.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace bench {

/// One kind of held-out drape: a build configuration (model, material, spacing, self-collision, start)
/// whose hold points are random points of the textile.
struct ForeignDrapeVariant {
  std::string name;         ///< short, e.g. "choi_ko"; the held-out database's textile is "towel_<name>"
  std::string description;  ///< what differs from the database
  db::DrapeBuildConfig config;
};

struct ForeignDrapeSetOptions {
  int holds_per_variant = 6;
  std::uint64_t seed = 1;
  /// Share of hold points drawn on the outline (edges and corners); the rest are uniform inside.
  double edge_share = 0.3;
  double max_time_s = 30.0;  ///< simulated-time cap of a held-out simulation [s] (a drape not at rest by then is kept)
  int workers = 0;           ///< held-out simulations at once (0 = automatic)
};

/// The held-out variants, all of the thesis towel, none with the database's exact settings:
/// Choi-Ko; materials with bending x1.5 / shear x0.5 / density x0.8 and the opposite; d = 0.8 cm with
/// self-collision and a tilted start; Choi-Ko with self-collision and a tilted start; a start picked
/// from a heap (three folds) at d = 0.8 cm; and, as the reference row, the thesis experiment's kind
/// (the database's model and material at d = 0.8 cm). Hold points are
/// drawn from `options.seed` (the same seed gives the same set).
std::vector<ForeignDrapeVariant> foreignDrapeVariants(const ForeignDrapeSetOptions& options);

/// A held-out rest shape with its truth.
struct ForeignDrape {
  std::string variant;
  Vec2 hold = Vec2::Zero();    ///< the held particle's position in the textile frame [m]
  bool rest_reached = true;    ///< false: still moving at the time cap (kept as seen)
  db::StoredDrapeMesh mesh;    ///< world frame, z up
  ParticleGrid grid;           ///< the held-out simulation's particle grid
};

/// Simulates (or resumes) every variant into the database at `path` and returns the finished shapes.
/// Failed simulations are left out and counted in *failed. Progress through `log` (may be empty).
std::vector<ForeignDrape> buildForeignDrapes(const std::string& path, const std::vector<ForeignDrapeVariant>& variants,
                                             int* failed,
                                             const std::function<void(const std::string&)>& log);

struct ForeignViewOptions {
  vision::PinholeIntrinsics intrinsics{525.0, 525.0, 319.5, 239.5, 640, 480};
  double camera_distance_m = 1.6;  ///< horizontal distance from the hold axis
  double camera_drop_m = 0.35;     ///< camera below the hold point
  double noise_sigma = 3.0;        ///< grey levels
  double depth_noise_m = 0.003;    ///< Gaussian depth noise, standard deviation
  double turn_deg = 90.0;          ///< gripper turn between the two images of a pair
  bool depth = true;
};

/// Image `k` of a drape at camera azimuth `azimuth_deg` (about the hold axis, the drape's stored frame),
/// with the camera pose it was rendered from.
struct ForeignView {
  recognition::CameraObservation observation;
  vision::CameraPose camera;
};
ForeignView renderForeignView(const ForeignDrape& drape, double azimuth_deg, const ForeignViewOptions& options,
                              std::uint64_t seed);

/// Error of one recognition against the truth. Distances in metres; -1 where not available.
struct ForeignScore {
  bool success = false;
  std::string reason;            ///< the recognizer's error when not a success (set by the caller)
  double hold_error_m = -1;      ///< textile frame, nearest symmetric image of the truth
  std::vector<std::string> corner_names;
  std::vector<double> corner_error_m;  ///< per reported corner: camera frame, truth with the same labelling
  std::vector<recognition::GraspPose> corner_poses;  ///< per reported corner, as reported (observation, evidence, trust)
  /// Per reported corner, why it is off: its distance [m] to the nearest true corner of any name (small
  /// while corner_error_m is large: the right place under a wrong name) and to the nearest particle of
  /// the true drape (large: not on the cloth at all, a misplaced point).
  std::vector<double> corner_any_truth_corner_m, corner_truth_surface_m;
  double lowest_corner_error_m = -1;   ///< the corner that hangs lowest in the truth
  double best_corner_error_m = -1;
  double max_corner_error_m = -1;
  double score = 0, confidence = 0;
  int contradicting_images = 0;
  /// Best minus worst image coverage by the winner (RecognitionResult::image_coverage); 0 for one image,
  /// -1 when the answer rests on fewer images than were given (a contradicting one left out).
  double coverage_gap = 0;
  double max_image_regret = 0;  ///< largest RecognitionResult::image_regret (0 for one image)
  /// The recogniser's ranked hold-point classes (RecognitionResult::top_k, winner first): each class's
  /// member hold point (textile frame), its distance to the nearest mirror image of the true hold point
  /// [m], and its score (refined IoU when refined, else coarse).
  struct Candidate {
    Vec2 hold_point = Vec2::Zero();
    double hold_error_m = -1;
    double score = 0;
    bool refined = false;
  };
  std::vector<Candidate> candidates;
  double processing_ms = 0;
  double segmentation_ms = 0, query_ms = 0, refine_ms = 0;  ///< the recognizer's stage times (refine includes the depth fit)
};

/// Scores a successful `result` (of an observation whose first image was rendered from `camera`) against `drape`.
/// The towel is mirror-symmetric: the hold error is the distance to the nearest mirror image of the
/// truth; the corners are compared under the mirror that explains the reported hold point best
/// (among mirrors within 1 cm of the best hold error, the one with the smallest mean corner error).
ForeignScore scoreRecognition(const ForeignDrape& drape, const vision::CameraPose& camera,
                              const recognition::RecognitionResult& result);

/// Distance [m] from `drape`'s hold point to the nearest mirror image of textile point `p` (the towel's
/// symmetries).
double mirrorDistance(const ForeignDrape& drape, const Vec2& p);

}  // namespace bench
}  // namespace textile_handling
