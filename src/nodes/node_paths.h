// Path parameters of the ROS nodes (header-only, no ROS).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <string>

namespace textile_handling {

/// `path` with a leading "~/" replaced by $HOME (or "." when HOME is unset); other paths unchanged.
inline std::string expandHome(const std::string& path) {
  if (path.rfind("~/", 0) != 0) return path;
  const char* home = std::getenv("HOME");
  return std::string(home ? home : ".") + path.substr(1);
}

/// The path of this package's executable `name` beside the running executable (catkin puts a package's
/// nodes and tools in one directory), or "" if there is none.
inline std::string packageToolPath(const std::string& name) {
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) return "";
  const std::filesystem::path tool = self.parent_path() / name;
  return ::access(tool.c_str(), X_OK) == 0 ? tool.string() : "";
}

}  // namespace textile_handling
