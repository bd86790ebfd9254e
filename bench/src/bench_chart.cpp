#include "textile_handling/bench/bench_chart.h"

#include "png_output.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace textile_handling {

namespace {

const cv::Scalar kInk(40, 40, 40);

/// How one series is drawn: a colour and, once the eight colours are used up, another marker shape.
struct SeriesStyle {
  cv::Scalar colour;
  int shape = 0;  ///< 0 disc, 1 square, 2 triangle, 3 diamond
};

std::map<std::string, SeriesStyle> seriesStyles(const std::vector<ChartPoint>& pts) {
  static const cv::Scalar palette[] = {{200, 80, 30}, {30, 150, 30}, {30, 30, 200}, {160, 40, 160},
                                       {0, 140, 200}, {120, 120, 0}, {90, 90, 90},  {200, 0, 100}};
  std::map<std::string, SeriesStyle> style;
  // Styles in order of first appearance, so a chart's first series always gets the first colour.
  for (const auto& p : pts)
    if (!style.count(p.series)) {
      const std::size_t k = style.size();
      style[p.series] = SeriesStyle{palette[k % 8], static_cast<int>((k / 8) % 4)};
    }
  return style;
}

/// A filled marker of half-size `r` pixels centred at `c`.
void drawMarker(cv::Mat& img, cv::Point c, int r, const SeriesStyle& s) {
  switch (s.shape) {
    case 1:
      cv::rectangle(img, {c.x - r, c.y - r}, {c.x + r, c.y + r}, s.colour, -1, cv::LINE_AA);
      return;
    case 2: {
      const std::vector<cv::Point> tri = {{c.x, c.y - r - 1}, {c.x - r - 1, c.y + r}, {c.x + r + 1, c.y + r}};
      cv::fillConvexPoly(img, tri, s.colour, cv::LINE_AA);
      return;
    }
    case 3: {
      const std::vector<cv::Point> dia = {{c.x, c.y - r - 2}, {c.x - r - 2, c.y}, {c.x, c.y + r + 2}, {c.x + r + 2, c.y}};
      cv::fillConvexPoly(img, dia, s.colour, cv::LINE_AA);
      return;
    }
    default:
      cv::circle(img, c, r, s.colour, -1, cv::LINE_AA);
  }
}

// Frame, title, axis labels and the legend right of the plot area.
void drawFrame(cv::Mat& img, int left, int top, int pw, int ph, const std::string& x_label, const std::string& y_label,
               const std::string& title, const std::map<std::string, SeriesStyle>& style) {
  cv::rectangle(img, {left, top}, {left + pw, top + ph}, kInk);
  cv::putText(img, title, {left, 24}, cv::FONT_HERSHEY_SIMPLEX, 0.65, kInk, 1, cv::LINE_AA);
  cv::putText(img, x_label, {left + pw / 2 - 80, img.rows - 20}, cv::FONT_HERSHEY_SIMPLEX, 0.55, kInk, 1, cv::LINE_AA);
  cv::putText(img, y_label, {10, top - 6}, cv::FONT_HERSHEY_SIMPLEX, 0.5, kInk, 1, cv::LINE_AA);
  int ly = top + 10;
  for (const auto& [name, s] : style) {
    drawMarker(img, {left + pw + 25, ly}, 6, s);
    cv::putText(img, name, {left + pw + 38, ly + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.5, kInk, 1, cv::LINE_AA);
    ly += 24;
  }
}

}  // namespace

bool writeLogLogChart(const std::string& path, const std::vector<ChartPoint>& points, const std::string& x_label,
                      const std::string& y_label, const std::string& title, std::string* error) {
  std::vector<ChartPoint> pts;
  for (const auto& p : points)
    if (p.x > 0 && p.y > 0 && std::isfinite(p.x) && std::isfinite(p.y)) pts.push_back(p);
  if (pts.empty()) {
    if (error) *error = "chart: no finite positive points";
    return false;
  }
  const int W = 1100, H = 720, left = 90, right = 330, top = 50, bottom = 70;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& p : pts) {
    x0 = std::min(x0, std::log10(p.x)); x1 = std::max(x1, std::log10(p.x));
    y0 = std::min(y0, std::log10(p.y)); y1 = std::max(y1, std::log10(p.y));
  }
  x0 = std::floor(x0 - 0.1); x1 = std::ceil(x1 + 0.1);
  y0 = std::floor(y0 - 0.1); y1 = std::ceil(y1 + 0.1);
  const int pw = W - left - right, ph = H - top - bottom;
  auto px = [&](double lx) { return left + static_cast<int>((lx - x0) / (x1 - x0) * pw); };
  auto py = [&](double ly) { return top + ph - static_cast<int>((ly - y0) / (y1 - y0) * ph); };
  const cv::Scalar grid(225, 225, 225), ink(40, 40, 40);
  for (double e = x0; e <= x1 + 1e-9; e += 1) {
    cv::line(img, {px(e), top}, {px(e), top + ph}, grid);
    cv::putText(img, "1e" + std::to_string(static_cast<int>(e)), {px(e) - 15, top + ph + 22}, cv::FONT_HERSHEY_SIMPLEX,
                0.45, ink, 1, cv::LINE_AA);
  }
  for (double e = y0; e <= y1 + 1e-9; e += 1) {
    cv::line(img, {left, py(e)}, {left + pw, py(e)}, grid);
    cv::putText(img, "1e" + std::to_string(static_cast<int>(e)), {left - 50, py(e) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45,
                ink, 1, cv::LINE_AA);
  }
  const std::map<std::string, SeriesStyle> style = seriesStyles(pts);
  drawFrame(img, left, top, pw, ph, x_label, y_label, title, style);
  for (const auto& p : pts) {
    const cv::Point c(px(std::log10(p.x)), py(std::log10(p.y)));
    drawMarker(img, c, 6, style.at(p.series));
    cv::putText(img, p.label, {c.x + 8, c.y - 6}, cv::FONT_HERSHEY_SIMPLEX, 0.33, style.at(p.series).colour, 1, cv::LINE_AA);
  }
  return writePngFile(path, img, "chart", error);
}

bool writeLineChart(const std::string& path, const std::vector<ChartPoint>& points, const std::string& x_label,
                    const std::string& y_label, const std::string& title, std::string* error) {
  std::vector<ChartPoint> pts;
  for (const auto& p : points)
    if (std::isfinite(p.x) && std::isfinite(p.y)) pts.push_back(p);
  if (pts.empty()) {
    if (error) *error = "chart: no finite points";
    return false;
  }
  const int W = 1100, H = 720, left = 110, right = 330, top = 50, bottom = 70;
  cv::Mat img(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  double x0 = 1e300, x1 = -1e300, y0 = 1e300, y1 = -1e300;
  for (const auto& p : pts) {
    x0 = std::min(x0, p.x), x1 = std::max(x1, p.x), y0 = std::min(y0, p.y), y1 = std::max(y1, p.y);
  }
  const double mx = 0.05 * std::max(x1 - x0, 1e-300), my = 0.05 * std::max(y1 - y0, 1e-300);
  x0 -= mx, x1 += mx, y0 -= my, y1 += my;
  const int pw = W - left - right, ph = H - top - bottom;
  auto px = [&](double x) { return left + static_cast<int>((x - x0) / (x1 - x0) * pw); };
  auto py = [&](double y) { return top + ph - static_cast<int>((y - y0) / (y1 - y0) * ph); };
  const cv::Scalar grid(225, 225, 225);
  for (int k = 0; k <= 5; ++k) {
    const double x = x0 + (x1 - x0) * k / 5, y = y0 + (y1 - y0) * k / 5;
    char text[32];
    cv::line(img, {px(x), top}, {px(x), top + ph}, grid);
    std::snprintf(text, sizeof text, "%.3g", x);
    cv::putText(img, text, {px(x) - 15, top + ph + 22}, cv::FONT_HERSHEY_SIMPLEX, 0.45, kInk, 1, cv::LINE_AA);
    cv::line(img, {left, py(y)}, {left + pw, py(y)}, grid);
    std::snprintf(text, sizeof text, "%.3g", y);
    cv::putText(img, text, {left - 90, py(y) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, kInk, 1, cv::LINE_AA);
  }
  if (y0 < 0 && y1 > 0) cv::line(img, {left, py(0)}, {left + pw, py(0)}, cv::Scalar(150, 150, 150));
  const std::map<std::string, SeriesStyle> style = seriesStyles(pts);
  drawFrame(img, left, top, pw, ph, x_label, y_label, title, style);
  for (std::size_t k = 0; k < pts.size(); ++k) {
    const cv::Point c(px(pts[k].x), py(pts[k].y));
    drawMarker(img, c, 3, style.at(pts[k].series));
    if (k > 0 && pts[k - 1].series == pts[k].series)
      cv::line(img, {px(pts[k - 1].x), py(pts[k - 1].y)}, c, style.at(pts[k].series).colour, 1, cv::LINE_AA);
  }
  return writePngFile(path, img, "chart", error);
}

}  // namespace textile_handling
