// Typed errors of the ROS-free recognition core (textile_handling_recognition_core). Every failure that
// bad input can cause is a RecognitionError with a code, so a caller (the textile_recognizer node) can
// answer with a clear, throttled message and keep running. See docs/recognition.md.
#pragma once

#include <stdexcept>
#include <string>

namespace textile_handling {
namespace recognition {

enum class RecognitionErrorCode {
  kInvalidImage,         ///< empty image, wrong size or a cv::Mat type that does not fit the encoding
  kUnsupportedEncoding,  ///< encoding other than bgr8, rgb8, mono8
  kInvalidDepth,         ///< depth image of the wrong type or size, or an unusable point cloud
  kInvalidGeometry,      ///< NaN / non-positive intrinsics, hold point behind the camera, bad up vector, view too steep
  kSegmentationFailed,   ///< no textile component at the hold point, or one that is too small
  kDatabase,             ///< the database could not be opened or read (damaged file, unknown schema, I/O)
  kEmptyDatabase,        ///< no finished simulations with views (for the selected textile)
  kUnknownTextile,       ///< a textile id or name that the database does not have
  kNoMatch,              ///< the matcher found no hold point with a positive score
  kInvalidOptions,       ///< an option out of range (negative radius, NaN threshold, ...)
  kImageTooLarge,        ///< more pixels than RecognizerOptions::max_image_pixels
  kInsufficientEvidence, ///< the best match is below the score or coverage floor (EvidenceOptions)
  kIncompleteDatabase,   ///< a selected textile lost stored views or has none yet (EvidenceOptions)
};

/// "invalid_image", "unsupported_encoding", ... (snake case of the enumerator).
const char* toString(RecognitionErrorCode code);

class RecognitionError : public std::runtime_error {
 public:
  RecognitionError(RecognitionErrorCode code, const std::string& what)
      : std::runtime_error(std::string(toString(code)) + ": " + what), code_(code) {}
  RecognitionErrorCode code() const { return code_; }

 private:
  RecognitionErrorCode code_;
};

}  // namespace recognition
}  // namespace textile_handling
