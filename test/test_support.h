// Helpers shared by the gtest suites (header-only, no ROS): an OpenMP thread-count scope and a
// temporary SQLite path that cleans up after itself.
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

}  // namespace test_support
}  // namespace textile_handling
