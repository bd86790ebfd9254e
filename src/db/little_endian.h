// Internal to the database core: little-endian integers and doubles in byte buffers, for the blob and
// message codecs (blob_codec.cpp, simulation_outcome_codec.cpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace textile_handling {
namespace db {
namespace internal {

template <typename T>
void putLE(std::uint8_t* p, T v) {
  for (std::size_t k = 0; k < sizeof(T); ++k) p[k] = static_cast<std::uint8_t>((static_cast<std::uint64_t>(v) >> (8 * k)) & 0xFFu);
}

template <typename T>
T getLE(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (std::size_t k = 0; k < sizeof(T); ++k) v |= static_cast<std::uint64_t>(p[k]) << (8 * k);
  return static_cast<T>(v);
}

inline void putDouble(std::uint8_t* p, double d) {
  std::uint64_t u;
  std::memcpy(&u, &d, 8);
  putLE<std::uint64_t>(p, u);
}

inline double getDouble(const std::uint8_t* p) {
  const std::uint64_t u = getLE<std::uint64_t>(p);
  double d;
  std::memcpy(&d, &u, 8);
  return d;
}

}  // namespace internal
}  // namespace db
}  // namespace textile_handling
