// Helpers shared by the gtest suites (header-only, no ROS): an OpenMP thread-count scope and
// temporary paths (files, SQLite databases, directories).
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace textile_handling {
namespace test_support {

/// Sets the OpenMP thread count for a scope. Checks run single-threaded except where the thread count
/// is the point: parallel regions are slow on a loaded machine, and results do not depend on it.
class ThreadScope {
 public:
  explicit ThreadScope(int n) {
#ifdef _OPENMP
    saved_ = omp_get_max_threads();
    omp_set_num_threads(n);
#else
    (void)n;
#endif
  }
  ~ThreadScope() {
#ifdef _OPENMP
    omp_set_num_threads(saved_);
#endif
  }
  ThreadScope(const ThreadScope&) = delete;
  ThreadScope& operator=(const ThreadScope&) = delete;

 private:
  int saved_ = 1;
};

/// A database path in the temporary directory, unique per process and `name`; the file and its WAL
/// and shared-memory files are removed before use and at the end of the scope.
class TempDatabase {
 public:
  explicit TempDatabase(const std::string& name) {
    path_ = (std::filesystem::temp_directory_path() /
             ("th_test_" + std::to_string(::getpid()) + "_" + name + ".sqlite"))
                .string();
    remove();
  }
  ~TempDatabase() { remove(); }
  TempDatabase(const TempDatabase&) = delete;
  TempDatabase& operator=(const TempDatabase&) = delete;
  const std::string& path() const { return path_; }

 private:
  void remove() {
    std::error_code ec;  // a missing file is fine
    for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(path_ + s, ec);
  }
  std::string path_;
};

/// A path <temp>/<prefix><pid>_<name>, unique per process; a leftover file there and its WAL and
/// shared-memory files are removed first.
inline std::string freshTempPath(const std::string& prefix, const std::string& name) {
  const auto p = std::filesystem::temp_directory_path() / (prefix + std::to_string(::getpid()) + "_" + name);
  for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(p.string() + s);
  return p.string();
}

/// A new empty directory <temp>/<prefix>_<pid> (removed first if it exists).
inline std::string freshTempDir(const std::string& prefix) {
  const std::string dir = (std::filesystem::temp_directory_path() / (prefix + "_" + std::to_string(::getpid()))).string();
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace test_support
}  // namespace textile_handling
