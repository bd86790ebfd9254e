// The shared end of a command-line tool's main(): nothing escapes it. An allocation failure and any
// other unexpected error are reported on stderr with the tool's name and mapped to exit status 5.
#pragma once

#include <exception>
#include <iostream>
#include <new>
#include <string>

namespace textile_handling {

/// Exit status of an allocation failure or an unexpected error (README, the tools' exit codes).
constexpr int kToolExitInternal = 5;

/// Returns run(), or kToolExitInternal after printing "<tool>: out of memory (<memory_hint>)" or
/// "<tool>: unexpected error: <what>".
template <typename Run>
int runGuarded(const std::string& tool, const std::string& memory_hint, Run&& run) {
  try {
    return run();
  } catch (const std::bad_alloc&) {
    std::cerr << tool << ": out of memory (" << memory_hint << ")\n";
  } catch (const std::exception& e) {
    std::cerr << tool << ": unexpected error: " << e.what() << "\n";
  }
  return kToolExitInternal;
}

}  // namespace textile_handling
