// Internal to the database core: SQL fragments and text forms shared by its source files.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace db {
namespace internal {

/// The current UTC time as SQLite writes it into the *_at columns (ISO 8601 with milliseconds).
constexpr const char* kNow = "strftime('%Y-%m-%dT%H:%M:%fZ','now')";

/// A hold point in whole micrometres: "same hold point" is exact in the UNIQUE constraint.
inline std::string holdKey(const Vec2& p) {
  return std::to_string(std::llround(p.x() * 1e6)) + "," + std::to_string(std::llround(p.y() * 1e6));
}

/// Round-trip text of a double.
inline std::string fmt17(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
