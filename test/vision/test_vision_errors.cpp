// The vision core refuses bad input with typed errors (vision_errors.h) whose message names the field or
// input at fault, and which existing std::invalid_argument / std::out_of_range handlers still catch.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

#include "textile_handling/vision/bit_mask.h"
#include "textile_handling/vision/image_header.h"
#include "textile_handling/vision/mask_cv.h"
#include "textile_handling/vision/shaded_renderer.h"
#include "textile_handling/vision/silhouette_matcher.h"
#include "textile_handling/vision/silhouette_renderer.h"
#include "textile_handling/vision/vision_errors.h"

using namespace textile_handling;
using namespace textile_handling::vision;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// Runs f, which must throw Error with field() == field and a message naming it and `function`.
template <typename Error, typename F>
void expectFieldError(F f, const std::string& function, const std::string& field, const std::string& named) {
  try {
    f();
    ADD_FAILURE() << "accepted; expected an error on '" << field << "'";
  } catch (const Error& e) {
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_TRUE(contains(e.what(), function + ": ")) << e.what();
    EXPECT_TRUE(contains(e.what(), named)) << e.what();
  }
}

}  // namespace

TEST(VisionErrors, BadArgumentsNameTheirField) {
  expectFieldError<InvalidArgumentError>([] { BitMask(-1, 4); }, "BitMask", "width", "-1x4");
  expectFieldError<InvalidArgumentError>([] { bestShiftIou(BitMask(4, 4), BitMask(4, 4), 1, -2); }, "bestShiftIou",
                                         "max_dy", "max_dy");
  expectFieldError<InvalidArgumentError>([] { metresPerPixelAtDepth(PinholeIntrinsics{}, -1.0); },
                                         "metresPerPixelAtDepth", "depth", "depth");
  CanonicalFrame frame;
  frame.supersample = 0;
  expectFieldError<InvalidArgumentError>([&] { frame.validate(); }, "CanonicalFrame", "supersample", "supersample");
  ShadedRenderOptions o;
  o.noise_sigma = std::numeric_limits<double>::quiet_NaN();
  expectFieldError<InvalidArgumentError>([&] { renderShaded(VecX::Zero(9), {{0, 1, 2}}, o); }, "renderShaded",
                                         "noise_sigma", "noise_sigma");
  SilhouetteMatcher matcher;
  expectFieldError<InvalidArgumentError>([&] { matcher.add({"t", "h", std::nan(""), BitMask(8, 8)}); },
                                         "SilhouetteMatcher::add", "view_angle_deg", "view angle");
}

TEST(VisionErrors, LimitsAreTypedAndStillInvalidArguments) {
  const cv::Mat mask(64, 64, CV_8UC1, cv::Scalar(255));
  expectFieldError<LimitExceededError>([&] { canonicaliseCameraMask(mask, Vec2(2e7, 0), Vec2(0.01, 0.01), CanonicalFrame()); },
                                       "canonicaliseCameraMask", "hold_pixel", "hold pixel");
  // Handlers written for std::invalid_argument (and for VisionError) still catch every typed error.
  EXPECT_THROW(canonicaliseCameraMask(mask, Vec2(2e7, 0), Vec2(0.01, 0.01), CanonicalFrame()), std::invalid_argument);
  EXPECT_THROW(BitMask(-1, 1), VisionError);
  EXPECT_THROW(BitMask(2, 2).at(5, 0), IndexOutOfRangeError);
  EXPECT_THROW(BitMask(2, 2).at(5, 0), std::out_of_range);
}

TEST(VisionErrors, UnreadableImageFileIsAnImageDecodeError) {
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("vision_errors_" + std::to_string(::getpid()) + ".png");
  {
    std::ofstream f(path, std::ios::binary);
    f << "not an image at all";
  }
  try {
    readImageDimensions(path.string());
    ADD_FAILURE() << "accepted a file that is not an image";
  } catch (const ImageDecodeError& e) {
    EXPECT_EQ(e.path(), path.string());
    EXPECT_TRUE(contains(e.what(), path.string())) << e.what();
  }
  EXPECT_THROW(readImageDimensions(path.string()), std::invalid_argument);
  std::filesystem::remove(path);
}
