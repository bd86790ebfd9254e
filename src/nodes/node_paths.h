// Path parameters of the ROS nodes (header-only, no ROS).
#pragma once

#include <cstdlib>
#include <string>

namespace textile_handling {

/// `path` with a leading "~/" replaced by $HOME (or "." when HOME is unset); other paths unchanged.
inline std::string expandHome(const std::string& path) {
  if (path.rfind("~/", 0) != 0) return path;
  const char* home = std::getenv("HOME");
  return std::string(home ? home : ".") + path.substr(1);
}

}  // namespace textile_handling
