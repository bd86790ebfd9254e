// Checked output directories and files (output_files.h).
#include "textile_handling/sim/output_files.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>

namespace textile_handling {

namespace {

std::string reason() { return std::strerror(errno); }

// Creates one directory with exactly `mode`; true if created, false if it already was a directory.
bool makeOneDirectory(const std::string& path, unsigned mode) {
  if (::mkdir(path.c_str(), static_cast<mode_t>(mode)) == 0) {
    // mkdir applies the umask; chmod sets the documented mode.
    if (::chmod(path.c_str(), static_cast<mode_t>(mode)) != 0)
      throw OutputError("cannot set the mode of directory " + path + ": " + reason());
    return true;
  }
  const int error = errno;
  const std::string why = reason();
  struct stat st{};
  if (error == EEXIST && ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode)) return false;
  if (error == EEXIST) throw OutputError("cannot create directory " + path + ": it exists and is not a directory");
  throw OutputError("cannot create directory " + path + ": " + why);
}

}  // namespace

void createDirectories(const std::string& dir, unsigned mode) {
  if (dir.empty()) throw OutputError("cannot create a directory with an empty path");
  // Every prefix ending before a '/' is a component; the root and repeated slashes are skipped.
  for (std::size_t pos = dir.find('/', 1); ; pos = dir.find('/', pos + 1)) {
    const std::string prefix = dir.substr(0, pos);
    if (!prefix.empty() && prefix.back() != '/') makeOneDirectory(prefix, mode);
    if (pos == std::string::npos) break;
  }
}

void checkWritableDirectory(const std::string& dir) {
  struct stat st{};
  if (::stat(dir.c_str(), &st) != 0) throw OutputError("output directory " + dir + " is not accessible: " + reason());
  if (!S_ISDIR(st.st_mode)) throw OutputError("output path " + dir + " is not a directory");
  const std::string probe = dir + "/.write_probe." + std::to_string(::getpid());
  std::FILE* f = std::fopen(probe.c_str(), "wb");
  if (f == nullptr) throw OutputError("output directory " + dir + " is not writable: " + reason());
  std::fclose(f);
  std::remove(probe.c_str());
}

void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp, std::ios::out | std::ios::trunc | std::ios::binary);
    if (!f) throw OutputError("cannot create " + tmp + ": " + reason());
    write(f);
    f.flush();
    const bool written = static_cast<bool>(f);
    f.close();
    if (!written || f.fail()) {
      std::remove(tmp.c_str());
      throw OutputError("cannot write " + path + " (disk full or I/O error)");
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = reason();
    std::remove(tmp.c_str());
    throw OutputError("cannot rename " + tmp + " to " + path + ": " + why);
  }
}

}  // namespace textile_handling
