// Tests of the yarns a cloth model gives to pictures (ClothModel::drawnYarns) and of their drawing in the
// rest-shape picture (rest_shape_picture.h): yarn_woven gives every warp and weft piece in node order,
// the particle models none, decorators forward them; the written PNG shows warp and weft in their
// colours (and a particle model's none), nearer cells hide yarns behind them, and dense yarns are
// thinned to every k-th line.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "../test_support.h"
#include "sim_test_support.h"
#include "textile_handling/sim/cloth_model_registry.h"
#include "textile_handling/sim/contact_force_model.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/particle_cloth_model.h"
#include "textile_handling/sim/self_collision_pass.h"
#include "textile_handling/sim/stability_scenes.h"
#include "textile_handling/sim/rest_shape_picture.h"
#include "textile_handling/sim/yarn_woven_model.h"

namespace textile_handling {
namespace {

// A 3 x 2 cm rectangle at d = 5 mm (7 x 5 particles) of the given model, held at one corner.
DrapeScene smallSheet(const std::string& model, bool self_collision = false) {
  DrapeSceneSpec s = sim_test_support::heldSquareSpec(0.02, 0.005);
  s.textile.outline = {Vec2(0, 0), Vec2(0.03, 0), Vec2(0.03, 0.02), Vec2(0, 0.02)};
  s.textile.named_points = {NamedPoint{"corner", "corner", Vec2(0, 0.02)}};
  s.model = ClothModelSpec(model);
  s.self_collision = self_collision;
  return buildDrapeScene(s);
}

// The scene's flat sheet stood upright in the x-z plane (y = 0), so the front view sees all of it.
VecX upright(const DrapeScene& scene) {
  VecX p = scene.model->positionsOf(scene.x0);
  for (Index i = 0; i < scene.model->numNodes(); ++i) node3(p, i) = Vec3(p[3 * i], 0, p[3 * i + 1]);
  return p;
}

// A rows x cols particle grid of spacing d, particle r cols + c at (row r, column c).
ParticleTopology gridTopology(int rows, int cols, Real d) {
  ParticleTopology t;
  t.spacing = d;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const Index p = r * cols + c;
      t.neighbour.push_back({c + 1 < cols ? p + 1 : -1, r + 1 < rows ? p + cols : -1, c > 0 ? p - 1 : -1,
                             r > 0 ? p - cols : -1});
      t.grid.push_back({r, c});
      t.area.push_back(d * d);
    }
  }
  return t;
}

// The yarn of grid line `line` (a row for a warp, a column for a weft) from `from` to `to` inclusive.
DrawnYarn gridYarn(bool warp, int line, int from, int to, int cols) {
  DrawnYarn y;
  y.warp = warp;
  y.line = static_cast<std::size_t>(line);
  for (int k = from; k <= to; ++k) y.nodes.push_back(warp ? line * cols + k : k * cols + line);
  return y;
}

bool nearColour(const cv::Vec3b& bgr, const std::array<unsigned char, 3>& rgb) {
  for (int k = 0; k < 3; ++k)
    if (std::abs(int(bgr[2 - k]) - int(rgb[static_cast<std::size_t>(k)])) > 40) return false;
  return true;
}

// Pixels within 40 per channel of `rgb` in `roi` of a picture.
int countColour(const cv::Mat& image, const cv::Rect& roi, const std::array<unsigned char, 3>& rgb) {
  int n = 0;
  for (int r = roi.y; r < roi.y + roi.height; ++r)
    for (int c = roi.x; c < roi.x + roi.width; ++c) n += nearColour(image.at<cv::Vec3b>(r, c), rgb);
  return n;
}

// Image rows of `roi` with more than `min_pixels` pixels of `rgb` (columns when `columns`).
int linesOfColour(const cv::Mat& image, const cv::Rect& roi, const std::array<unsigned char, 3>& rgb,
                  int min_pixels, bool columns) {
  int lines = 0;
  for (int a = 0; a < (columns ? roi.width : roi.height); ++a) {
    const cv::Rect line = columns ? cv::Rect(roi.x + a, roi.y, 1, roi.height) : cv::Rect(roi.x, roi.y + a, roi.width, 1);
    lines += countColour(image, line, rgb) > min_pixels;
  }
  return lines;
}

// Writes the picture to a fresh temporary file and reads it back (BGR); with KEEP_PICTURES set in the
// environment the file stays, to be looked at.
cv::Mat picture(const std::string& name, const ParticleTopology& t, const VecX& x, const std::vector<DrawnYarn>& yarns,
                int view_px) {
  const std::string path = test_support::freshTempPath("th_picture_", name + ".png");
  std::string error;
  EXPECT_TRUE(writeRestShapePicture(path, t, x, {}, yarns, view_px, &error)) << error;
  cv::Mat image = cv::imread(path, cv::IMREAD_COLOR);
  if (!std::getenv("KEEP_PICTURES")) std::remove(path.c_str());
  EXPECT_EQ(image.cols, 2 * view_px);
  EXPECT_EQ(image.rows, view_px);
  return image;
}

TEST(DrawnYarns, YarnWovenGivesEveryPieceInNodeOrder) {
  const DrapeScene scene = smallSheet("yarn_woven");
  const ParticleTopology t = ParticleTopology::fromGrid(scene.grid);
  const std::vector<DrawnYarn> yarns = scene.model->drawnYarns();
  // 5 rows of 7 particles: 5 warp pieces of 7 crossings, 7 weft pieces of 5.
  ASSERT_EQ(yarns.size(), 12u);
  int min_row = t.grid[0][0], min_col = t.grid[0][1];
  for (const auto& rc : t.grid) min_row = std::min(min_row, rc[0]), min_col = std::min(min_col, rc[1]);
  std::vector<int> on_warp(static_cast<std::size_t>(t.size()), 0), on_weft = on_warp;
  std::set<std::size_t> warp_lines, weft_lines;
  for (const DrawnYarn& y : yarns) {
    ASSERT_EQ(y.nodes.size(), y.warp ? 7u : 5u);
    const int along = y.warp ? 0 : 1;  // neighbour slot along the yarn: right (warp) or up (weft)
    EXPECT_LT(t.neighbour[y.nodes.front()][along + 2], 0) << "a yarn starts at its run's first particle";
    for (std::size_t k = 0; k + 1 < y.nodes.size(); ++k) EXPECT_EQ(t.neighbour[y.nodes[k]][along], y.nodes[k + 1]);
    EXPECT_LT(t.neighbour[y.nodes.back()][along], 0);
    EXPECT_EQ(y.line, static_cast<std::size_t>(y.warp ? t.grid[y.nodes[0]][0] - min_row : t.grid[y.nodes[0]][1] - min_col));
    for (Index n : y.nodes) ++(y.warp ? on_warp : on_weft)[static_cast<std::size_t>(n)];
    (y.warp ? warp_lines : weft_lines).insert(y.line);
  }
  EXPECT_EQ(warp_lines.size(), 5u);
  EXPECT_EQ(weft_lines.size(), 7u);
  for (Index p = 0; p < t.size(); ++p) {
    EXPECT_EQ(on_warp[static_cast<std::size_t>(p)], 1) << "particle " << p;
    EXPECT_EQ(on_weft[static_cast<std::size_t>(p)], 1) << "particle " << p;
  }
  // The sheet's own pieces, one to one.
  const auto& pieces = dynamic_cast<const YarnWovenModel&>(*scene.model).sheet().grid.pieces;
  ASSERT_EQ(pieces.size(), yarns.size());
  for (std::size_t k = 0; k < pieces.size(); ++k) {
    EXPECT_EQ(yarns[k].warp, pieces[k].warp);
    EXPECT_EQ(yarns[k].nodes, std::vector<Index>(pieces[k].nodes.begin(), pieces[k].nodes.end()));
  }
}

TEST(DrawnYarns, ParticleModelsHaveNone) {
  for (const char* model : {"particle_kes", "choi_ko"}) EXPECT_TRUE(smallSheet(model).model->drawnYarns().empty()) << model;
}

// A particle model that reports two yarns, to see the decorators forward them.
class ParticleModelWithYarns : public ParticleClothModel {
 public:
  using ParticleClothModel::ParticleClothModel;
  std::vector<DrawnYarn> drawnYarns() const override { return {gridYarn(true, 0, 0, 2, 3), gridYarn(false, 1, 0, 2, 3)}; }
};

TEST(DrawnYarns, DecoratorsForwardThem) {
  const ParticleTopology t = gridTopology(3, 3, 0.01);
  ParticleModelWithYarns base(t, Material::cotton());
  SelfCollisionPass pass(t, PinnedNodes{});
  const ContactForceModel contact(base, pass);
  const AnchoredClothModel anchored(base, {}, {}, 1.0);
  for (const ClothModel* m : {static_cast<const ClothModel*>(&contact), static_cast<const ClothModel*>(&anchored)}) {
    const std::vector<DrawnYarn> yarns = m->drawnYarns();
    ASSERT_EQ(yarns.size(), 2u);
    EXPECT_TRUE(yarns[0].warp);
    EXPECT_EQ(yarns[0].nodes, (std::vector<Index>{0, 1, 2}));
    EXPECT_FALSE(yarns[1].warp);
    EXPECT_EQ(yarns[1].line, 1u);
    EXPECT_EQ(yarns[1].nodes, (std::vector<Index>{1, 4, 7}));
  }
}

TEST(RestShapePictureYarns, YarnSheetShowsWarpAndWeftParticleSheetNeither) {
  const int px = 200;
  const cv::Rect front(0, 0, px, px);
  const DrapeScene yarn = smallSheet("yarn_woven");
  const cv::Mat with = picture("yarn", ParticleTopology::fromGrid(yarn.grid), upright(yarn), yarn.model->drawnYarns(), px);
  // 30 px per 5 mm: 5 horizontal warp lines of 180 px and 7 vertical weft lines of 120 px.
  EXPECT_GT(countColour(with, front, kPictureWarpRgb), 500);
  EXPECT_GT(countColour(with, front, kPictureWeftRgb), 500);
  EXPECT_EQ(linesOfColour(with, front, kPictureWarpRgb, 100, false), 5);
  EXPECT_EQ(linesOfColour(with, front, kPictureWeftRgb, 80, true), 7);
  const cv::Rect all(0, 0, 2 * px, px);
  const DrapeScene particles = smallSheet("particle_kes");
  const cv::Mat without = picture("particles", ParticleTopology::fromGrid(particles.grid), upright(particles),
                                  particles.model->drawnYarns(), px);
  EXPECT_EQ(countColour(without, all, kPictureWarpRgb), 0);
  EXPECT_EQ(countColour(without, all, kPictureWeftRgb), 0);
  // The cells are there: the sheet covers 180 x 120 px of the front view.
  EXPECT_GT(without.rows * without.cols - countColour(without, all, {255, 255, 255}), 180 * 120);
}

TEST(RestShapePictureYarns, NearerCellsHideYarns) {
  // A sheet folded at its top: rows 0..9 in one layer, rows 10..19 folded down behind or in front of it.
  // Warp yarns on the first layer, weft yarns on the second, both inside the layers' common outline.
  const int rows = 20, cols = 12;
  const Real d = 0.01;
  const ParticleTopology t = gridTopology(rows, cols, d);
  std::vector<DrawnYarn> yarns;
  for (int r = 2; r <= 7; ++r) yarns.push_back(gridYarn(true, r, 2, cols - 3, cols));
  for (int c = 2; c <= cols - 3; ++c) yarns.push_back(gridYarn(false, c, 12, 17, cols));
  const cv::Rect front(0, 0, 200, 200);
  for (const Real second_layer_y : {0.02, -0.02}) {  // behind the first layer, then in front of it
    VecX x(3 * t.size());
    for (Index p = 0; p < t.size(); ++p) {
      const int r = t.grid[p][0], c = t.grid[p][1];
      node3(x, p) = r < rows / 2 ? Vec3(c * d, 0, r * d) : Vec3(c * d, second_layer_y, (rows - 1 - r) * d);
    }
    const cv::Mat image = picture("fold", t, x, yarns, 200);
    const bool first_in_front = second_layer_y > 0;
    EXPECT_EQ(countColour(image, front, kPictureWarpRgb) > 300, first_in_front) << "second layer y " << second_layer_y;
    EXPECT_EQ(countColour(image, front, kPictureWeftRgb) > 300, !first_in_front) << "second layer y " << second_layer_y;
    EXPECT_EQ(countColour(image, front, first_in_front ? kPictureWeftRgb : kPictureWarpRgb), 0);
  }
}

TEST(RestShapePictureYarns, DenseYarnsAreThinnedToEveryKthLine) {
  // 201 x 201 particles, upright, one warp yarn per row and one weft yarn per column.
  const int n = 201;
  const Real d = 0.005;
  const ParticleTopology t = gridTopology(n, n, d);
  VecX x(3 * t.size());
  for (Index p = 0; p < t.size(); ++p) node3(x, p) = Vec3(t.grid[p][1] * d, 0, t.grid[p][0] * d);
  std::vector<DrawnYarn> yarns;
  for (int k = 0; k < n; ++k) {
    yarns.push_back(gridYarn(true, k, 0, n - 1, n));
    yarns.push_back(gridYarn(false, k, 0, n - 1, n));
  }
  // 400 px: at most 80 lines per direction, so every 3rd of 201 (67 lines, 5.7 px apart).
  ASSERT_EQ(maxPictureYarnLines(400), 80);
  const cv::Mat thinned = picture("thinned", t, x, yarns, 400);
  EXPECT_EQ(linesOfColour(thinned, cv::Rect(0, 0, 400, 400), kPictureWarpRgb, 200, false), 67);
  EXPECT_EQ(linesOfColour(thinned, cv::Rect(0, 0, 400, 400), kPictureWeftRgb, 200, true), 67);
  // 1100 px: up to 220 lines, so all 201 (5.4 px apart).
  const cv::Mat all = picture("all", t, x, yarns, 1100);
  EXPECT_EQ(linesOfColour(all, cv::Rect(0, 0, 1100, 1100), kPictureWarpRgb, 500, false), 201);
  EXPECT_EQ(linesOfColour(all, cv::Rect(0, 0, 1100, 1100), kPictureWeftRgb, 500, true), 201);
}

TEST(RestShapePictureYarns, YarnNodeOutsideTheShapeRefused) {
  const ParticleTopology t = gridTopology(2, 2, 0.01);
  VecX x = VecX::Zero(12);
  for (Index p = 0; p < 4; ++p) node3(x, p) = Vec3(t.grid[p][1] * 0.01, 0, t.grid[p][0] * 0.01);
  DrawnYarn y;
  y.nodes = {0, 4};
  std::string error;
  EXPECT_FALSE(writeRestShapePicture(test_support::freshTempPath("th_picture_", "bad.png"), t, x, {}, {y}, 100, &error));
  EXPECT_NE(error.find("yarn node 4"), std::string::npos) << error;
}

}  // namespace
}  // namespace textile_handling
