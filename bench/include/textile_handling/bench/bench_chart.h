// Log-log scatter and linear line charts for benchmarks (PNG via OpenCV, kept out of this header).
#pragma once

#include <string>
#include <vector>

namespace textile_handling {

struct ChartPoint {
  double x = 0, y = 0;   ///< both > 0 (log axes)
  std::string label;     ///< drawn next to the point
  std::string series;    ///< points of one series share a colour; listed in the legend
};

/// Writes a log-log scatter chart; returns false with a message if nothing can be drawn or written.
bool writeLogLogChart(const std::string& path, const std::vector<ChartPoint>& points, const std::string& x_label,
                      const std::string& y_label, const std::string& title, std::string* error);

/// Writes a chart with linear axes; consecutive points of one series are joined by lines (in the
/// order given). Returns false with a message if nothing can be drawn or written.
bool writeLineChart(const std::string& path, const std::vector<ChartPoint>& points, const std::string& x_label,
                    const std::string& y_label, const std::string& title, std::string* error);

}  // namespace textile_handling
