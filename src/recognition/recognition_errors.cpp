#include "textile_handling/recognition/recognition_errors.h"

namespace textile_handling {
namespace recognition {

const char* toString(RecognitionErrorCode code) {
  switch (code) {
    case RecognitionErrorCode::kInvalidImage: return "invalid_image";
    case RecognitionErrorCode::kUnsupportedEncoding: return "unsupported_encoding";
    case RecognitionErrorCode::kInvalidDepth: return "invalid_depth";
    case RecognitionErrorCode::kInvalidGeometry: return "invalid_geometry";
    case RecognitionErrorCode::kSegmentationFailed: return "segmentation_failed";
    case RecognitionErrorCode::kDatabase: return "database";
    case RecognitionErrorCode::kEmptyDatabase: return "empty_database";
    case RecognitionErrorCode::kUnknownTextile: return "unknown_textile";
    case RecognitionErrorCode::kNoMatch: return "no_match";
    case RecognitionErrorCode::kInvalidOptions: return "invalid_options";
    case RecognitionErrorCode::kImageTooLarge: return "image_too_large";
    case RecognitionErrorCode::kInsufficientEvidence: return "insufficient_evidence";
    case RecognitionErrorCode::kIncompleteDatabase: return "incomplete_database";
  }
  return "unknown";
}

}  // namespace recognition
}  // namespace textile_handling
