// Strict parsing and capping of tool thread counts (thread_limit.h).
#include "textile_handling/sim/thread_limit.h"

#include <omp.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <thread>

namespace textile_handling {

int maxUsefulThreads() {
  const unsigned hardware = std::thread::hardware_concurrency();
  return std::max(1, 2 * static_cast<int>(std::min(hardware, 512u)));
}

bool parseThreadCount(const std::string& text, int* threads, std::string* error) {
  const std::string range = "an integer from 1 to " + std::to_string(kMaxRequestableThreads);
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text.c_str(), &end, 10);
  if (text.empty() || end == nullptr || *end != '\0' || errno == ERANGE) {
    *error = "--threads must be " + range + ", got '" + text.substr(0, 32) + "'";
    return false;
  }
  if (v < 1 || v > kMaxRequestableThreads) {
    *error = "--threads must be " + range + ", got " + std::to_string(v);
    return false;
  }
  *threads = static_cast<int>(v);
  return true;
}

int applyThreadLimit(int requested, std::string* note) {
  const int wanted = requested > 0 ? requested : omp_get_max_threads();
  const int cap = maxUsefulThreads();
  const int used = std::min(wanted, cap);
  omp_set_num_threads(used);
  if (note != nullptr) {
    note->clear();
    if (used < wanted)
      *note = std::to_string(wanted) + " threads requested; using " + std::to_string(used) +
              " (at most twice the " + std::to_string(cap / 2) + " hardware threads)";
  }
  return used;
}

}  // namespace textile_handling
