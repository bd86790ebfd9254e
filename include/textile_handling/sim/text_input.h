// Reading configuration text (scene and material YAML) with a size limit, so that a huge or endless
// file (e.g. /dev/zero) is refused before it is read into memory or parsed.
#pragma once

#include <cstddef>
#include <string>

namespace textile_handling {

/// Largest scene or material YAML document [bytes] (1 MiB): hundreds of times the largest real file,
/// and small enough that parsing it stays fast and its node tree small (docs/simulation.md).
constexpr std::size_t kMaxYamlDocumentBytes = std::size_t{1} << 20;

/// Reads the regular file `path` into `*text` if it has at most `max_bytes` bytes. Returns false with a
/// reason in `*error` (not found, not a regular file, too large, read error); never reads more than
/// max_bytes + 1 bytes.
bool readBoundedTextFile(const std::string& path, std::size_t max_bytes, std::string* text, std::string* error);

/// An error message if `text` exceeds max_bytes, else empty: "<what> has N bytes, more than the limit of M".
std::string textSizeError(const std::string& what, std::size_t size, std::size_t max_bytes);

}  // namespace textile_handling
