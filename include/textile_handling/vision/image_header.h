// Image dimensions read from a file's header without decoding it, so that a tool can refuse an image
// that is too large before OpenCV allocates it (OpenCV 4.6 has no public header-only read, and its
// OPENCV_IO_MAX_IMAGE_PIXELS limit is fixed when the library loads). See docs/vision.md.
#pragma once

#include <cstdint>
#include <string>

namespace textile_handling {
namespace vision {

struct ImageDimensions {
  std::int64_t width = 0, height = 0;
  std::string format;  ///< "png", "jpeg", "bmp", "pnm"
};

/// Reads the width and height from the header of a PNG, JPEG (baseline or progressive), BMP or
/// PNM (P1-P6) file. Throws std::invalid_argument naming the file for an unreadable file, another
/// format, or a truncated / inconsistent header.
ImageDimensions readImageDimensions(const std::string& path);

}  // namespace vision
}  // namespace textile_handling
