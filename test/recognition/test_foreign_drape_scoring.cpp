// The foreign-drape benchmark's scoring (bench/include/textile_handling/bench/foreign_drapes.h): a
// result that reports the truth scores zero, under the towel's mirror labelling too, and a displaced
// corner is scored by its displacement. The figures of foreign_drape_bench rest on this.
#include <gtest/gtest.h>

#include "textile_handling/bench/foreign_drapes.h"
#include "textile_handling/db/textile_symmetry.h"
#include "textile_handling/recognition/grasp_poses.h"
#include "textile_handling/vision/silhouette_renderer.h"

using namespace textile_handling;

namespace {

// The towel as a flat vertical sheet hanging from (hold) in the plane y = 0 (textile y up-side down).
bench::ForeignDrape verticalTowel(const Vec2& hold) {
  bench::ForeignDrape d;
  d.variant = "test";
  d.mesh.textile.outline = presetTextile("towel");
  std::string error;
  d.grid = ParticleGrid::rasterize(d.mesh.textile.outline, 0.02, &error);
  const Index n = d.grid.numActive();
  d.mesh.positions.resize(3 * n);
  for (Index p = 0; p < n; ++p) {
    const Vec2 q = d.grid.activePosition(p);
    d.mesh.positions.segment<3>(3 * p) = Vec3(q.x() - hold.x(), 0.0, 1.0 - (hold.y() - q.y()) - 0.5);
  }
  d.mesh.held_particle = d.grid.nearestActive(hold);
  d.hold = d.grid.activePosition(d.mesh.held_particle);
  d.mesh.triangles = vision::trianglesFromTopology(ParticleTopology::fromGrid(d.grid));
  return d;
}

// A result reporting the truth under mirror `g` (the reported labelling is the truth's mirrored).
recognition::RecognitionResult truthResult(const bench::ForeignDrape& d, const vision::CameraPose& camera,
                                           db::MirrorKind g) {
  const db::TextileSymmetry sym = db::detectSymmetry(d.mesh.textile.outline, 1e-6);
  recognition::RecognitionResult r;
  r.hold_point = sym.apply(g, d.hold);
  for (const auto& np : d.mesh.textile.outline.named_points) {
    recognition::GraspPose p;
    p.name = np.name;
    p.kind = np.kind;
    p.textile_position = np.position;  // reported label q; the truth point is g(q)
    p.position_camera =
        camera.toCamera(recognition::sampleRestShape(d.grid, d.mesh.positions, sym.apply(g, np.position)).position);
    r.grasp_poses.push_back(p);
  }
  return r;
}

}  // namespace

TEST(ForeignDrapeScoring, TheTruthScoresZeroUnderEveryMirror) {
  const bench::ForeignDrape d = verticalTowel(Vec2(0.1, 0.46));
  const vision::CameraPose camera = vision::CameraPose::lookAt(Vec3(0, -1.5, 0.5), Vec3(0, 0, 0.5));
  for (db::MirrorKind g : {db::MirrorKind::kIdentity, db::MirrorKind::kMirrorX, db::MirrorKind::kMirrorY,
                           db::MirrorKind::kMirrorXY}) {
    const bench::ForeignScore s = bench::scoreRecognition(d, camera, truthResult(d, camera, g));
    EXPECT_TRUE(s.success);
    EXPECT_NEAR(s.hold_error_m, 0.0, 1e-12);
    ASSERT_EQ(s.corner_error_m.size(), 4u);
    for (double e : s.corner_error_m) EXPECT_NEAR(e, 0.0, 1e-9);
    EXPECT_NEAR(s.lowest_corner_error_m, 0.0, 1e-9);
  }
}

TEST(ForeignDrapeScoring, ADisplacedCornerAndHoldAreScoredByTheirDisplacement) {
  const bench::ForeignDrape d = verticalTowel(Vec2(0.1, 0.46));
  const vision::CameraPose camera = vision::CameraPose::lookAt(Vec3(0, -1.5, 0.5), Vec3(0, 0, 0.5));
  recognition::RecognitionResult r = truthResult(d, camera, db::MirrorKind::kIdentity);
  r.hold_point += Vec2(0.03, 0.0);
  // The lowest corner of a sheet held near the top left: a bottom corner, (x, 0) in the textile frame.
  double lowest_z = 1e9;
  std::size_t lowest = 0;
  for (std::size_t k = 0; k < r.grasp_poses.size(); ++k) {
    if (r.grasp_poses[k].kind != "corner") continue;
    const double z = recognition::sampleRestShape(d.grid, d.mesh.positions, r.grasp_poses[k].textile_position).position.z();
    if (z < lowest_z) {
      lowest_z = z;
      lowest = k;
    }
  }
  r.grasp_poses[lowest].position_camera += Vec3(0.0, 0.04, 0.0);
  const bench::ForeignScore s = bench::scoreRecognition(d, camera, r);
  EXPECT_NEAR(s.hold_error_m, 0.03, 1e-9);
  EXPECT_NEAR(s.lowest_corner_error_m, 0.04, 1e-9);
  EXPECT_NEAR(s.max_corner_error_m, 0.04, 1e-9);
  EXPECT_NEAR(s.best_corner_error_m, 0.0, 1e-9);
}
