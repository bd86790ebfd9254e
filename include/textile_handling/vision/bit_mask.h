// Binary W x H masks with rows bit-packed into 64-bit words, and the silhouette similarity of the
// thesis (similarity v2 = intersection over union) with pixel shifts.
//
// ROS-free and OpenCV-free (conversions to/from cv::Mat live in mask_cv.h). See docs/vision.md.
//
// Layout: row y occupies wordsPerRow() = ceil(W / 64) consecutive words; pixel x of that row is bit
// (x % 64) of word (x / 64), least significant bit first. Bits beyond the width are always zero.
//
// Shift convention: shift(B, dx, dy) moves the content of B by dx pixels to the right (+x) and dy
// pixels down (+y): shift(B, dx, dy)(x, y) = B(x - dx, y - dy). Similarities treat a silhouette as a set
// of pixels on the unbounded integer plane; the W x H window is only its storage. So pixels that a
// shift moves out of the window still count in |B| and in the union:
//   |A and shift(B)| = pixels of A also in the shifted B (necessarily inside the window),
//   |A or  shift(B)| = |A| + |B| - |A and shift(B)|,
//   IoU(A, B, dx, dy) = |A and shift(B)| / |A or shift(B)|   (0 when both are empty).
// This makes IoU(A, B, dx, dy) == IoU(B, A, -dx, -dy) and never rewards moving content out of view.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace vision {

class BitMask {
 public:
  /// An empty 0 x 0 mask.
  BitMask() = default;
  /// An all-zero mask; throws std::invalid_argument for negative sizes.
  BitMask(int width, int height);

  int width() const { return width_; }
  int height() const { return height_; }
  int wordsPerRow() const { return words_per_row_; }
  /// True if the window has no pixels (0 x 0, W x 0 or 0 x H). An all-zero W x H mask is not empty().
  bool empty() const { return width_ == 0 || height_ == 0; }
  bool sameSize(const BitMask& o) const { return width_ == o.width_ && height_ == o.height_; }

  /// Pixel access; (x, y) must be inside the window (checked only by at(), which throws).
  bool get(int x, int y) const {
    return (words_[static_cast<std::size_t>(y) * words_per_row_ + (x >> 6)] >> (x & 63)) & 1u;
  }
  void set(int x, int y, bool value = true) {
    std::uint64_t& w = words_[static_cast<std::size_t>(y) * words_per_row_ + (x >> 6)];
    const std::uint64_t bit = std::uint64_t{1} << (x & 63);
    w = value ? (w | bit) : (w & ~bit);
  }
  bool at(int x, int y) const;  ///< bounds-checked get(); throws IndexOutOfRangeError (a std::out_of_range)
  /// Sets pixels [x0, x1) of row y (clipped to the window).
  void setSpan(int y, int x0, int x1);
  void clear();

  const std::uint64_t* row(int y) const { return words_.data() + static_cast<std::size_t>(y) * words_per_row_; }
  std::uint64_t* row(int y) { return words_.data() + static_cast<std::size_t>(y) * words_per_row_; }
  const std::vector<std::uint64_t>& words() const { return words_; }

  /// Number of set pixels |A|.
  std::int64_t count() const;
  /// Set pixels per row (size H) and per column (size W).
  std::vector<int> rowCounts() const;
  std::vector<int> colCounts() const;
  /// Tight bounding box [x0, x1) x [y0, y1) of the set pixels; false (and untouched outputs) if none.
  bool boundingBox(int* x0, int* y0, int* x1, int* y1) const;

  /// A copy with the content moved by (dx, dy); pixels leaving the window are dropped.
  BitMask shifted(int dx, int dy) const;

  bool operator==(const BitMask& o) const {
    return width_ == o.width_ && height_ == o.height_ && words_ == o.words_;
  }
  bool operator!=(const BitMask& o) const { return !(*this == o); }

  /// ASCII picture ('#' set, '.' clear), one line per row; for tests and debugging.
  std::string toString() const;
  /// Parses toString()-style text: lines of equal length, '#'/'1'/'X' set, anything else clear.
  static BitMask fromString(const std::string& text);

 private:
  int width_ = 0;
  int height_ = 0;
  int words_per_row_ = 0;
  std::vector<std::uint64_t> words_;
};

/// |A and shift(B, dx, dy)|. A and B must have the same size (std::invalid_argument otherwise).
std::int64_t andCount(const BitMask& a, const BitMask& b, int dx = 0, int dy = 0);
/// |A or shift(B, dx, dy)| on the unbounded plane = |A| + |B| - andCount(a, b, dx, dy).
std::int64_t orCount(const BitMask& a, const BitMask& b, int dx = 0, int dy = 0);
/// Similarity v2 of the thesis, IoU = |A and shift(B)| / |A or shift(B)|; 0 if both are empty.
double iou(const BitMask& a, const BitMask& b, int dx = 0, int dy = 0);

/// IoU from counts: inter / (area_a + area_b - inter), 0 when the union is empty. Monotone in inter,
/// so an upper bound on the intersection gives an upper bound on the IoU (used by the matcher).
inline double iouFromCounts(std::int64_t inter, std::int64_t area_a, std::int64_t area_b) {
  const std::int64_t uni = area_a + area_b - inter;
  return uni > 0 ? static_cast<double>(inter) / static_cast<double>(uni) : 0.0;
}

/// Best IoU over all shifts |dx| <= max_dx, |dy| <= max_dy, brute force (every shift evaluated).
/// Ties are broken towards the smaller shift (dx^2 + dy^2, then dy, then dx). Throws on size mismatch
/// or negative ranges.
struct ShiftedIou {
  double score = 0;
  int dx = 0;
  int dy = 0;
  std::int64_t intersection = 0;
};
ShiftedIou bestShiftIou(const BitMask& a, const BitMask& b, int max_dx, int max_dy);

/// The total order on shifts used for tie-breaking: true if (dx1, dy1) comes before (dx2, dy2).
inline bool shiftBefore(int dx1, int dy1, int dx2, int dy2) {
  const int r1 = dx1 * dx1 + dy1 * dy1, r2 = dx2 * dx2 + dy2 * dy2;
  if (r1 != r2) return r1 < r2;
  if (dy1 != dy2) return dy1 < dy2;
  return dx1 < dx2;
}

namespace detail {
/// Population count of one word (compiles to POPCNT when the target has it, see docs/vision.md).
inline int popcount64(std::uint64_t w) { return __builtin_popcountll(w); }
/// Row y of B shifted right by dx bits (dx may be negative), word k of the result; nwords = words/row.
inline std::uint64_t shiftedWord(const std::uint64_t* brow, int nwords, int k, int dx) {
  // floor division of dx by 64
  const int q = dx >= 0 ? (dx >> 6) : -(((-dx) + 63) >> 6);
  const int r = dx - q * 64;  // 0..63
  const int src = k - q;
  std::uint64_t w = 0;
  if (src >= 0 && src < nwords) w = brow[src] << r;
  if (r != 0 && src - 1 >= 0 && src - 1 < nwords) w |= brow[src - 1] >> (64 - r);
  return w;
}
}  // namespace detail

}  // namespace vision
}  // namespace textile_handling
