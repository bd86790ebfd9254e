// PNG files written and checked (png_output.h).
#include "png_output.h"

#include <opencv2/imgcodecs.hpp>

#include <vector>

#include "textile_handling/sim/output_files.h"

namespace textile_handling {

bool writePngFile(const std::string& path, const cv::Mat& image, const std::string& what, std::string* error) {
  std::vector<unsigned char> bytes;
  try {
    if (!cv::imencode(".png", image, bytes)) {
      if (error) *error = what + ": cannot encode " + path;
      return false;
    }
    writeFileAtomically(path, [&](std::ostream& f) {
      f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    });
  } catch (const cv::Exception& e) {
    if (error) *error = what + ": " + e.what();
    return false;
  } catch (const OutputError& e) {
    if (error) *error = what + ": " + e.what();
    return false;
  }
  return true;
}

}  // namespace textile_handling
