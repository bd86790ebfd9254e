#include "textile_handling/vision/mask_cv.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "textile_handling/vision/vision_errors.h"
namespace textile_handling {
namespace vision {

cv::Mat toMat(const BitMask& mask) {
  cv::Mat m(mask.height(), mask.width(), CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < mask.height(); ++y) {
    std::uint8_t* r = m.ptr<std::uint8_t>(y);
    for (int x = 0; x < mask.width(); ++x) r[x] = mask.get(x, y) ? 255 : 0;
  }
  return m;
}

BitMask fromMat(const cv::Mat& image) {
  if (image.empty()) return BitMask();
  if (image.type() != CV_8UC1)
    throw InvalidArgumentError("fromMat", "image", "image must be a CV_8UC1 mask, got type " + std::to_string(image.type()));
  BitMask m(image.cols, image.rows);
  for (int y = 0; y < image.rows; ++y) {
    const std::uint8_t* r = image.ptr<std::uint8_t>(y);
    std::uint64_t* dst = m.row(y);
    for (int x = 0; x < image.cols; ++x)
      if (r[x]) dst[x >> 6] |= std::uint64_t{1} << (x & 63);
  }
  return m;
}

Vec2 metresPerPixelAtDepth(const PinholeIntrinsics& k, double depth) {
  if (!(depth > 0) || !std::isfinite(depth))
    throw InvalidArgumentError("metresPerPixelAtDepth", "depth", "depth must be finite and > 0");
  if (!(k.fx > 0) || !(k.fy > 0) || !std::isfinite(k.fx) || !std::isfinite(k.fy))
    throw InvalidArgumentError("metresPerPixelAtDepth", "intrinsics.fx/fy", "focal lengths intrinsics.fx, fy must be finite and > 0");
  return Vec2(depth / k.fx, depth / k.fy);
}

namespace {

// Sparse weights of the overlap of canonical pixel i (along one axis) with source pixels: canonical
// pixel i covers source interval [a0 + i*step, a0 + (i+1)*step) in continuous source coordinates
// (source pixel j covers [j, j+1)); weights are overlap lengths / step.
struct AxisWeights {
  std::vector<int> begin;        // first source index per canonical pixel
  std::vector<std::vector<float>> w;
};

// The interval is clamped to the source in double before any conversion to int (no overflow for far
// away intervals), so a canonical pixel never holds more than n_src weights.
AxisWeights axisWeights(int n_out, int n_src, double a0, double step) {
  AxisWeights aw;
  aw.begin.resize(static_cast<std::size_t>(n_out));
  aw.w.resize(static_cast<std::size_t>(n_out));
  const double src_end = static_cast<double>(n_src);
  for (int i = 0; i < n_out; ++i) {
    const double lo = a0 + i * step, hi = lo + step;
    const int j0 = static_cast<int>(std::floor(std::clamp(lo, 0.0, src_end)));
    const int j1 = static_cast<int>(std::ceil(std::clamp(hi, 0.0, src_end))) - 1;
    aw.begin[static_cast<std::size_t>(i)] = j0;
    auto& w = aw.w[static_cast<std::size_t>(i)];
    for (int j = j0; j <= j1; ++j) {
      const double ov = std::min(hi, j + 1.0) - std::max(lo, static_cast<double>(j));
      w.push_back(static_cast<float>(std::max(0.0, ov) / step));
    }
  }
  return aw;
}

// Source pixels one canonical pixel overlaps along an axis (at most the whole source).
double weightsPerPixel(double step, int n_src) { return std::min(static_cast<double>(n_src), std::ceil(step) + 1.0); }

// Bytes canonicalCoverage() allocates for the axis weights, the horizontal pass and the result
// (upper bound, in double so that it cannot overflow).
double coverageBytes(const cv::Mat& mask, double sx, double sy, const CanonicalFrame& frame) {
  const double wx = frame.width_px * weightsPerPixel(sx, mask.cols), wy = frame.height_px * weightsPerPixel(sy, mask.rows);
  const double rows = std::min(static_cast<double>(mask.rows), frame.height_px * (std::ceil(sy) + 1.0));
  return sizeof(float) * (wx + wy + rows * frame.width_px + static_cast<double>(frame.width_px) * frame.height_px) +
         sizeof(std::vector<float>) * (frame.width_px + frame.height_px);
}

}  // namespace

cv::Mat canonicalCoverage(const cv::Mat& mask, const Vec2& hold_pixel, const Vec2& mpp, const CanonicalFrame& frame) {
  frame.validate();
  if (mask.empty()) throw InvalidArgumentError("canonicaliseCameraMask", "mask", "the camera mask is empty");
  if (mask.type() != CV_8UC1)
    throw InvalidArgumentError("canonicaliseCameraMask", "mask",
                               "the camera mask must be CV_8UC1, got type " + std::to_string(mask.type()));
  if (!hold_pixel.allFinite()) throw InvalidArgumentError("canonicaliseCameraMask", "hold_pixel", "hold pixel is not finite");
  if (!(mpp.x() > 0) || !(mpp.y() > 0) || !mpp.allFinite())
    throw InvalidArgumentError("canonicaliseCameraMask", "metres_per_pixel", "metres_per_pixel must be finite and > 0");

  if (!(std::abs(hold_pixel.x()) <= kMaxHoldPixelOffset && std::abs(hold_pixel.y()) <= kMaxHoldPixelOffset))
    throw LimitExceededError("canonicaliseCameraMask", "hold_pixel",
                             "hold pixel (" + std::to_string(hold_pixel.x()) + ", " + std::to_string(hold_pixel.y()) +
                                 ") is more than " + std::to_string(static_cast<long>(kMaxHoldPixelOffset)) +
                                 " px from the image");

  // Canonical continuous X maps to camera continuous x = hold_u + 0.5 + (X - W/2) * (mpp_c / mpp_x).
  const double sx = frame.metres_per_pixel / mpp.x(), sy = frame.metres_per_pixel / mpp.y();
  if (!(sx >= 1.0 / kMaxScaleRatio && sx <= kMaxScaleRatio && sy >= 1.0 / kMaxScaleRatio && sy <= kMaxScaleRatio))
    throw LimitExceededError("canonicaliseCameraMask", "metres_per_pixel",
                             "metres_per_pixel (" + std::to_string(mpp.x()) + ", " + std::to_string(mpp.y()) +
                                 ") is out of range: one canonical pixel (" + std::to_string(frame.metres_per_pixel) +
                                 " m) would span " + std::to_string(sx) + " camera pixels; allowed 1/" +
                                 std::to_string(static_cast<long>(kMaxScaleRatio)) + ".." +
                                 std::to_string(static_cast<long>(kMaxScaleRatio)));
  const double bytes = coverageBytes(mask, sx, sy, frame);
  if (bytes > static_cast<double>(kMaxCoverageBytes))
    throw LimitExceededError("canonicaliseCameraMask", "frame",
                             "the resampling would allocate " + std::to_string(static_cast<long long>(bytes / (1 << 20))) +
                                 " MiB (limit " + std::to_string(kMaxCoverageBytes >> 20) +
                                 " MiB); is the canonical frame too large?");
  const double ax = hold_pixel.x() + 0.5 - 0.5 * frame.width_px * sx;
  const double ay = hold_pixel.y() + 0.5 - frame.top_margin_px * sy;
  const AxisWeights wx = axisWeights(frame.width_px, mask.cols, ax, sx);
  const AxisWeights wy = axisWeights(frame.height_px, mask.rows, ay, sy);

  // Horizontal pass for the camera rows that any canonical row touches.
  int r_lo = mask.rows, r_hi = -1;
  for (int j = 0; j < frame.height_px; ++j) {
    const auto& w = wy.w[static_cast<std::size_t>(j)];
    if (w.empty()) continue;
    r_lo = std::min(r_lo, wy.begin[static_cast<std::size_t>(j)]);
    r_hi = std::max(r_hi, wy.begin[static_cast<std::size_t>(j)] + static_cast<int>(w.size()) - 1);
  }
  cv::Mat cov(frame.height_px, frame.width_px, CV_32FC1, cv::Scalar(0));
  if (r_hi < r_lo) return cov;
  std::vector<float> tmp(static_cast<std::size_t>(r_hi - r_lo + 1) * static_cast<std::size_t>(frame.width_px), 0.f);
  for (int r = r_lo; r <= r_hi; ++r) {
    const std::uint8_t* src = mask.ptr<std::uint8_t>(r);
    float* t = tmp.data() + static_cast<std::size_t>(r - r_lo) * static_cast<std::size_t>(frame.width_px);
    for (int i = 0; i < frame.width_px; ++i) {
      const auto& w = wx.w[static_cast<std::size_t>(i)];
      const int b = wx.begin[static_cast<std::size_t>(i)];
      float s = 0.f;
      for (std::size_t k = 0; k < w.size(); ++k) s += src[b + static_cast<int>(k)] ? w[k] : 0.f;
      t[i] = s;
    }
  }
  for (int j = 0; j < frame.height_px; ++j) {
    const auto& w = wy.w[static_cast<std::size_t>(j)];
    const int b = wy.begin[static_cast<std::size_t>(j)];
    float* out = cov.ptr<float>(j);
    for (std::size_t k = 0; k < w.size(); ++k) {
      const float* t = tmp.data() + static_cast<std::size_t>(b + static_cast<int>(k) - r_lo) *
                                        static_cast<std::size_t>(frame.width_px);
      for (int i = 0; i < frame.width_px; ++i) out[i] += w[k] * t[i];
    }
  }
  return cov;
}

BitMask canonicaliseCameraMask(const cv::Mat& mask, const Vec2& hold_pixel, const Vec2& mpp,
                               const CanonicalFrame& frame) {
  const cv::Mat cov = canonicalCoverage(mask, hold_pixel, mpp, frame);
  BitMask m(frame.width_px, frame.height_px);
  const float t = static_cast<float>(frame.coverage_threshold) - 1e-5f;
  for (int y = 0; y < cov.rows; ++y) {
    const float* r = cov.ptr<float>(y);
    for (int x = 0; x < cov.cols; ++x)
      if (r[x] >= t) m.set(x, y);
  }
  return m;
}

}  // namespace vision
}  // namespace textile_handling
