#include "textile_handling/db/blob_codec.h"

#include <array>
#include <cmath>
#include <cstring>

#include "little_endian.h"
#include "textile_handling/db/database_errors.h"

namespace textile_handling {
namespace db {

using internal::getDouble;
using internal::getLE;
using internal::putDouble;
using internal::putLE;

namespace {

constexpr char kPositionsMagic[4] = {'T', 'H', 'P', 'S'};
constexpr char kMaskMagic[4] = {'T', 'H', 'M', 'K'};
constexpr std::size_t kPositionsHeader = 16;
constexpr std::size_t kMaskHeader = 16;
constexpr std::size_t kCrcSize = 4;

std::array<std::uint32_t, 256> makeCrcTable() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1u) ? (0xEDB88320u ^ (c >> 1)) : (c >> 1);
    t[i] = c;
  }
  return t;
}

bool hostIsLittleEndian() {
  const std::uint16_t one = 1;
  std::uint8_t b;
  std::memcpy(&b, &one, 1);
  return b == 1;
}

void checkCrc(const std::uint8_t* data, std::size_t size, const std::string& what, const char* kind) {
  const std::uint32_t stored = getLE<std::uint32_t>(data + size - kCrcSize);
  const std::uint32_t actual = crc32(data, size - kCrcSize);
  if (stored != actual)
    throw BlobFormatError(std::string(kind) + " blob of " + what + " is corrupted (CRC-32 mismatch)");
}

}  // namespace

std::uint32_t crc32(const std::uint8_t* data, std::size_t n, std::uint32_t crc) {
  static const std::array<std::uint32_t, 256> table = makeCrcTable();
  crc = ~crc;
  for (std::size_t i = 0; i < n; ++i) crc = table[(crc ^ data[i]) & 0xFFu] ^ (crc >> 8);
  return ~crc;
}

// ---- positions --------------------------------------------------------------------------------

std::vector<std::uint8_t> encodePositions(const VecX& positions) {
  if (positions.size() == 0 || positions.size() % 3 != 0)
    throw InvalidInputError("positions: size " + std::to_string(positions.size()) + " is not a positive multiple of 3");
  if (!positions.allFinite()) throw InvalidInputError("positions: non-finite value");
  const std::uint64_t nodes = static_cast<std::uint64_t>(positions.size() / 3);
  std::vector<std::uint8_t> out(kPositionsHeader + 8 * static_cast<std::size_t>(positions.size()) + kCrcSize);
  std::memcpy(out.data(), kPositionsMagic, 4);
  putLE<std::uint16_t>(out.data() + 4, kPositionsBlobVersion);
  putLE<std::uint16_t>(out.data() + 6, 3);
  putLE<std::uint64_t>(out.data() + 8, nodes);
  std::uint8_t* p = out.data() + kPositionsHeader;
  if (hostIsLittleEndian()) {
    std::memcpy(p, positions.data(), 8 * static_cast<std::size_t>(positions.size()));
  } else {
    for (Eigen::Index k = 0; k < positions.size(); ++k) putDouble(p + 8 * k, positions[k]);
  }
  putLE<std::uint32_t>(out.data() + out.size() - kCrcSize, crc32(out.data(), out.size() - kCrcSize));
  return out;
}

VecX decodePositions(const std::uint8_t* data, std::size_t size, const std::string& what) {
  if (data == nullptr || size < kPositionsHeader + kCrcSize)
    throw BlobFormatError("positions blob of " + what + " is truncated (" + std::to_string(size) + " bytes)");
  if (std::memcmp(data, kPositionsMagic, 4) != 0)
    throw BlobFormatError("positions blob of " + what + " has no THPS tag (not a positions blob)");
  const std::uint16_t version = getLE<std::uint16_t>(data + 4);
  if (version != kPositionsBlobVersion)
    throw BlobFormatError("positions blob of " + what + " has unknown format version " + std::to_string(version) +
                          " (this program reads version " + std::to_string(kPositionsBlobVersion) + ")");
  const std::uint16_t dofs = getLE<std::uint16_t>(data + 6);
  if (dofs != 3)
    throw BlobFormatError("positions blob of " + what + " has " + std::to_string(dofs) + " DOFs per node (expected 3)");
  const std::uint64_t nodes = getLE<std::uint64_t>(data + 8);
  const std::uint64_t max_nodes = (size - kPositionsHeader - kCrcSize) / 24;
  if (nodes == 0 || nodes > max_nodes || kPositionsHeader + 24 * nodes + kCrcSize != size)
    throw BlobFormatError("positions blob of " + what + " is truncated or has trailing bytes (" + std::to_string(size) +
                          " bytes for " + std::to_string(nodes) + " nodes)");
  checkCrc(data, size, what, "positions");
  VecX x(static_cast<Eigen::Index>(3 * nodes));
  const std::uint8_t* p = data + kPositionsHeader;
  if (hostIsLittleEndian()) {
    std::memcpy(x.data(), p, 24 * static_cast<std::size_t>(nodes));
  } else {
    for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = getDouble(p + 8 * k);
  }
  if (!x.allFinite()) throw BlobFormatError("positions blob of " + what + " holds non-finite values");
  return x;
}

// ---- masks ------------------------------------------------------------------------------------

std::vector<std::uint8_t> encodeMask(const vision::BitMask& mask) {
  if (mask.empty()) throw InvalidInputError("mask: empty window");
  if (static_cast<std::uint32_t>(mask.width()) > kMaxMaskSide || static_cast<std::uint32_t>(mask.height()) > kMaxMaskSide)
    throw InvalidInputError("mask: window larger than 8192 px");
  const std::size_t nwords = mask.words().size();
  std::vector<std::uint8_t> out(kMaskHeader + 8 * nwords + kCrcSize);
  std::memcpy(out.data(), kMaskMagic, 4);
  putLE<std::uint16_t>(out.data() + 4, kMaskBlobVersion);
  putLE<std::uint16_t>(out.data() + 6, 0);
  putLE<std::uint32_t>(out.data() + 8, static_cast<std::uint32_t>(mask.width()));
  putLE<std::uint32_t>(out.data() + 12, static_cast<std::uint32_t>(mask.height()));
  std::uint8_t* p = out.data() + kMaskHeader;
  if (hostIsLittleEndian()) {
    std::memcpy(p, mask.words().data(), 8 * nwords);
  } else {
    for (std::size_t k = 0; k < nwords; ++k) putLE<std::uint64_t>(p + 8 * k, mask.words()[k]);
  }
  putLE<std::uint32_t>(out.data() + out.size() - kCrcSize, crc32(out.data(), out.size() - kCrcSize));
  return out;
}

MaskBlobView inspectMaskBlob(const std::uint8_t* data, std::size_t size, const std::string& what) {
  if (data == nullptr || size < kMaskHeader + kCrcSize)
    throw BlobFormatError("mask blob of " + what + " is truncated (" + std::to_string(size) + " bytes)");
  if (std::memcmp(data, kMaskMagic, 4) != 0)
    throw BlobFormatError("mask blob of " + what + " has no THMK tag (not a mask blob)");
  const std::uint16_t version = getLE<std::uint16_t>(data + 4);
  if (version != kMaskBlobVersion)
    throw BlobFormatError("mask blob of " + what + " has unknown format version " + std::to_string(version) +
                          " (this program reads version " + std::to_string(kMaskBlobVersion) + ")");
  const std::uint32_t w = getLE<std::uint32_t>(data + 8), h = getLE<std::uint32_t>(data + 12);
  if (w == 0 || h == 0 || w > kMaxMaskSide || h > kMaxMaskSide)
    throw BlobFormatError("mask blob of " + what + " has an invalid size " + std::to_string(w) + "x" + std::to_string(h));
  const std::size_t wpr = (w + 63) / 64;
  if (kMaskHeader + 8 * wpr * h + kCrcSize != size)
    throw BlobFormatError("mask blob of " + what + " is truncated or has trailing bytes (" + std::to_string(size) +
                          " bytes for " + std::to_string(w) + "x" + std::to_string(h) + ")");
  checkCrc(data, size, what, "mask");
  MaskBlobView v;
  v.width = static_cast<int>(w);
  v.height = static_cast<int>(h);
  v.words_per_row = static_cast<int>(wpr);
  v.words = data + kMaskHeader;
  if (w % 64 != 0) {
    const std::uint64_t pad = ~std::uint64_t{0} << (w % 64);
    for (std::size_t y = 0; y < h; ++y)
      if (getLE<std::uint64_t>(v.words + 8 * (y * wpr + wpr - 1)) & pad)
        throw BlobFormatError("mask blob of " + what + " has bits set beyond its width");
  }
  return v;
}

vision::BitMask decodeMask(const std::uint8_t* data, std::size_t size, const std::string& what) {
  const MaskBlobView v = inspectMaskBlob(data, size, what);
  vision::BitMask m(v.width, v.height);
  const std::size_t nwords = static_cast<std::size_t>(v.words_per_row) * static_cast<std::size_t>(v.height);
  std::uint64_t* dst = m.row(0);
  if (hostIsLittleEndian()) {
    std::memcpy(dst, v.words, 8 * nwords);
  } else {
    for (std::size_t k = 0; k < nwords; ++k) dst[k] = getLE<std::uint64_t>(v.words + 8 * k);
  }
  return m;
}

}  // namespace db
}  // namespace textile_handling
