// Held-out evaluation of hold-point recognition: shapes that are NOT in the database (the same textile
// simulated at another resolution or with a perturbed material) are rendered as camera images from view
// angles between the stored ones, with pixel noise, segmented, canonicalised and matched; single-image
// and two-image (fusion) accuracy, neighbour confusion and query times are counted. Used by the tests
// and by `drape_db bench`. See docs/database.md.
#pragma once

#include <array>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "textile_handling/db/drape_export.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace db {

/// Segmentation of a camera image against a known uniform background colour ("green screen").
struct SegmentationOptions {
  std::array<std::uint8_t, 3> background_bgr{{235, 235, 235}};
  double threshold = 60.0;      ///< Euclidean BGR distance from the background that counts as textile
  int open_radius_px = 1;       ///< morphological opening against noise speckles (0 = off)
  bool largest_component = true;
};
/// CV_8UC1 mask (255 = textile) of a CV_8UC3 image. Throws std::invalid_argument for another type.
cv::Mat segmentAgainstBackground(const cv::Mat& bgr, const SegmentationOptions& options = {});

/// A held-out shape to query with.
struct HeldOutShape {
  std::string textile;
  Vec2 hold = Vec2::Zero();            ///< true hold point [m], textile frame
  std::string variant;                 ///< e.g. "material" or "resolution"
  VecX positions;
  std::vector<vision::Triangle> triangles;
  Index held_particle = -1;
};
HeldOutShape heldOutShapeFromMesh(const StoredDrapeMesh& mesh, const std::string& variant);

enum class QueryRenderMode {
  kShadedCamera,     ///< pinhole camera image with lighting and Gaussian noise, segmented, canonicalised
  kSilhouetteNoise,  ///< orthographic canonical silhouette with random flips of its boundary pixels
};

struct QueryRenderOptions {
  QueryRenderMode mode = QueryRenderMode::kShadedCamera;
  // Camera (kShadedCamera): VGA with a narrow lens, 4 m from the hold axis, 0.4 m below the hold point.
  vision::PinholeIntrinsics intrinsics{1200.0, 1200.0, 319.5, 239.5, 640, 480};
  double camera_distance = 4.0;
  double camera_height = -0.4;
  double noise_sigma = 6.0;            ///< Gaussian pixel noise [grey levels]
  double hold_pixel_sigma_px = 1.0;    ///< error of the detected hold pixel [camera px]
  SegmentationOptions segmentation;
  // kSilhouetteNoise
  double flip_probability = 0.15;      ///< probability to flip a boundary pixel
};

/// The canonical query mask of a held-out shape seen at `azimuth_deg` (deterministic for a seed).
vision::BitMask renderHeldOutQuery(const HeldOutShape& shape, double azimuth_deg, const QueryRenderOptions& options,
                                   const vision::CanonicalFrame& frame, std::uint64_t seed);

struct EvaluationOptions {
  int pairs_per_shape = 4;             ///< image pairs per held-out shape
  double stored_step_deg = 10.0;       ///< spacing of the stored views
  double min_offset_deg = 2.0;         ///< query azimuths lie between stored ones: offset in [min, step-min]
  double min_pair_angle_deg = 60.0;    ///< second image: first azimuth + U[min, max] (gripper turned)
  double max_pair_angle_deg = 120.0;
  vision::MatchOptions match;          ///< default +-30/+-5 px, top 5
  QueryRenderOptions render;
  std::uint64_t seed = 1;
};

struct MatchEvaluation {
  std::string experiment;
  int queries = 0;
  int exact = 0;                       ///< class of the true hold point ranked first
  int within_one = 0;                  ///< first class is the true one or a 4-neighbour on the lattice
  int within_one_diagonal = 0;         ///< ... or an 8-neighbour
  int top5 = 0;                        ///< true class among the top 5
  std::vector<double> query_ms;        ///< wall time per query
  /// (true class, predicted class) -> count, over all queries.
  std::map<std::pair<std::size_t, std::size_t>, int> confusion;
  double exactRate() const { return queries ? static_cast<double>(exact) / queries : 0.0; }
  double withinOneRate() const { return queries ? static_cast<double>(within_one) / queries : 0.0; }
  double withinOneDiagonalRate() const { return queries ? static_cast<double>(within_one_diagonal) / queries : 0.0; }
  double top5Rate() const { return queries ? static_cast<double>(top5) / queries : 0.0; }
  /// Fraction of the wrong answers that are 4-neighbours of the truth.
  double neighbourShareOfErrors() const {
    const int wrong = queries - exact;
    return wrong ? static_cast<double>(within_one - exact) / wrong : 0.0;
  }
  double meanQueryMs() const;
  double percentileQueryMs(double p) const;
};

/// The rendered images of one pair (a1 and a2 = a1 + turn, both between stored views).
struct HeldOutPair {
  std::size_t shape = 0;
  std::size_t truth_class = 0;  ///< class of the shape's true hold point in the index
  double a1 = 0, a2 = 0;        ///< view azimuths [deg] (a2 - a1 is the relative view angle)
  vision::BitMask m1, m2;       ///< canonical query masks
};
/// Draws and renders pairs_per_shape pairs per shape (rendering in parallel; deterministic for a seed).
/// Throws std::invalid_argument if a shape's hold point has no class in the index.
std::vector<HeldOutPair> renderHeldOutPairs(const DrapeMatchIndex& index, const std::vector<HeldOutShape>& shapes,
                                            const EvaluationOptions& options);
/// Single-image result over both images of every pair, two-image result over every pair; queries are
/// timed one by one on the calling thread. A top match outside the index's classes (a foreign entry
/// added to the matcher) counts as wrong.
std::pair<MatchEvaluation, MatchEvaluation> evaluatePairs(const DrapeMatchIndex& index,
                                                          const std::vector<HeldOutPair>& pairs,
                                                          const EvaluationOptions& options);

/// Single-image and two-image evaluation on the same rendered images: every shape gets
/// pairs_per_shape pairs (a1, a2); the single-image result counts both images of every pair, the
/// two-image result counts every pair once (fusion with relative_view_deg = a2 - a1).
/// Throws std::invalid_argument if a shape's hold point has no class in the index.
std::pair<MatchEvaluation, MatchEvaluation> evaluateHeldOut(const DrapeMatchIndex& index,
                                                            const std::vector<HeldOutShape>& shapes,
                                                            const EvaluationOptions& options);

}  // namespace db
}  // namespace textile_handling
