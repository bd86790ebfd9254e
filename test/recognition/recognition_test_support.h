// Helpers shared by the recognition gtest suites: the VGA camera the tests use and a check that a call
// fails with a given RecognitionErrorCode.
#pragma once

#include <functional>
#include <string>

#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace test_support {

/// 640 x 480, f = 525 px, principal point at the centre (the cell camera of the tests).
inline vision::PinholeIntrinsics vga() { return vision::PinholeIntrinsics{525.0, 525.0, 319.5, 239.5, 640, 480}; }

/// True if `f` throws a RecognitionError with `code` (its message in *msg); false if it throws
/// anything else or nothing.
inline bool throwsCode(const std::function<void()>& f, recognition::RecognitionErrorCode code,
                       std::string* msg = nullptr) {
  try {
    f();
  } catch (const recognition::RecognitionError& e) {
    if (msg) *msg = e.what();
    return e.code() == code;
  } catch (...) {
    return false;
  }
  return false;
}

}  // namespace test_support
}  // namespace textile_handling
