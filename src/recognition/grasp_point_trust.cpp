#include "textile_handling/recognition/grasp_point_trust.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

void GraspPointTrustOptions::validate() const {
  auto bad = [](const std::string& what) { throw RecognitionError(RecognitionErrorCode::kInvalidOptions, what); };
  for (const double b : {model_m, surface_m, outline_corner_m, lowest_point_m})
    if (!(b > 0) || !std::isfinite(b)) bad("trust: every per-evidence bound (model_m, surface_m, outline_corner_m, lowest_point_m) must be finite and > 0");
  if (!(shift_gain >= 0) || !std::isfinite(shift_gain)) bad("trust.shift_gain must be finite and >= 0");
  if (!(roughness_gain >= 0) || !std::isfinite(roughness_gain)) bad("trust.roughness_gain must be finite and >= 0");
  if (!(label_margin_m >= 0) || !std::isfinite(label_margin_m)) bad("trust.label_margin_m must be finite and >= 0");
  if (!(weak_score >= 0 && weak_score <= 1) || !(weak_score_agreeing >= 0 && weak_score_agreeing <= 1))
    bad("trust.weak_score and weak_score_agreeing must be in [0, 1]");
  if (!(agreeing_m >= 0) || !std::isfinite(agreeing_m)) bad("trust.agreeing_m must be finite and >= 0");
  if (!(safe_bound_m >= 0) || !std::isfinite(safe_bound_m)) bad("trust.safe_bound_m must be finite and >= 0");
}

double graspPointUncertainty(const GraspPointLocation& L, double score, int contradicting_images,
                             const GraspPointTrustOptions& o) {
  double u = o.model_m;
  switch (L.evidence) {
    case GraspPointEvidence::kModel: u = o.model_m; break;
    case GraspPointEvidence::kSurface: u = o.surface_m; break;
    case GraspPointEvidence::kOutlineCorner: u = o.outline_corner_m; break;
    case GraspPointEvidence::kLowestPoint: u = o.lowest_point_m; break;
  }
  const bool agreeing = locatedFromData(L.evidence) && L.images >= 2;
  if (locatedFromData(L.evidence)) {
    const double shift = std::max(0.0, L.shift_m);
    if (agreeing) u = std::max(0.0, u - o.agreeing_m);
    u += o.shift_gain * shift;
    if (!(L.label_margin_m >= o.label_margin_m)) u += shift + std::max(0.0, L.label_margin_m);
    u += std::max(0.0, L.disagreement_m);
    if (std::isfinite(L.tip_roughness_m)) u += o.roughness_gain * std::max(0.0, L.tip_roughness_m);
  }
  if (contradicting_images > 0 && !agreeing) score = 0;
  if (!(score >= (agreeing ? o.weak_score_agreeing : o.weak_score))) u *= 2;
  return u;
}

}  // namespace recognition
}  // namespace textile_handling
