// Path parameters of the ROS nodes (header-only, no ROS).
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

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

/// The words of a command line given as one string: split at whitespace, no shell quoting.
inline std::vector<std::string> splitCommandWords(const std::string& text) {
  std::vector<std::string> words;
  std::istringstream in(text);
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

/// `words` with every word equal to `tool` replaced by `tool_path`. Throws std::runtime_error naming
/// `what` if such a word exists and tool_path is empty (the tool was not found).
inline std::vector<std::string> withToolPath(std::vector<std::string> words, const std::string& tool,
                                             const std::string& tool_path, const std::string& what) {
  for (std::string& w : words)
    if (w == tool) {
      if (tool_path.empty())
        throw std::runtime_error(what + ": no " + tool + " beside the node's executable; give its path");
      w = tool_path;
    }
  return words;
}

}  // namespace textile_handling
