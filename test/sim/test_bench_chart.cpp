// Benchmark charts (bench/include/textile_handling/bench/bench_chart.h): every series of a chart is told
// apart, also past the eight colours of the palette (the speed/accuracy chart draws up to 14 series).
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "../test_support.h"
#include "textile_handling/bench/bench_chart.h"

using namespace textile_handling;

namespace {

// Legend marker centres of writeLogLogChart(): right of the 680-pixel-wide plot area, 24 pixels apart, in
// the series' alphabetical order.
cv::Point legendMarker(int k) { return {90 + 680 + 25, 50 + 10 + 24 * k}; }

bool sameColour(const cv::Vec3b& a, const cv::Vec3b& b) {
  return std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) < 30;
}

}  // namespace

TEST(BenchChart, SeriesPastThePaletteGetAnotherMarkerShape) {
  const std::string dir = test_support::freshTempDir("th_bench_chart");
  std::vector<ChartPoint> pts;
  for (int k = 0; k < 9; ++k) pts.push_back({1.0 + k, 1.0 + k, "", std::string(1, static_cast<char>('a' + k))});
  std::string error;
  ASSERT_TRUE(writeLogLogChart(dir + "/chart.png", pts, "x", "y", "nine series", &error)) << error;
  const cv::Mat img = cv::imread(dir + "/chart.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  const cv::Point first = legendMarker(0), ninth = legendMarker(8);
  const cv::Vec3b white(255, 255, 255);
  // The ninth series reuses the first colour ...
  const cv::Vec3b c0 = img.at<cv::Vec3b>(first), c8 = img.at<cv::Vec3b>(ninth);
  EXPECT_FALSE(sameColour(c0, white));
  EXPECT_TRUE(sameColour(c0, c8));
  // ... as a square: its marker fills the corner that the first series' disc (radius 6) leaves white.
  const cv::Point corner(5, 5);
  EXPECT_TRUE(sameColour(img.at<cv::Vec3b>(first + corner), white));
  EXPECT_TRUE(sameColour(img.at<cv::Vec3b>(ninth + corner), c8));
  // The second series has a colour of its own.
  EXPECT_FALSE(sameColour(img.at<cv::Vec3b>(legendMarker(1)), c0));
}
