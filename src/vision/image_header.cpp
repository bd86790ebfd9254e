#include "textile_handling/vision/image_header.h"

#include <cctype>
#include <fstream>
#include <stdexcept>
#include <vector>

#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace vision {

namespace {

[[noreturn]] void bad(const std::string& path, const std::string& why) {
  throw ImageDecodeError(path, why);
}

std::int64_t be16(const unsigned char* p) { return (std::int64_t{p[0]} << 8) | p[1]; }
std::int64_t be32(const unsigned char* p) { return (be16(p) << 16) | be16(p + 2); }
std::int64_t le32s(const unsigned char* p) {  // signed (BMP heights are negative for top-down rows)
  const std::uint32_t u = std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
                          (std::uint32_t{p[3]} << 24);
  return static_cast<std::int32_t>(u);
}

// JPEG: the first start-of-frame segment (SOF0..SOF15 except DHT 0xC4, JPG 0xC8, DAC 0xCC) holds the size.
ImageDimensions jpegDimensions(std::ifstream& in, const std::string& path) {
  in.seekg(2);
  for (int segments = 0; segments < 10000; ++segments) {
    unsigned char m[4];
    if (!in.read(reinterpret_cast<char*>(m), 2)) break;
    while (m[0] == 0xFF && m[1] == 0xFF) {  // fill bytes
      if (!in.read(reinterpret_cast<char*>(m + 1), 1)) bad(path, "truncated JPEG header");
    }
    if (m[0] != 0xFF) bad(path, "damaged JPEG header");
    if (!in.read(reinterpret_cast<char*>(m + 2), 2)) break;
    const std::int64_t len = be16(m + 2);
    if (len < 2) bad(path, "damaged JPEG segment length");
    const int marker = m[1];
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC) {
      unsigned char f[5];
      if (!in.read(reinterpret_cast<char*>(f), 5)) break;
      return {be16(f + 3), be16(f + 1), "jpeg"};
    }
    in.seekg(len - 2, std::ios::cur);
  }
  bad(path, "no JPEG frame header found");
}

// PNM: magic, then width and height as decimal text (comments start with '#').
ImageDimensions pnmDimensions(std::ifstream& in, const std::string& path) {
  in.seekg(2);
  std::int64_t v[2] = {0, 0};
  for (std::int64_t& x : v) {
    int c = in.get();
    while (c != EOF && (std::isspace(c) || c == '#')) {
      if (c == '#')
        while (c != EOF && c != '\n') c = in.get();
      c = in.get();
    }
    if (c == EOF || !std::isdigit(c)) bad(path, "damaged PNM header");
    for (int digits = 0; c != EOF && std::isdigit(c); c = in.get())
      if (++digits > 12) bad(path, "PNM size too long");
      else x = 10 * x + (c - '0');
  }
  return {v[0], v[1], "pnm"};
}

}  // namespace

ImageDimensions readImageDimensions(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) bad(path, "cannot open the file");
  unsigned char h[26] = {};
  in.read(reinterpret_cast<char*>(h), sizeof h);
  const std::streamsize n = in.gcount();
  in.clear();
  ImageDimensions d;
  static const unsigned char kPng[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (n >= 24 && std::equal(kPng, kPng + 8, h) && std::equal(h + 12, h + 16, "IHDR")) {
    d = {be32(h + 16), be32(h + 20), "png"};
  } else if (n >= 3 && h[0] == 0xFF && h[1] == 0xD8 && h[2] == 0xFF) {
    d = jpegDimensions(in, path);
  } else if (n >= 26 && h[0] == 'B' && h[1] == 'M') {
    const std::int64_t hh = le32s(h + 22);
    d = {le32s(h + 18), hh < 0 ? -hh : hh, "bmp"};
  } else if (n >= 2 && h[0] == 'P' && h[1] >= '1' && h[1] <= '6') {
    d = pnmDimensions(in, path);
  } else {
    bad(path, "not a PNG, JPEG, BMP or PNM file");
  }
  if (d.width <= 0 || d.height <= 0) bad(path, "the " + d.format + " header gives no positive size");
  return d;
}

}  // namespace vision
}  // namespace textile_handling
