#include "textile_handling/db/drape_export.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <set>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/vision/mask_cv.h"

namespace textile_handling {
namespace db {

StoredDrapeMesh loadDrapeMesh(const HangingDrapeDatabase& db, std::int64_t simulation_id) {
  StoredDrapeMesh m;
  m.record = db.simulation(simulation_id);
  if (m.record.status != SimulationStatus::kDone)
    throw NotFoundError("simulation " + std::to_string(simulation_id) + " is " + toString(m.record.status) +
                        ", it has no stored shape");
  m.textile = db.textile(m.record.textile_id);
  m.positions = db.positions(simulation_id);
  std::string err;
  const ParticleGrid grid = ParticleGrid::rasterize(m.textile.outline, m.record.spacing, &err);
  if (grid.empty()) throw BlobFormatError("simulation " + std::to_string(simulation_id) + ": cannot rebuild its grid: " + err);
  if (3 * static_cast<Eigen::Index>(grid.numActive()) != m.positions.size())
    throw BlobFormatError("simulation " + std::to_string(simulation_id) + " stores " +
                          std::to_string(m.positions.size() / 3) + " particles, its textile grid has " +
                          std::to_string(grid.numActive()));
  m.triangles = vision::trianglesFromTopology(ParticleTopology::fromGrid(grid));
  m.held_particle = m.record.held_particle;
  if (m.held_particle < 0 || m.held_particle >= grid.numActive())
    throw BlobFormatError("simulation " + std::to_string(simulation_id) + " has no valid held particle");
  return m;
}

namespace {
std::ofstream openOut(const std::string& path) {
  std::ofstream f(path);
  if (!f) throw std::runtime_error("cannot write '" + path + "'");
  f.precision(9);
  return f;
}
void finish(std::ofstream& f, const std::string& path) {
  f.flush();
  if (!f) throw std::runtime_error("error while writing '" + path + "'");
}
}  // namespace

void writePly(const std::string& path, const VecX& positions, const std::vector<vision::Triangle>& triangles) {
  std::ofstream f = openOut(path);
  const Eigen::Index n = positions.size() / 3;
  f << "ply\nformat ascii 1.0\ncomment textile_handling drape_db export, metres, z up\n"
    << "element vertex " << n << "\nproperty float x\nproperty float y\nproperty float z\n"
    << "element face " << triangles.size() << "\nproperty list uchar int vertex_indices\nend_header\n";
  for (Eigen::Index k = 0; k < n; ++k)
    f << positions[3 * k] << ' ' << positions[3 * k + 1] << ' ' << positions[3 * k + 2] << '\n';
  for (const auto& t : triangles) f << "3 " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  finish(f, path);
}

void writeObj(const std::string& path, const VecX& positions, const std::vector<vision::Triangle>& triangles) {
  std::ofstream f = openOut(path);
  f << "# textile_handling drape_db export, metres, z up\n";
  const Eigen::Index n = positions.size() / 3;
  for (Eigen::Index k = 0; k < n; ++k)
    f << "v " << positions[3 * k] << ' ' << positions[3 * k + 1] << ' ' << positions[3 * k + 2] << '\n';
  for (const auto& t : triangles) f << "f " << t[0] + 1 << ' ' << t[1] + 1 << ' ' << t[2] + 1 << '\n';
  finish(f, path);
}

std::vector<std::string> exportViewPngs(const HangingDrapeDatabase& db, std::int64_t simulation_id,
                                        const std::string& dir, int sheet_scale) {
  const std::vector<StoredView> views = db.views(simulation_id);
  if (views.empty())
    throw NotFoundError("simulation " + std::to_string(simulation_id) + " has no stored views");
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw std::runtime_error("cannot create '" + dir + "': " + ec.message());
  std::vector<std::string> paths;
  std::set<std::string> names;
  const std::string stem = dir + "/sim" + std::to_string(simulation_id);
  for (const StoredView& v : views) {
    // Whole degrees as three digits (the usual views); other angles keep their fraction (millidegrees),
    // so that e.g. 0.5 and 1.0 deg do not both become "_view001.png" and overwrite each other.
    char name[64];
    const double a = v.view_angle_deg;
    if (std::abs(a - std::round(a)) < 1e-9)
      std::snprintf(name, sizeof name, "_view%03ld.png", std::lround(a));
    else
      std::snprintf(name, sizeof name, "_view%07.3f.png", a);
    if (!names.insert(name).second)
      throw std::runtime_error("views of simulation " + std::to_string(simulation_id) + " at angles closer than " +
                               "0.001 deg would share the file name '" + std::string(name) + "'");
    const std::string p = stem + name;
    if (!cv::imwrite(p, vision::toMat(v.mask))) throw std::runtime_error("cannot write '" + p + "'");
    paths.push_back(p);
  }
  // Contact sheet: 6 views per row, a grey 1-px grid between them.
  const int cols = std::min<int>(6, static_cast<int>(views.size()));
  const int rows = (static_cast<int>(views.size()) + cols - 1) / cols;
  const int s = std::max(1, sheet_scale);
  const int w = views.front().width_px * s, h = views.front().height_px * s;
  cv::Mat sheet(rows * (h + 1) + 1, cols * (w + 1) + 1, CV_8UC1, cv::Scalar(128));
  for (std::size_t k = 0; k < views.size(); ++k) {
    cv::Mat big;
    cv::resize(vision::toMat(views[k].mask), big, cv::Size(w, h), 0, 0, cv::INTER_NEAREST);
    const int r = static_cast<int>(k) / cols, c = static_cast<int>(k) % cols;
    big.copyTo(sheet(cv::Rect(1 + c * (w + 1), 1 + r * (h + 1), w, h)));
  }
  const std::string sp = stem + "_views.png";
  if (!cv::imwrite(sp, sheet)) throw std::runtime_error("cannot write '" + sp + "'");
  paths.push_back(sp);
  return paths;
}

}  // namespace db
}  // namespace textile_handling
