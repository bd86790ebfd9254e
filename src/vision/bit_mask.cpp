#include "textile_handling/vision/bit_mask.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>

#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace vision {

namespace {

std::uint64_t lastWordMask(int width) {
  const int r = width & 63;
  return r == 0 ? ~std::uint64_t{0} : ((std::uint64_t{1} << r) - 1);
}

void requireSameSize(const BitMask& a, const BitMask& b, const char* what) {
  if (!a.sameSize(b)) {
    std::ostringstream os;
    os << "mask sizes differ (" << a.width() << "x" << a.height() << " vs " << b.width() << "x"
       << b.height() << ")";
    throw InvalidArgumentError(what, "mask", os.str());
  }
}

}  // namespace

BitMask::BitMask(int width, int height) {
  if (width < 0 || height < 0)
    throw InvalidArgumentError("BitMask", width < 0 ? "width" : "height",
                               "negative size (width x height) " + std::to_string(width) + "x" + std::to_string(height));
  width_ = width;
  height_ = height;
  words_per_row_ = (width + 63) / 64;
  words_.assign(static_cast<std::size_t>(words_per_row_) * static_cast<std::size_t>(height), 0);
}

bool BitMask::at(int x, int y) const {
  if (x < 0 || y < 0 || x >= width_ || y >= height_)
    throw IndexOutOfRangeError("BitMask::at: (x, y) = (" + std::to_string(x) + ", " + std::to_string(y) + ") outside " +
                            std::to_string(width_) + "x" + std::to_string(height_));
  return get(x, y);
}

void BitMask::setSpan(int y, int x0, int x1) {
  if (y < 0 || y >= height_) return;
  x0 = std::max(x0, 0);
  x1 = std::min(x1, width_);
  if (x0 >= x1) return;
  std::uint64_t* r = row(y);
  const int w0 = x0 >> 6, w1 = (x1 - 1) >> 6;
  for (int w = w0; w <= w1; ++w) {
    const int lo = w == w0 ? (x0 & 63) : 0;
    const int hi = w == w1 ? ((x1 - 1) & 63) : 63;  // inclusive
    const std::uint64_t upper = hi == 63 ? ~std::uint64_t{0} : ((std::uint64_t{1} << (hi + 1)) - 1);
    const std::uint64_t lower = (std::uint64_t{1} << lo) - 1;
    r[w] |= upper & ~lower;
  }
}

void BitMask::clear() { std::fill(words_.begin(), words_.end(), 0); }

std::int64_t BitMask::count() const {
  std::int64_t n = 0;
  for (std::uint64_t w : words_) n += detail::popcount64(w);
  return n;
}

std::vector<int> BitMask::rowCounts() const {
  std::vector<int> c(static_cast<std::size_t>(height_), 0);
  for (int y = 0; y < height_; ++y) {
    const std::uint64_t* r = row(y);
    int n = 0;
    for (int k = 0; k < words_per_row_; ++k) n += detail::popcount64(r[k]);
    c[static_cast<std::size_t>(y)] = n;
  }
  return c;
}

std::vector<int> BitMask::colCounts() const {
  std::vector<int> c(static_cast<std::size_t>(width_), 0);
  for (int y = 0; y < height_; ++y) {
    const std::uint64_t* r = row(y);
    for (int k = 0; k < words_per_row_; ++k) {
      std::uint64_t w = r[k];
      while (w) {
        const int b = __builtin_ctzll(w);
        ++c[static_cast<std::size_t>(k * 64 + b)];
        w &= w - 1;
      }
    }
  }
  return c;
}

bool BitMask::boundingBox(int* x0, int* y0, int* x1, int* y1) const {
  int bx0 = width_, by0 = height_, bx1 = -1, by1 = -1;
  for (int y = 0; y < height_; ++y) {
    const std::uint64_t* r = row(y);
    for (int k = 0; k < words_per_row_; ++k) {
      if (!r[k]) continue;
      by0 = std::min(by0, y);
      by1 = y;
      bx0 = std::min(bx0, k * 64 + __builtin_ctzll(r[k]));
      bx1 = std::max(bx1, k * 64 + 63 - __builtin_clzll(r[k]));
    }
  }
  if (bx1 < 0) return false;
  if (x0) *x0 = bx0;
  if (y0) *y0 = by0;
  if (x1) *x1 = bx1 + 1;
  if (y1) *y1 = by1 + 1;
  return true;
}

BitMask BitMask::shifted(int dx, int dy) const {
  BitMask out(width_, height_);
  if (empty()) return out;
  const std::uint64_t last = lastWordMask(width_);
  for (int y = 0; y < height_; ++y) {
    const int sy = y - dy;
    if (sy < 0 || sy >= height_) continue;
    const std::uint64_t* src = row(sy);
    std::uint64_t* dst = out.row(y);
    for (int k = 0; k < words_per_row_; ++k) dst[k] = detail::shiftedWord(src, words_per_row_, k, dx);
    dst[words_per_row_ - 1] &= last;
  }
  return out;
}

std::string BitMask::toString() const {
  std::string s;
  s.reserve(static_cast<std::size_t>(height_) * static_cast<std::size_t>(width_ + 1));
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) s.push_back(get(x, y) ? '#' : '.');
    s.push_back('\n');
  }
  return s;
}

BitMask BitMask::fromString(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream is(text);
  std::string line;
  while (std::getline(is, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (!line.empty()) lines.push_back(line);
  }
  if (lines.empty()) return BitMask();
  const std::size_t w = lines.front().size();
  for (const auto& l : lines)
    if (l.size() != w) throw InvalidArgumentError("BitMask::fromString", "text", "text lines of different length");
  BitMask m(static_cast<int>(w), static_cast<int>(lines.size()));
  for (std::size_t y = 0; y < lines.size(); ++y)
    for (std::size_t x = 0; x < w; ++x) {
      const char c = lines[y][x];
      if (c == '#' || c == '1' || c == 'X') m.set(static_cast<int>(x), static_cast<int>(y));
    }
  return m;
}

std::int64_t andCount(const BitMask& a, const BitMask& b, int dx, int dy) {
  requireSameSize(a, b, "andCount");
  const int h = a.height(), nw = a.wordsPerRow();
  const int y0 = std::max(0, dy), y1 = std::min(h, h + dy);
  std::int64_t n = 0;
  for (int y = y0; y < y1; ++y) {
    const std::uint64_t* ar = a.row(y);
    const std::uint64_t* br = b.row(y - dy);
    for (int k = 0; k < nw; ++k) n += detail::popcount64(ar[k] & detail::shiftedWord(br, nw, k, dx));
  }
  return n;
}

std::int64_t orCount(const BitMask& a, const BitMask& b, int dx, int dy) {
  const std::int64_t inter = andCount(a, b, dx, dy);
  return a.count() + b.count() - inter;
}

double iou(const BitMask& a, const BitMask& b, int dx, int dy) {
  const std::int64_t inter = andCount(a, b, dx, dy);
  return iouFromCounts(inter, a.count(), b.count());
}

ShiftedIou bestShiftIou(const BitMask& a, const BitMask& b, int max_dx, int max_dy) {
  requireSameSize(a, b, "bestShiftIou");
  if (max_dx < 0 || max_dy < 0)
    throw InvalidArgumentError("bestShiftIou", max_dx < 0 ? "max_dx" : "max_dy", "negative shift range (max_dx, max_dy must be >= 0)");
  const std::int64_t na = a.count(), nb = b.count();
  ShiftedIou best;
  bool have = false;
  for (int dy = -max_dy; dy <= max_dy; ++dy) {
    for (int dx = -max_dx; dx <= max_dx; ++dx) {
      const std::int64_t inter = andCount(a, b, dx, dy);
      const double s = iouFromCounts(inter, na, nb);
      if (!have || s > best.score || (s == best.score && shiftBefore(dx, dy, best.dx, best.dy))) {
        best = ShiftedIou{s, dx, dy, inter};
        have = true;
      }
    }
  }
  return best;
}

}  // namespace vision
}  // namespace textile_handling
