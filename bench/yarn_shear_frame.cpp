// yarn_shear_frame: the picture-frame shear test of the yarn_woven model for the three bundled weaves
// (docs/yarn_model.md, "Shear frame"): load-unload curves of the frame's moment against the shear
// angle, the hysteresis (loop area) and the jamming knee.
//
//   yarn_shear_frame [--out DIR] [--min-angle PHI] [--step RAD] [--yarns N] [--relax S] [--jamming-gain C]
//
// Writes DIR/shear_frame.csv (weave, frame and shear angle, loading, moment, kinetic energy) and
// DIR/shear_frame.png, and prints per weave the largest moment, the moment at 0.4 rad of shear on
// loading and the loop area. Exit status: 0 done, 2 usage, 4 outputs cannot be written, 5 error.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/bench/yarn_shear_frame.h"

using namespace textile_handling;

int main(int argc, char** argv) {
  std::string out = "out/yarn_shear_frame";
  ShearFrameSpec spec;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "yarn_shear_frame: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--out") out = value();
    else if (a == "--min-angle") spec.min_angle = std::atof(value().c_str());
    else if (a == "--step") spec.angle_step = std::atof(value().c_str());
    else if (a == "--yarns") spec.yarns = std::atoi(value().c_str());
    else if (a == "--relax") spec.relax_time = std::atof(value().c_str());
    else if (a == "--jamming-gain") spec.model.crossing.jamming_gain = std::atof(value().c_str());
    else {
      std::cerr << "usage: yarn_shear_frame [--out DIR] [--min-angle PHI] [--step RAD] [--yarns N] [--relax S] [--jamming-gain C]\n";
      return 2;
    }
  }
  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  std::ofstream csv(out + "/shear_frame.csv");
  if (!csv) {
    std::cerr << "yarn_shear_frame: cannot write " << out << "/shear_frame.csv\n";
    return 4;
  }
  std::vector<ChartPoint> chart;
  bool header = true;
  try {
    for (const std::string weave : {"plain", "twill_2_2", "satin_5"}) {
      ShearFrameSpec s = spec;
      s.model.fabric.weave = namedWeave(weave);
      const std::vector<ShearFramePoint> points = runShearFrame(s);
      std::ostringstream rows;
      writeShearFrameCsv(rows, weave, points);
      std::string text = rows.str();
      if (!header) text = text.substr(text.find('\n') + 1);
      header = false;
      csv << text;
      Real largest = 0, at_04 = 0, area = 0;
      for (std::size_t k = 0; k < points.size(); ++k) {
        const ShearFramePoint& p = points[k];
        largest = std::max(largest, p.moment);
        if (p.loading && std::abs(p.shear_angle - 0.4) < 0.5 * s.angle_step) at_04 = p.moment;
        if (k > 0) area += 0.5 * (p.moment + points[k - 1].moment) * (p.shear_angle - points[k - 1].shear_angle);
        chart.push_back({p.shear_angle, p.moment, "", weave});
      }
      std::printf("%-10s largest moment %.4g N m, at 0.4 rad (loading) %.4g N m, loop area %.4g J\n", weave.c_str(),
                  largest, at_04, area);
    }
  } catch (const std::exception& e) {
    std::cerr << "yarn_shear_frame: " << e.what() << "\n";
    return 5;
  }
  std::string error;
  if (!writeLineChart(out + "/shear_frame.png", chart, "shear angle [rad]", "frame moment [N m]",
                      "yarn_woven picture-frame shear: load and unload", &error)) {
    std::cerr << "yarn_shear_frame: " << error << "\n";
    return 4;
  }
  std::cout << "wrote " << out << "/shear_frame.csv and .png\n";
  return 0;
}
