// The vision core protects itself against hostile scales and sizes: canonicaliseCameraMask() refuses a
// scale, hold pixel or resampling size beyond its limits before allocating (mask_cv.h), and
// readImageDimensions() reads an image's size from its header without decoding it (image_header.h).
#include <gtest/gtest.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "textile_handling/vision/image_header.h"
#include "textile_handling/vision/mask_cv.h"

using namespace textile_handling;
using namespace textile_handling::vision;

namespace {

// Runs f, which must throw std::invalid_argument mentioning `needle`.
template <typename F>
void expectRefused(F f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "accepted; expected a refusal mentioning '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

cv::Mat mask64() {
  cv::Mat m(64, 64, CV_8UC1, cv::Scalar(0));
  m(cv::Rect(22, 4, 20, 40)).setTo(255);
  return m;
}

TEST(CanonicalisationLimits, HostileScalesAndHoldPixelsAreRefusedBeforeAllocating) {
  const cv::Mat m = mask64();
  const CanonicalFrame frame;  // 64 px over 1 m
  expectRefused([&] { canonicaliseCameraMask(m, Vec2(32, 4), Vec2(1e-300, 1e-300), frame); }, "metres_per_pixel");
  expectRefused([&] { canonicaliseCameraMask(m, Vec2(32, 4), Vec2(1e300, 1e300), frame); }, "metres_per_pixel");
  expectRefused([&] { canonicaliseCameraMask(m, Vec2(1e300, -1e300), Vec2(0.01, 0.01), frame); }, "hold pixel");
  expectRefused([&] { canonicaliseCameraMask(m, Vec2(2e7, 0), Vec2(0.01, 0.01), frame); }, "hold pixel");
  // Far outside but within the limits: an empty result, no overflow.
  EXPECT_EQ(canonicaliseCameraMask(m, Vec2(9e6, -9e6), Vec2(0.01, 0.01), frame).count(), 0);
  // The largest frame at the finest accepted scale would need gigabytes of weights: refused.
  CanonicalFrame big = CanonicalFrame::fromMetric(1.0, 1.0, 8192);
  const cv::Mat wide(4000, 4000, CV_8UC1, cv::Scalar(255));
  expectRefused([&] { canonicaliseCameraMask(wide, Vec2(2000, 10), Vec2(big.metres_per_pixel / 9000, big.metres_per_pixel / 9000), big); },
                "MiB");
  // An ordinary query still works.
  EXPECT_GT(canonicaliseCameraMask(m, Vec2(32, 4), Vec2(0.01, 0.01), frame).count(), 0);
}

class ImageHeaders : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = (std::filesystem::temp_directory_path() / ("th_headers_" + std::to_string(::getpid()))).string();
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string dir_;
};

TEST_F(ImageHeaders, SizesOfWrittenImagesAreReadFromTheHeader) {
  const cv::Mat img(37, 53, CV_8UC3, cv::Scalar(10, 20, 30));
  for (const char* ext : {".png", ".jpg", ".bmp", ".ppm", ".pgm"}) {
    const std::string path = dir_ + "/img" + ext;
    cv::Mat src = img;
    if (std::string(ext) == ".pgm") cv::cvtColor(img, src, cv::COLOR_BGR2GRAY);
    ASSERT_TRUE(cv::imwrite(path, src)) << ext;
    const ImageDimensions d = readImageDimensions(path);
    EXPECT_EQ(d.width, 53) << ext;
    EXPECT_EQ(d.height, 37) << ext;
  }
}

TEST_F(ImageHeaders, AHugeHeaderIsReadWithoutDecodingAndGarbageIsRefused) {
  const std::string png = dir_ + "/huge.png";
  {
    const unsigned char head[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                  0, 0, 0x4E, 0x20, 0, 0, 0x4E, 0x20, 8, 2, 0, 0, 0, 0, 0, 0, 0};
    std::ofstream(png, std::ios::binary).write(reinterpret_cast<const char*>(head), sizeof head);
  }
  const ImageDimensions d = readImageDimensions(png);
  EXPECT_EQ(d.width, 20000);
  EXPECT_EQ(d.height, 20000);
  EXPECT_EQ(d.format, "png");
  const std::string text = dir_ + "/text.png";
  std::ofstream(text) << "not an image";
  expectRefused([&] { readImageDimensions(text); }, "text.png");
  expectRefused([&] { readImageDimensions(dir_ + "/missing.png"); }, "missing.png");
  const std::string jpeg = dir_ + "/truncated.jpg";
  {
    const unsigned char head[] = {0xFF, 0xD8, 0xFF, 0xE0, 0x00, 0x10, 'J', 'F'};
    std::ofstream(jpeg, std::ios::binary).write(reinterpret_cast<const char*>(head), sizeof head);
  }
  expectRefused([&] { readImageDimensions(jpeg); }, "truncated.jpg");
}

}  // namespace
