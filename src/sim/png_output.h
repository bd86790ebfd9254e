// Writing pictures as PNG through writeFileAtomically (output_files.h): the encoded bytes are written
// and checked like every other output, and a failed write leaves no partial file.
#pragma once

#include <opencv2/core.hpp>

#include <string>

namespace textile_handling {

/// Encodes `image` as PNG and writes it to `path`. Returns false with "<what>: <reason>" in `*error`
/// (if non-null) when encoding or writing fails.
bool writePngFile(const std::string& path, const cv::Mat& image, const std::string& what, std::string* error);

}  // namespace textile_handling
