// Grasp poses from a rest shape: sampling the shape at named points, placement in the hold frame,
// orientation (normal towards the camera, outward edge direction), reflections.
#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

#include "textile_handling/recognition/grasp_poses.h"
#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/vision/shaded_renderer.h"
#include "textile_handling/vision/silhouette_renderer.h"

using namespace textile_handling;
using namespace textile_handling::recognition;

namespace {

TextileOutline sheet() {
  TextileOutline t;
  t.name = "sheet";
  t.outline = {Vec2(0, 0), Vec2(0.4, 0), Vec2(0.4, 0.3), Vec2(0, 0.3)};
  t.named_points = {{"corner_ll", "corner", Vec2(0, 0)},
                    {"corner_ur", "corner", Vec2(0.4, 0.3)},
                    {"bottom_mid", "grasp", Vec2(0.2, 0)},
                    {"inside", "grasp", Vec2(0.13, 0.17)}};
  return t;
}

// The flat sheet hanging in the vertical plane y = 0 from its top-left corner (0, 0.3) at (0, 0, 1):
// textile (u, v) -> world (u, 0, 1 + v - 0.3).
VecX hangingFlat(const ParticleGrid& g, Index* held) {
  VecX x(3 * g.numActive());
  for (Index k = 0; k < g.numActive(); ++k) {
    const Vec2 p = g.activePosition(k);
    x.segment<3>(3 * k) = Vec3(p.x(), 0.0, 1.0 + p.y() - 0.3);
  }
  *held = g.nearestActive(Vec2(0, 0.3));
  return x;
}

HoldGeometry cameraAt(double azimuth) {
  const Vec3 hold(0, 0, 1);
  const vision::CameraPose pose = vision::cameraPoseForView(hold, azimuth, 1.5);
  return computeHoldGeometry(vision::PinholeIntrinsics{}, pose.toCamera(hold), pose.rotation.transpose() * Vec3::UnitZ(),
                             pose.rotation.transpose() * Vec3::UnitX());
}

}  // namespace

TEST(GraspPoses, SamplesAnAffineShapeExactly) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(sheet(), 0.05, &err);
  ASSERT_FALSE(g.empty()) << err;
  Eigen::Matrix<double, 3, 2> a;
  a << 0.8, 0.1, -0.2, 0.5, 0.3, 0.9;
  const Vec3 b(0.1, -0.4, 1.2);
  VecX x(3 * g.numActive());
  for (Index k = 0; k < g.numActive(); ++k) x.segment<3>(3 * k) = a * g.activePosition(k) + b;
  for (const Vec2& p : {Vec2(0.13, 0.17), Vec2(0.0, 0.0), Vec2(0.4, 0.3), Vec2(0.4, 0.11), Vec2(0.21, 0.0)}) {
    const RestShapeSample s = sampleRestShape(g, x, p);
    EXPECT_TRUE(s.interpolated);
    EXPECT_LT((s.position - (a * p + b)).norm(), 1e-12);
    EXPECT_LT((s.du - a.col(0)).norm(), 1e-12);
    EXPECT_LT((s.dv - a.col(1)).norm(), 1e-12);
  }
  EXPECT_THROW(sampleRestShape(g, VecX::Zero(6), Vec2(0, 0)), RecognitionError);
  EXPECT_THROW(sampleRestShape(g, x, Vec2(std::nan(""), 0)), RecognitionError);
}

TEST(GraspPoses, FlatHangingSheet) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(sheet(), 0.02, &err);
  Index held = -1;
  const VecX x = hangingFlat(g, &held);
  for (double az : {0.0, 180.0}) {  // the camera in front of / behind the sheet
    const HoldGeometry geo = cameraAt(az);
    const std::vector<GraspPose> poses = computeGraspPoses(sheet(), g, x, held, 0.0, geo);
    ASSERT_EQ(poses.size(), 4u);
    const Vec3 towards_camera = az == 0.0 ? Vec3(0, -1, 0) : Vec3(0, 1, 0);
    for (const GraspPose& p : poses) {
      EXPECT_LT((p.rotation.transpose() * p.rotation - Mat3::Identity()).norm(), 1e-9);
      EXPECT_NEAR(p.rotation.determinant(), 1.0, 1e-9);
      EXPECT_LT((p.normal() - towards_camera).norm(), 1e-9) << p.name;
      EXPECT_LT((p.position_camera - geo.holdToCamera(p.position)).norm(), 1e-12);
      EXPECT_LT((p.rotation_camera - geo.rotation_camera_hold * p.rotation).norm(), 1e-12);
    }
    // Positions relative to the hold point; outward directions mapped onto the sheet (u -> x, v -> z).
    EXPECT_LT((poses[0].position - Vec3(0, 0, -0.3)).norm(), 1e-9);
    EXPECT_TRUE(poses[0].on_outline_vertex);
    EXPECT_LT((poses[0].rotation.col(0) - Vec3(-1, 0, -1).normalized()).norm(), 1e-9);  // corner bisector
    EXPECT_LT((poses[0].edge_direction - Vec3(1, 0, 0)).norm(), 1e-9);  // counter-clockwise edge leaving it
    EXPECT_LT((poses[1].position - Vec3(0.4, 0, 0)).norm(), 1e-9);
    EXPECT_LT((poses[1].rotation.col(0) - Vec3(1, 0, 1).normalized()).norm(), 1e-9);
    EXPECT_TRUE(poses[2].on_outline_edge);
    EXPECT_LT((poses[2].position - Vec3(0.2, 0, -0.3)).norm(), 1e-9);
    EXPECT_LT((poses[2].rotation.col(0) - Vec3(0, 0, -1)).norm(), 1e-9);  // the bottom edge's outward normal
    EXPECT_FALSE(poses[3].on_outline_vertex || poses[3].on_outline_edge);
    EXPECT_LT((poses[3].position - Vec3(0.13, 0, 0.17 - 0.3)).norm(), 1e-9);
    EXPECT_LT((poses[3].rotation.col(0) - Vec3(1, 0, 0)).norm(), 1e-9);  // warp direction inside
  }
  // The textile-front convention keeps du x dv (= -y for this sheet) whatever the camera.
  GraspPoseOptions front;
  front.normal = NormalConvention::kTextileFront;
  for (double az : {0.0, 180.0})
    for (const GraspPose& p : computeGraspPoses(sheet(), g, x, held, 0.0, cameraAt(az), front))
      EXPECT_LT((p.normal() - Vec3(0, -1, 0)).norm(), 1e-9);
}

TEST(GraspPoses, RotationAboutTheHoldAxis) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(sheet(), 0.02, &err);
  Index held = -1;
  const VecX x = hangingFlat(g, &held);
  const HoldGeometry geo = cameraAt(0.0);
  const auto p0 = computeGraspPoses(sheet(), g, x, held, 0.0, geo);
  const auto p1 = computeGraspPoses(sheet(), g, x, held, 90.0, geo);
  for (std::size_t k = 0; k < p0.size(); ++k) {
    EXPECT_LT((p1[k].position - rotationZ(90.0) * p0[k].position).norm(), 1e-9);
    EXPECT_LT((p1[k].rotation.col(0) - rotationZ(90.0) * p0[k].rotation.col(0)).norm(), 1e-9);
  }
  const VecX placed = placeInHoldFrame(x, held, 30.0);
  EXPECT_LT(placed.segment<3>(3 * held).norm(), 1e-12);
  EXPECT_THROW(placeInHoldFrame(x, -1, 0.0), RecognitionError);
  EXPECT_THROW(computeGraspPoses(sheet(), g, VecX::Zero(9), held, 0.0, geo), RecognitionError);
  // The codes say what is wrong: the shape (geometry) or the options.
  try {
    placeInHoldFrame(x, -1, 0.0);
  } catch (const RecognitionError& e) {
    EXPECT_EQ(e.code(), RecognitionErrorCode::kInvalidGeometry) << e.what();
  }
  GraspPoseOptions bad;
  bad.boundary_tolerance_m = -1;
  try {
    computeGraspPoses(sheet(), g, x, held, 0.0, geo, bad);
    ADD_FAILURE() << "a negative boundary tolerance was accepted";
  } catch (const RecognitionError& e) {
    EXPECT_EQ(e.code(), RecognitionErrorCode::kInvalidOptions) << e.what();
    EXPECT_NE(std::string(e.what()).find("boundary_tolerance_m"), std::string::npos) << e.what();
  }
}

TEST(GraspPoses, OutlineVerticesOnRequest) {
  TextileOutline t = sheet();
  t.named_points = {{"corner_ll", "corner", Vec2(0, 0)}};
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(t, 0.05, &err);
  Index held = -1;
  const VecX x = hangingFlat(g, &held);
  GraspPoseOptions o;
  o.include_outline_vertices = true;
  const auto poses = computeGraspPoses(t, g, x, held, 0.0, cameraAt(0.0), o);
  ASSERT_EQ(poses.size(), 4u);  // the named corner and the three unnamed vertices
  EXPECT_EQ(poses[0].name, "corner_ll");
  for (std::size_t k = 1; k < poses.size(); ++k) {
    EXPECT_EQ(poses[k].name.rfind("vertex_", 0), 0u);
    EXPECT_EQ(poses[k].kind, "corner");
    EXPECT_TRUE(poses[k].on_outline_vertex);
  }
}

// The reflection across the plane perpendicular to a view keeps that view's silhouette, moves points
// through the plane, and keeps the labels.
TEST(GraspPoses, ReflectionAcrossTheView) {
  std::string err;
  const ParticleGrid g = ParticleGrid::rasterize(sheet(), 0.02, &err);
  Index held = -1;
  VecX x = hangingFlat(g, &held);
  for (Index k = 0; k < g.numActive(); ++k) x[3 * k + 1] = 0.1 * std::sin(7 * x[3 * k]) * (1.0 - x[3 * k + 2]);  // folds
  const auto tris = vision::trianglesFromTopology(ParticleTopology::fromGrid(g));
  for (double view : {0.0, 35.0, 250.0}) {
    const VecX r = reflectAcrossView(x, held, view);
    EXPECT_EQ(vision::renderSilhouette(r, tris, held, view), vision::renderSilhouette(x, tris, held, view));
    EXPECT_NE(vision::renderSilhouette(r, tris, held, view + 60.0), vision::renderSilhouette(x, tris, held, view + 60.0));
    const Vec3 d = vision::viewDirection(view), h = x.segment<3>(3 * held);
    for (Index k = 0; k < g.numActive(); k += 7) {
      const Vec3 a = x.segment<3>(3 * k) - h, b = r.segment<3>(3 * k) - h;
      EXPECT_NEAR(a.dot(d), -b.dot(d), 1e-12);
      EXPECT_LT(((a - a.dot(d) * d) - (b - b.dot(d) * d)).norm(), 1e-12);
    }
  }
}
