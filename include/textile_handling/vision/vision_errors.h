// Typed errors of the ROS-free vision core (textile_handling_vision_core). Every argument or input the
// core refuses is a VisionError whose message names the function and the field or input at fault, e.g.
// "renderShaded: intrinsics.width/height must be in 1..16384". VisionError derives from
// std::invalid_argument, so callers that catch std::invalid_argument (the recognition core's fallback
// to the orthographic projection, the database build, the tools) keep working unchanged.
//
// The one exception outside this hierarchy is IndexOutOfRangeError: the bounds-checked accessors
// (BitMask::at, SilhouetteMatcher::entry) promise std::out_of_range, and it derives from that.
#pragma once

#include <stdexcept>
#include <string>

namespace textile_handling {
namespace vision {

/// Base of the vision core's errors: an argument or input it refuses.
class VisionError : public std::invalid_argument {
 public:
  explicit VisionError(const std::string& what) : std::invalid_argument(what) {}
};

/// One named argument or input field is invalid (NaN, out of range, wrong type, inconsistent with
/// another argument). field() is the name as the message gives it, e.g. "intrinsics.fx" or "mask".
class InvalidArgumentError : public VisionError {
 public:
  InvalidArgumentError(const std::string& function, const std::string& field, const std::string& why)
      : VisionError(function + ": " + why), field_(field) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

/// A size limit is exceeded (pixels per side, memory a resampling would allocate); field() names the
/// input that is too large.
class LimitExceededError : public VisionError {
 public:
  LimitExceededError(const std::string& function, const std::string& field, const std::string& why)
      : VisionError(function + ": " + why), field_(field) {}
  const std::string& field() const { return field_; }

 private:
  std::string field_;
};

/// An image file that cannot be read or whose header is not one of the supported formats; path() is
/// the file.
class ImageDecodeError : public VisionError {
 public:
  ImageDecodeError(const std::string& path, const std::string& why)
      : VisionError("image '" + path + "': " + why), path_(path) {}
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

/// An index outside a container (BitMask::at, SilhouetteMatcher::entry). Derives from
/// std::out_of_range, not VisionError: the accessors document std::out_of_range.
class IndexOutOfRangeError : public std::out_of_range {
 public:
  explicit IndexOutOfRangeError(const std::string& what) : std::out_of_range(what) {}
};

}  // namespace vision
}  // namespace textile_handling
