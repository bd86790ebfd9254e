// fitShapeToDepth(): a matched shape deformed onto a measured depth image. A curved sheet hanging in
// front of a VGA camera is the truth; its rendered depth and mask are the measurement.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include <Eigen/Geometry>

#include "recognition_test_support.h"
#include "textile_handling/recognition/shape_fitting.h"
#include "textile_handling/vision/shaded_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;
using textile_handling::test_support::vga;

namespace {

struct Sheet {
  VecX x;
  std::vector<vision::Triangle> triangles;
  Index top = 0;  // held vertex (top middle)
};

// A 30 x 40 cm sheet at 1.5 cm spacing hanging below (0, -0.2, 1.2) in the optical frame (y down),
// bent about the vertical axis (a cylinder of radius 0.4 m, bulging towards the camera), plus
// `perturb` times a smooth deformation that grows with the distance from the top.
Sheet makeSheet(double perturb) {
  Sheet s;
  const int nx = 21, ny = 27;
  const double d = 0.015;
  s.x.resize(3 * nx * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double u = (i - (nx - 1) / 2.0) * d, v = j * d;  // across, down
      const double a = u / 0.4;
      Vec3 p(0.4 * std::sin(a), -0.2 + v, 1.2 - 0.4 * (std::cos(a) - 1.0) * -1.0);
      const double t = v / ((ny - 1) * d);
      p += perturb * Vec3(0.012 * t * t, 0.0, 0.035 * t * t * (1.0 + 0.5 * u / 0.15));
      s.x.segment<3>(3 * (j * nx + i)) = p;
    }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const Index a = j * nx + i, b = a + 1, c = a + nx, e = c + 1;
      s.triangles.push_back({a, b, e});
      s.triangles.push_back({a, e, c});
    }
  s.top = (nx - 1) / 2;
  return s;
}

vision::ShadedImage measure(const Sheet& s) {
  vision::ShadedRenderOptions ro;
  ro.intrinsics = vga();
  ro.noise_sigma = 0;
  return vision::renderShaded(s.x, s.triangles, ro);
}

double meanError(const VecX& a, const VecX& b) {
  double sum = 0;
  for (Eigen::Index i = 0; i < a.size() / 3; ++i) sum += (a.segment<3>(3 * i) - b.segment<3>(3 * i)).norm();
  return sum / static_cast<double>(a.size() / 3);
}

}  // namespace

TEST(ShapeFitting, TheTrueShapeStaysPut) {
  const Sheet truth = makeSheet(0.0);
  const vision::ShadedImage m = measure(truth);
  ShapeFitReport rep;
  const VecX f = fitShapeToDepth(truth.x, truth.triangles, truth.top, m.depth, m.mask, vga(), {}, &rep);
  EXPECT_TRUE(rep.applied) << rep.note;
  EXPECT_GT(rep.depth_correspondences, 200);
  EXPECT_LT(rep.max_displacement_m, 0.004);
  EXPECT_LT(meanError(f, truth.x), 0.001);
}

TEST(ShapeFitting, ADeformedShapeMovesTowardsTheMeasuredSurface) {
  const Sheet truth = makeSheet(0.0), guess = makeSheet(1.0);
  const vision::ShadedImage m = measure(truth);
  ShapeFitReport rep;
  const VecX f = fitShapeToDepth(guess.x, guess.triangles, guess.top, m.depth, m.mask, vga(), {}, &rep);
  ASSERT_TRUE(rep.applied) << rep.note;
  const double before = meanError(guess.x, truth.x), after = meanError(f, truth.x);
  std::printf("mean vertex error %.1f mm -> %.1f mm; depth residual %.1f -> %.1f mm, %d iterations\n", 1e3 * before,
              1e3 * after, 1e3 * rep.mean_depth_residual_before_m, 1e3 * rep.mean_depth_residual_after_m, rep.iterations);
  EXPECT_GT(before, 0.01);
  EXPECT_LT(after, 0.5 * before);
  EXPECT_LT(rep.mean_depth_residual_after_m, rep.mean_depth_residual_before_m);
  // The held vertex does not move.
  EXPECT_LT((f.segment<3>(3 * guess.top) - guess.x.segment<3>(3 * guess.top)).norm(), 1e-6);
}

// The lower part of the truth swung 20 cm away from the matched shape (sideways in the image, or towards
// the camera): the fit must reach it, since a stored shape can be that far off where a real drape folds
// differently. `swing` is the displacement of the bottom edge [m], growing with the square of the height
// below the top.
Sheet swungSheet(const Vec3& swing) {
  Sheet s = makeSheet(0.0);
  const double top_y = s.x(3 * s.top + 1), bottom_y = s.x(s.x.size() - 2);
  for (Eigen::Index i = 0; i < s.x.size() / 3; ++i) {
    const double t = (s.x(3 * i + 1) - top_y) / (bottom_y - top_y);
    s.x.segment<3>(3 * i) += t * t * swing;
  }
  return s;
}

// The truth with its lower right part folded by `angle` towards the camera about a hinge across the
// corner, `hinge_m` from the corner in the flat sheet: the corner moves 2 hinge_m sin(angle / 2).
Sheet foldedCorner(double hinge_m, double angle) {
  Sheet s = makeSheet(0.0);
  const int nx = 21, ny = 27;
  const double d = 0.015, uc = 0.15, vc = (ny - 1) * d;
  const double c = uc + vc - hinge_m * std::sqrt(2.0);  // hinge: u + v = c
  auto at = [&](double u, double v) {  // position of a flat-sheet point (bilinear in the grid)
    const double fi = u / d + (nx - 1) / 2.0, fj = v / d;
    const int i = std::min(nx - 2, static_cast<int>(fi)), j = std::min(ny - 2, static_cast<int>(fj));
    const double a = fi - i, b = fj - j;
    auto p = [&](int ii, int jj) { return Vec3(s.x.segment<3>(3 * (jj * nx + ii))); };
    return Vec3((1 - a) * (1 - b) * p(i, j) + a * (1 - b) * p(i + 1, j) + (1 - a) * b * p(i, j + 1) + a * b * p(i + 1, j + 1));
  };
  const Vec3 p1 = at(uc, c - uc), p2 = at(c - vc, vc);
  const Vec3 axis = (p2 - p1).normalized();
  const Index corner = nx * ny - 1;
  Sheet best = s;
  for (double sign : {1.0, -1.0}) {
    const Mat3 r = Eigen::AngleAxis<Real>(sign * angle, axis).toRotationMatrix();
    Sheet f = s;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const double u = (i - (nx - 1) / 2.0) * d, v = j * d;
        if (u + v <= c) continue;
        f.x.segment<3>(3 * (j * nx + i)) = p1 + r * (s.x.segment<3>(3 * (j * nx + i)) - p1);
      }
    if (sign > 0 || f.x(3 * corner + 2) < best.x(3 * corner + 2)) best = f;
  }
  return best;
}

TEST(ShapeFitting, ReachesALowerPartTwentyCentimetresAway) {
  const Sheet guess = makeSheet(0.0);
  const Index corner = static_cast<Index>(guess.x.size() / 3) - 1;  // the bottom right corner
  ShapeFitOptions linear;  // the edge vectors kept and the 6 cm limit from the start: a fit without reach
  linear.reach_m = linear.max_correspondence_m;
  ShapeFitOptions turning;  // the default reach with a rotation per vertex
  turning.rotations = true;
  struct Case {
    const char* what;
    Sheet truth;
    ShapeFitOptions options;
    double max_corner_error_m;
    bool needs_reach;  // the linear fit without reach stops far short
  };
  // The fold keeps lengths (a flap turned as a whole) and needs the rotations; the swings stretch the
  // sheet. Sideways the depth says nothing about where on the surface a point lies, only the outline does,
  // hence the looser bound.
  const std::vector<Case> cases = {
      {"corner folded 60 deg towards the camera, hinge 20 cm away", foldedCorner(0.20, M_PI / 3), turning, 0.03, true},
      {"lower part swung 20 cm towards the camera", swungSheet(Vec3(0, 0, -0.20)), ShapeFitOptions(), 0.03, false},
      {"lower part swung 20 cm sideways", swungSheet(Vec3(0.20, 0, 0)), ShapeFitOptions(), 0.05, true}};
  for (const Case& c : cases) {
    const vision::ShadedImage m = measure(c.truth);
    ShapeFitReport rep, rep_linear, rep_default;
    const VecX f = fitShapeToDepth(guess.x, guess.triangles, guess.top, m.depth, m.mask, vga(), c.options, &rep);
    const VecX g = fitShapeToDepth(guess.x, guess.triangles, guess.top, m.depth, m.mask, vga(), linear, &rep_linear);
    const VecX h = fitShapeToDepth(guess.x, guess.triangles, guess.top, m.depth, m.mask, vga(), {}, &rep_default);
    ASSERT_TRUE(rep.applied && rep_linear.applied && rep_default.applied) << rep.note;
    auto cornerError = [&](const VecX& x) { return (x.segment<3>(3 * corner) - c.truth.x.segment<3>(3 * corner)).norm(); };
    std::printf("%s: corner %.1f cm -> %.1f cm (default options %.1f, linear without reach %.1f cm), mean vertex error "
                "%.1f -> %.1f cm, largest move %.1f cm\n",
                c.what, 100 * cornerError(guess.x), 100 * cornerError(f), 100 * cornerError(h), 100 * cornerError(g),
                100 * meanError(guess.x, c.truth.x), 100 * meanError(f, c.truth.x), 100 * rep.max_displacement_m);
    EXPECT_GT(cornerError(guess.x), 0.19) << c.what;
    EXPECT_LT(cornerError(f), c.max_corner_error_m) << c.what;
    if (c.needs_reach) EXPECT_LT(cornerError(f), 0.5 * cornerError(g)) << c.what;
    EXPECT_LT(meanError(f, c.truth.x), 0.6 * meanError(guess.x, c.truth.x)) << c.what;
    EXPECT_LT((f.segment<3>(3 * guess.top) - guess.x.segment<3>(3 * guess.top)).norm(), 1e-6);
  }
}

TEST(ShapeFitting, WithoutDepthTheShapeIsReturnedUnchanged) {
  const Sheet truth = makeSheet(0.0), guess = makeSheet(1.0);
  vision::ShadedImage m = measure(truth);
  m.depth.setTo(std::numeric_limits<float>::quiet_NaN());
  ShapeFitReport rep;
  const VecX f = fitShapeToDepth(guess.x, guess.triangles, guess.top, m.depth, m.mask, vga(), {}, &rep);
  EXPECT_FALSE(rep.applied);
  EXPECT_FALSE(rep.note.empty());
  EXPECT_EQ((f - guess.x).norm(), 0.0);
  cv::Mat empty_mask = cv::Mat::zeros(m.mask.size(), CV_8UC1);
  const VecX g = fitShapeToDepth(guess.x, guess.triangles, guess.top, measure(truth).depth, empty_mask, vga(), {}, &rep);
  EXPECT_FALSE(rep.applied);
  EXPECT_EQ((g - guess.x).norm(), 0.0);
}

TEST(ShapeFitting, BadInputIsRejected) {
  const Sheet s = makeSheet(0.0);
  const vision::ShadedImage m = measure(s);
  EXPECT_THROW(fitShapeToDepth(VecX(s.x.head(s.x.size() - 1)), s.triangles, s.top, m.depth, m.mask, vga()),
               RecognitionError);
  EXPECT_THROW(fitShapeToDepth(s.x, s.triangles, s.x.size(), m.depth, m.mask, vga()), RecognitionError);
  std::vector<vision::Triangle> bad = s.triangles;
  bad.push_back({0, 1, static_cast<Index>(s.x.size())});
  EXPECT_THROW(fitShapeToDepth(s.x, bad, s.top, m.depth, m.mask, vga()), RecognitionError);
  cv::Mat depth16;
  m.depth.convertTo(depth16, CV_16UC1);
  EXPECT_THROW(fitShapeToDepth(s.x, s.triangles, s.top, depth16, m.mask, vga()), RecognitionError);
  cv::Mat small(10, 10, CV_32FC1, cv::Scalar(1.0));
  EXPECT_THROW(fitShapeToDepth(s.x, s.triangles, s.top, small, m.mask, vga()), RecognitionError);
  ShapeFitOptions o;
  o.iterations = 0;
  EXPECT_THROW(fitShapeToDepth(s.x, s.triangles, s.top, m.depth, m.mask, vga(), o), RecognitionError);
  o = ShapeFitOptions();
  o.reach_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(fitShapeToDepth(s.x, s.triangles, s.top, m.depth, m.mask, vga(), o), RecognitionError);
}

TEST(ShapeFitting, SecondViewFromBehindFitsInTheCommonFrame) {
  // Camera 1 is the optical frame of makeSheet; camera 2 looks at the sheet from behind (half turn about
  // the vertical line x = 0, z = 1.2), so the common frame is camera 1's. Each view alone must pull the
  // deformed sheet towards the truth (a wrong frame mapping would push it away), and both together at
  // least as well as the better one.
  const Sheet truth = makeSheet(0.0), guess = makeSheet(1.0);
  const Mat3 r2 = Eigen::AngleAxis<Real>(M_PI, Vec3::UnitY()).toRotationMatrix();
  const Vec3 c(0, 0, 1.2);
  const Vec3 t2 = c - r2 * c;
  Sheet truth2 = truth;
  for (Eigen::Index i = 0; i < truth.x.size() / 3; ++i) truth2.x.segment<3>(3 * i) = r2 * truth.x.segment<3>(3 * i) + t2;
  const vision::ShadedImage m1 = measure(truth), m2 = measure(truth2);
  DepthView v1, v2;
  v1.depth = m1.depth;
  v1.mask = m1.mask;
  v1.intrinsics = vga();
  v2.depth = m2.depth;
  v2.mask = m2.mask;
  v2.intrinsics = vga();
  v2.rotation = r2;
  v2.translation = t2;
  const double before = meanError(guess.x, truth.x);
  double after[3];
  const std::vector<std::vector<DepthView>> sets = {{v1}, {v2}, {v1, v2}};
  for (int k = 0; k < 3; ++k) {
    ShapeFitReport rep;
    const VecX f = fitShapeToDepthViews(guess.x, guess.triangles, guess.top, sets[static_cast<size_t>(k)], {}, &rep);
    ASSERT_TRUE(rep.applied) << k << ": " << rep.note;
    after[k] = meanError(f, truth.x);
    EXPECT_LT((f.segment<3>(3 * guess.top) - guess.x.segment<3>(3 * guess.top)).norm(), 1e-6);
  }
  std::printf("mean vertex error %.1f mm -> front %.1f, back %.1f, both %.1f mm\n", 1e3 * before, 1e3 * after[0],
              1e3 * after[1], 1e3 * after[2]);
  EXPECT_LT(after[0], 0.5 * before);
  EXPECT_LT(after[1], 0.5 * before);
  EXPECT_LE(after[2], 1.1 * std::min(after[0], after[1]));
  // The one-view entry point is the one-view case of the general one.
  const VecX a = fitShapeToDepth(guess.x, guess.triangles, guess.top, m1.depth, m1.mask, vga());
  const VecX b = fitShapeToDepthViews(guess.x, guess.triangles, guess.top, {v1});
  EXPECT_EQ((a - b).norm(), 0.0);
  // A view with a rotation that is not a rotation is refused.
  DepthView bad = v2;
  bad.rotation *= 2.0;
  EXPECT_THROW(fitShapeToDepthViews(guess.x, guess.triangles, guess.top, {bad}), RecognitionError);
  EXPECT_THROW(fitShapeToDepthViews(guess.x, guess.triangles, guess.top, {}), RecognitionError);
}
