#include "textile_handling/recognition/grasp_point_trust.h"

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
  if (!(label_margin_m >= 0) || !std::isfinite(label_margin_m)) bad("trust.label_margin_m must be finite and >= 0");
  if (!(weak_score >= 0 && weak_score <= 1)) bad("trust.weak_score must be in [0, 1]");
  if (!(safe_bound_m >= 0) || !std::isfinite(safe_bound_m)) bad("trust.safe_bound_m must be finite and >= 0");
}

double graspPointUncertainty(GraspPointEvidence evidence, double located_shift_m, double label_margin_m, double score,
                             const GraspPointTrustOptions& o) {
  double u = o.model_m;
  switch (evidence) {
    case GraspPointEvidence::kModel: u = o.model_m; break;
    case GraspPointEvidence::kSurface: u = o.surface_m; break;
    case GraspPointEvidence::kOutlineCorner: u = o.outline_corner_m; break;
    case GraspPointEvidence::kLowestPoint: u = o.lowest_point_m; break;
  }
  if (locatedFromData(evidence)) {
    const double shift = std::max(0.0, located_shift_m);
    u += o.shift_gain * shift;
    if (!(label_margin_m >= o.label_margin_m)) u += shift + std::max(0.0, label_margin_m);
  }
  if (!(score >= o.weak_score)) u *= 2;
  return u;
}

}  // namespace recognition
}  // namespace textile_handling
