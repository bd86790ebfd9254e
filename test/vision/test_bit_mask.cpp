// Tests for the bit-packed mask, its shifted AND/OR counts, the IoU (similarity v2) and the cv::Mat
// conversions.
#include "textile_handling/vision/bit_mask.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>

#include "textile_handling/vision/mask_cv.h"

namespace textile_handling {
namespace vision {
namespace {

BitMask randomMask(int w, int h, double density, std::mt19937& rng) {
  std::bernoulli_distribution b(density);
  BitMask m(w, h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      if (b(rng)) m.set(x, y);
  return m;
}

// Naive references on the unbounded plane.
std::set<std::pair<int, int>> pixels(const BitMask& m, int dx = 0, int dy = 0) {
  std::set<std::pair<int, int>> s;
  for (int y = 0; y < m.height(); ++y)
    for (int x = 0; x < m.width(); ++x)
      if (m.get(x, y)) s.insert({x + dx, y + dy});
  return s;
}

std::int64_t naiveAnd(const BitMask& a, const BitMask& b, int dx, int dy) {
  const auto pa = pixels(a), pb = pixels(b, dx, dy);
  std::int64_t n = 0;
  for (const auto& p : pa) n += pb.count(p);
  return n;
}

std::int64_t naiveOr(const BitMask& a, const BitMask& b, int dx, int dy) {
  auto pa = pixels(a);
  const auto pb = pixels(b, dx, dy);
  pa.insert(pb.begin(), pb.end());
  return static_cast<std::int64_t>(pa.size());
}

BitMask rect(int w, int h, int x0, int y0, int x1, int y1) {
  BitMask m(w, h);
  for (int y = y0; y < y1; ++y) m.setSpan(y, x0, x1);
  return m;
}

TEST(BitMask, ConstructionAndPixelAccess) {
  BitMask m(70, 3);
  EXPECT_EQ(m.width(), 70);
  EXPECT_EQ(m.height(), 3);
  EXPECT_EQ(m.wordsPerRow(), 2);
  EXPECT_FALSE(m.empty());
  EXPECT_EQ(m.count(), 0);
  m.set(0, 0);
  m.set(63, 1);
  m.set(64, 1);
  m.set(69, 2);
  EXPECT_TRUE(m.get(0, 0));
  EXPECT_TRUE(m.get(63, 1));
  EXPECT_TRUE(m.get(64, 1));
  EXPECT_TRUE(m.at(69, 2));
  EXPECT_FALSE(m.get(1, 0));
  EXPECT_EQ(m.count(), 4);
  m.set(63, 1, false);
  EXPECT_EQ(m.count(), 3);
  EXPECT_THROW(m.at(70, 0), std::out_of_range);
  EXPECT_THROW(m.at(-1, 0), std::out_of_range);
  EXPECT_THROW(BitMask(-1, 4), std::invalid_argument);
  EXPECT_TRUE(BitMask().empty());
  EXPECT_TRUE(BitMask(5, 0).empty());
}

TEST(BitMask, SetSpanMatchesPixelLoop) {
  std::mt19937 rng(3);
  for (int w : {1, 13, 63, 64, 65, 128, 150}) {
    std::uniform_int_distribution<int> X(-5, w + 5);
    for (int t = 0; t < 50; ++t) {
      BitMask a(w, 2), b(w, 2);
      const int x0 = X(rng), x1 = X(rng);
      a.setSpan(1, x0, x1);
      for (int x = std::max(0, x0); x < std::min(w, x1); ++x) b.set(x, 1);
      EXPECT_EQ(a, b) << "w=" << w << " span " << x0 << ".." << x1;
    }
  }
}

TEST(BitMask, StringRoundTripAndCounts) {
  const std::string s =
      "..#..\n"
      ".###.\n"
      "#####\n";
  const BitMask m = BitMask::fromString(s);
  EXPECT_EQ(m.width(), 5);
  EXPECT_EQ(m.height(), 3);
  EXPECT_EQ(m.toString(), s);
  EXPECT_EQ(m.count(), 9);
  EXPECT_EQ(m.rowCounts(), (std::vector<int>{1, 3, 5}));
  EXPECT_EQ(m.colCounts(), (std::vector<int>{1, 2, 3, 2, 1}));
  int x0, y0, x1, y1;
  ASSERT_TRUE(m.boundingBox(&x0, &y0, &x1, &y1));
  EXPECT_EQ(x0, 0);
  EXPECT_EQ(y0, 0);
  EXPECT_EQ(x1, 5);
  EXPECT_EQ(y1, 3);
  EXPECT_FALSE(BitMask(4, 4).boundingBox(&x0, &y0, &x1, &y1));
  EXPECT_THROW(BitMask::fromString("##\n#\n"), std::invalid_argument);
}

TEST(BitMask, CountsAndBoundingBoxMatchNaiveOnRandomMasks) {
  std::mt19937 rng(11);
  for (int w : {1, 7, 63, 64, 65, 130}) {
    const BitMask m = randomMask(w, 9, 0.3, rng);
    std::vector<int> rc(9, 0), cc(static_cast<std::size_t>(w), 0);
    int bx0 = w, by0 = 9, bx1 = 0, by1 = 0;
    std::int64_t n = 0;
    for (int y = 0; y < 9; ++y)
      for (int x = 0; x < w; ++x)
        if (m.get(x, y)) {
          ++n, ++rc[static_cast<std::size_t>(y)], ++cc[static_cast<std::size_t>(x)];
          bx0 = std::min(bx0, x), by0 = std::min(by0, y), bx1 = std::max(bx1, x + 1), by1 = std::max(by1, y + 1);
        }
    EXPECT_EQ(m.count(), n);
    EXPECT_EQ(m.rowCounts(), rc);
    EXPECT_EQ(m.colCounts(), cc);
    int x0, y0, x1, y1;
    if (n > 0) {
      ASSERT_TRUE(m.boundingBox(&x0, &y0, &x1, &y1));
      EXPECT_EQ(std::make_pair(x0, y0), std::make_pair(bx0, by0));
      EXPECT_EQ(std::make_pair(x1, y1), std::make_pair(bx1, by1));
    }
  }
}

TEST(BitMask, ShiftedAndOrCountsMatchNaive) {
  std::mt19937 rng(7);
  for (int w : {5, 63, 64, 65, 129}) {
    for (int trial = 0; trial < 4; ++trial) {
      const int h = 6 + trial;
      const BitMask a = randomMask(w, h, 0.4, rng), b = randomMask(w, h, 0.4, rng);
      for (int dy : {-h, -3, -1, 0, 2, h - 1, h + 2}) {
        for (int dx : {-w - 1, -65, -64, -63, -31, -1, 0, 1, 5, 63, 64, 70, w}) {
          const std::int64_t ai = andCount(a, b, dx, dy), oi = orCount(a, b, dx, dy);
          ASSERT_EQ(ai, naiveAnd(a, b, dx, dy)) << "w=" << w << " dx=" << dx << " dy=" << dy;
          ASSERT_EQ(oi, naiveOr(a, b, dx, dy)) << "w=" << w << " dx=" << dx << " dy=" << dy;
          // The shifted copy is the clipped version of the same shift.
          const BitMask bs = b.shifted(dx, dy);
          ASSERT_EQ(andCount(a, bs), ai);
          const auto pb = pixels(b, dx, dy);
          std::int64_t inside = 0;
          for (const auto& p : pb) inside += (p.first >= 0 && p.first < w && p.second >= 0 && p.second < h);
          ASSERT_EQ(bs.count(), inside);
        }
      }
    }
  }
}

TEST(BitMask, IouMatchesThesisExamples) {
  const BitMask a = rect(64, 64, 20, 2, 44, 50);
  // Identical -> 1; disjoint -> 0; against an empty image -> 0 (v2 ignores the background).
  EXPECT_DOUBLE_EQ(iou(a, a), 1.0);
  EXPECT_DOUBLE_EQ(iou(a, rect(64, 64, 0, 52, 64, 64)), 0.0);
  EXPECT_DOUBLE_EQ(iou(a, BitMask(64, 64)), 0.0);
  EXPECT_DOUBLE_EQ(iou(BitMask(64, 64), BitMask(64, 64)), 0.0);
  // A copy whose hold point is off the top centre: < 1 without shifts, 1 with the shift search.
  const BitMask b = a.shifted(-4, 2);
  EXPECT_LT(iou(a, b), 0.9);
  const ShiftedIou s = bestShiftIou(a, b, 30, 5);
  EXPECT_DOUBLE_EQ(s.score, 1.0);
  EXPECT_EQ(s.dx, 4);
  EXPECT_EQ(s.dy, -2);
  EXPECT_EQ(s.intersection, a.count());
  // Outside the search range the shift is not found.
  EXPECT_LT(bestShiftIou(a, b, 3, 5).score, 1.0);
  // Overlap of two rectangles: |A and B| / |A or B|.
  const BitMask c = rect(64, 64, 30, 2, 54, 50);
  EXPECT_DOUBLE_EQ(iou(a, c), (14.0 * 48) / (2 * 24.0 * 48 - 14.0 * 48));
  // Symmetry of the unbounded-plane definition.
  EXPECT_DOUBLE_EQ(iou(a, c, 3, -1), iou(c, a, -3, 1));
}

TEST(BitMask, ShiftingOutOfTheWindowIsNotRewarded) {
  // B touches the left edge; moving it further left loses pixels from view but they still count.
  const BitMask a = rect(32, 8, 0, 0, 4, 8), b = rect(32, 8, 0, 0, 8, 8);
  EXPECT_DOUBLE_EQ(iou(a, b, 0, 0), 0.5);
  EXPECT_DOUBLE_EQ(iou(a, b, -4, 0), 0.5);  // the clipped copy would give 1.0
}

TEST(BitMask, SizeMismatchAndBadRangesThrow) {
  EXPECT_THROW(andCount(BitMask(4, 4), BitMask(5, 4)), std::invalid_argument);
  EXPECT_THROW(iou(BitMask(4, 4), BitMask(4, 5)), std::invalid_argument);
  EXPECT_THROW(bestShiftIou(BitMask(4, 4), BitMask(4, 4), -1, 0), std::invalid_argument);
}

TEST(BitMask, MatConversionRoundTrip) {
  std::mt19937 rng(5);
  const BitMask m = randomMask(77, 13, 0.5, rng);
  const cv::Mat img = toMat(m);
  ASSERT_EQ(img.type(), CV_8UC1);
  EXPECT_EQ(img.cols, 77);
  EXPECT_EQ(img.rows, 13);
  EXPECT_EQ(cv::countNonZero(img), m.count());
  EXPECT_EQ(fromMat(img), m);
  cv::Mat grey(2, 3, CV_8UC1, cv::Scalar(0));
  grey.at<std::uint8_t>(1, 2) = 7;  // any non-zero value is foreground
  const BitMask g = fromMat(grey);
  EXPECT_TRUE(g.get(2, 1));
  EXPECT_EQ(g.count(), 1);
  EXPECT_TRUE(fromMat(cv::Mat()).empty());
  EXPECT_THROW(fromMat(cv::Mat(3, 3, CV_8UC3)), std::invalid_argument);
  EXPECT_THROW(fromMat(cv::Mat(3, 3, CV_32FC1)), std::invalid_argument);
}

}  // namespace
}  // namespace vision
}  // namespace textile_handling
