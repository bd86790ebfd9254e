// Output directories and files that are checked: created with a fixed mode whatever the umask, and
// every write verified, so that a tool never reports outputs it could not write.
#pragma once

#include <functional>
#include <ostream>
#include <stdexcept>
#include <string>

namespace textile_handling {

/// A directory or file could not be created or written; the message names the path and the reason.
class OutputError : public std::runtime_error {
 public:
  explicit OutputError(const std::string& what) : std::runtime_error(what) {}
};

/// Creates `dir` and every missing parent, each with exactly `mode` (mkdir, then chmod, so the umask
/// does not apply). Components that already exist are left as they are. Throws OutputError naming the
/// path when a component cannot be created or exists but is not a directory.
void createDirectories(const std::string& dir, unsigned mode = 0755);

/// Throws OutputError unless a file can be created in the existing directory `dir` (a probe file is
/// created and removed), so that a long computation does not end in an unwritable directory.
void checkWritableDirectory(const std::string& dir);

/// Writes `path` through `write` into PATH.tmp, checks that every byte reached the file (stream state
/// after flush and close), then renames it to `path`; a reader never sees a partial file. Throws
/// OutputError naming the path on any failure (the temporary file is removed).
void writeFileAtomically(const std::string& path, const std::function<void(std::ostream&)>& write);

}  // namespace textile_handling
