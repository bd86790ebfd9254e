// Versioned binary blobs of the drape database: final particle positions and packed silhouette masks.
// Little-endian, with a magic tag, a format version, explicit sizes and a CRC-32 trailer, so that a
// truncated, corrupted or unknown-version blob is detected and reported (BlobFormatError), never read
// as garbage. Layouts (docs/database.md):
//
//   positions v1: "THPS" | u16 version=1 | u16 dofs_per_node=3 | u64 nodes N | N*3 f64 | u32 crc32
//   mask v1:      "THMK" | u16 version=1 | u16 reserved=0 | u32 width | u32 height
//                 | height*ceil(width/64) u64 words (BitMask layout) | u32 crc32
//
// The CRC-32 (IEEE 802.3 polynomial, as zlib) covers every byte before it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/vision/bit_mask.h"

namespace textile_handling {
namespace db {

constexpr std::uint16_t kPositionsBlobVersion = 1;
constexpr std::uint16_t kMaskBlobVersion = 1;
/// Largest mask side accepted when decoding [px] (the matcher's limit).
constexpr std::uint32_t kMaxMaskSide = 8192;

/// CRC-32 (zlib convention) of `n` bytes, continuing from `crc` (0 to start).
std::uint32_t crc32(const std::uint8_t* data, std::size_t n, std::uint32_t crc = 0);

/// Encodes particle positions (3 per node). Throws InvalidInputError if the size is not a multiple of
/// 3 or a value is not finite.
std::vector<std::uint8_t> encodePositions(const VecX& positions);
/// Decodes a positions blob; `what` names the row in error messages. Throws BlobFormatError.
VecX decodePositions(const std::uint8_t* data, std::size_t size, const std::string& what);

/// Encodes a mask. Throws InvalidInputError for an empty mask or a side > kMaxMaskSide.
std::vector<std::uint8_t> encodeMask(const vision::BitMask& mask);
/// Header fields of a mask blob, checked (magic, version, sizes, CRC, zero padding bits).
struct MaskBlobView {
  int width = 0, height = 0, words_per_row = 0;
  const std::uint8_t* words = nullptr;  ///< height * words_per_row little-endian u64 words
};
/// Validates a mask blob without copying it. Throws BlobFormatError.
MaskBlobView inspectMaskBlob(const std::uint8_t* data, std::size_t size, const std::string& what);
/// Decodes a mask blob. Throws BlobFormatError.
vision::BitMask decodeMask(const std::uint8_t* data, std::size_t size, const std::string& what);

}  // namespace db
}  // namespace textile_handling
