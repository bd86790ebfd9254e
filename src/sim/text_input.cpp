// Size-limited reading of configuration files (text_input.h).
#include "textile_handling/sim/text_input.h"

#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <algorithm>
#include <cstring>
#include <utility>

namespace textile_handling {

std::string textSizeError(const std::string& what, std::size_t size, std::size_t max_bytes) {
  if (size <= max_bytes) return "";
  return what + " has " + std::to_string(size) + " bytes, more than the limit of " + std::to_string(max_bytes);
}

bool readBoundedTextFile(const std::string& path, std::size_t max_bytes, std::string* text, std::string* error) {
  struct stat st{};
  if (::stat(path.c_str(), &st) != 0) {
    *error = "cannot open " + path + ": " + std::strerror(errno);
    return false;
  }
  // Devices and pipes may never end (/dev/zero) or block (a FIFO); only regular files are read.
  if (!S_ISREG(st.st_mode)) {
    *error = path + " is not a regular file";
    return false;
  }
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    *error = "cannot open " + path + ": " + std::strerror(errno);
    return false;
  }
  std::string out;
  char buf[65536];
  std::size_t k = 0;
  // The file may grow after stat(): the read itself stops one byte past the limit.
  while (out.size() <= max_bytes && (k = std::fread(buf, 1, sizeof buf, f)) > 0) out.append(buf, k);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) {
    *error = "error while reading " + path;
    return false;
  }
  if (out.size() > max_bytes) {
    *error = textSizeError(path, static_cast<std::size_t>(std::max<long long>(st.st_size, out.size())), max_bytes);
    return false;
  }
  *text = std::move(out);
  return true;
}

}  // namespace textile_handling
