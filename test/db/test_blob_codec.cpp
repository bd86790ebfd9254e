// Versioned, checksummed blobs of the drape database: round trips and every kind of damage.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "textile_handling/db/blob_codec.h"
#include "textile_handling/db/database_errors.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

VecX samplePositions(int nodes) {
  VecX x(3 * nodes);
  for (int k = 0; k < x.size(); ++k) x[k] = std::sin(0.37 * k) * (k % 7 == 0 ? 1e-300 : 1.0) + (k == 5 ? -0.0 : 0.0);
  return x;
}

vision::BitMask sampleMask(int w, int h) {
  vision::BitMask m(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if ((x * 7 + y * 13) % 5 == 0 || (x == w - 1)) m.set(x, y);
  return m;
}

}  // namespace

TEST(BlobCodec, Crc32MatchesTheStandardCheckValue) {
  const std::string s = "123456789";
  EXPECT_EQ(crc32(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()), 0xCBF43926u);
}

TEST(BlobCodec, PositionsRoundTripBitExactly) {
  const VecX x = samplePositions(37);
  const auto blob = encodePositions(x);
  EXPECT_EQ(blob.size(), 16u + 8u * 111u + 4u);
  const VecX y = decodePositions(blob.data(), blob.size(), "test");
  ASSERT_EQ(y.size(), x.size());
  for (int k = 0; k < x.size(); ++k) EXPECT_EQ(std::signbit(x[k]), std::signbit(y[k]));
  EXPECT_EQ(std::memcmp(x.data(), y.data(), sizeof(double) * x.size()), 0);
}

TEST(BlobCodec, MasksRoundTripForOneAndSeveralWordsPerRow) {
  for (int w : {1, 63, 64, 65, 130}) {
    const vision::BitMask m = sampleMask(w, 17);
    const auto blob = encodeMask(m);
    EXPECT_EQ(decodeMask(blob.data(), blob.size(), "test"), m) << "width " << w;
    const MaskBlobView v = inspectMaskBlob(blob.data(), blob.size(), "test");
    EXPECT_EQ(v.width, w);
    EXPECT_EQ(v.height, 17);
  }
}

TEST(BlobCodec, RejectsBadInputWhenEncoding) {
  VecX x = samplePositions(3);
  x[4] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(encodePositions(x), InvalidInputError);
  EXPECT_THROW(encodePositions(VecX(4)), InvalidInputError);
  EXPECT_THROW(encodePositions(VecX()), InvalidInputError);
  EXPECT_THROW(encodeMask(vision::BitMask()), InvalidInputError);
}

TEST(BlobCodec, EveryTruncationIsDetected) {
  const auto pos = encodePositions(samplePositions(5));
  for (std::size_t n = 0; n < pos.size(); ++n)
    EXPECT_THROW(decodePositions(pos.data(), n, "sim 1"), BlobFormatError) << n << " bytes";
  const auto mask = encodeMask(sampleMask(64, 8));
  for (std::size_t n = 0; n < mask.size(); ++n)
    EXPECT_THROW(decodeMask(mask.data(), n, "view 1"), BlobFormatError) << n << " bytes";
  EXPECT_THROW(decodePositions(nullptr, 0, "x"), BlobFormatError);
}

TEST(BlobCodec, EveryFlippedByteIsDetected) {
  auto pos = encodePositions(samplePositions(4));
  for (std::size_t i = 0; i < pos.size(); ++i) {
    auto bad = pos;
    bad[i] ^= 0x5A;
    EXPECT_THROW(decodePositions(bad.data(), bad.size(), "sim 2"), BlobFormatError) << "byte " << i;
  }
  auto mask = encodeMask(sampleMask(70, 5));
  for (std::size_t i = 0; i < mask.size(); ++i) {
    auto bad = mask;
    bad[i] ^= 0x01;
    EXPECT_THROW(decodeMask(bad.data(), bad.size(), "view 2"), BlobFormatError) << "byte " << i;
  }
}

TEST(BlobCodec, TrailingBytesAndSwappedKindsAreRejected) {
  auto pos = encodePositions(samplePositions(2));
  auto mask = encodeMask(sampleMask(8, 8));
  auto longer = pos;
  longer.push_back(0);
  EXPECT_THROW(decodePositions(longer.data(), longer.size(), "x"), BlobFormatError);
  EXPECT_THROW(decodePositions(mask.data(), mask.size(), "x"), BlobFormatError);
  EXPECT_THROW(decodeMask(pos.data(), pos.size(), "x"), BlobFormatError);
}

TEST(BlobCodec, UnknownVersionIsReportedAsSuch) {
  auto pos = encodePositions(samplePositions(2));
  pos[4] = 2;  // version 2, CRC recomputed so only the version is wrong
  const std::uint32_t c = crc32(pos.data(), pos.size() - 4);
  for (int k = 0; k < 4; ++k) pos[pos.size() - 4 + k] = static_cast<std::uint8_t>(c >> (8 * k));
  try {
    decodePositions(pos.data(), pos.size(), "simulation 9");
    FAIL() << "no error";
  } catch (const BlobFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("unknown format version 2"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("simulation 9"), std::string::npos) << e.what();
  }
}

TEST(BlobCodec, PaddingBitsBeyondTheWidthAreRejected) {
  vision::BitMask m(10, 2);
  auto blob = encodeMask(m);
  blob[16 + 1] = 0x80;  // bit 15 of row 0: beyond width 10
  const std::uint32_t c = crc32(blob.data(), blob.size() - 4);
  for (int k = 0; k < 4; ++k) blob[blob.size() - 4 + k] = static_cast<std::uint8_t>(c >> (8 * k));
  EXPECT_THROW(decodeMask(blob.data(), blob.size(), "x"), BlobFormatError);
}
