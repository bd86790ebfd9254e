// Helpers shared by the recognition gtest suites (and the drape_db process tests): the VGA camera and the
// small towel of the tests, a check that a call fails with a given RecognitionErrorCode, and damage to
// stored views as a flipped disk byte would do.
#pragma once

#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "../test_support.h"
#include "textile_handling/db/drape_database_builder.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/sqlite_wrapper.h"
#include "textile_handling/recognition/recognition_errors.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/vision/shaded_renderer.h"

namespace textile_handling {
namespace test_support {

/// 640 x 480, f = 525 px, principal point at the centre (the cell camera of the tests).
inline vision::PinholeIntrinsics vga() { return vision::PinholeIntrinsics{525.0, 525.0, 319.5, 239.5, 640, 480}; }

/// A 36 x 24 cm towel-shaped rectangle with its four corners and two edge midpoints as named points.
inline TextileOutline smallTowel() {
  TextileOutline t;
  t.name = "small_towel";
  t.outline = {Vec2(0, 0), Vec2(0.36, 0), Vec2(0.36, 0.24), Vec2(0, 0.24)};
  t.named_points = {{"corner_ll", "corner", Vec2(0, 0)},       {"corner_lr", "corner", Vec2(0.36, 0)},
                    {"corner_ur", "corner", Vec2(0.36, 0.24)}, {"corner_ul", "corner", Vec2(0, 0.24)},
                    {"bottom_mid", "grasp", Vec2(0.18, 0)},    {"left_mid", "grasp", Vec2(0, 0.12)}};
  return t;
}

/// The small towel's database build of the recognition tests: d = 3 cm, hold points 12 cm apart, 12
/// views of a 64 px frame 0.6 m wide (callers link the builder library).
inline db::DrapeBuildConfig smallTowelBuildConfig() {
  db::DrapeBuildConfig c;
  c.textile = smallTowel();
  c.spacing = 0.03;
  c.lattice_spacing = 0.12;
  c.frame = vision::CanonicalFrame::fromMetric(0.6, 0.6, 64);
  c.views.count = 12;
  c.views.step_deg = 30;
  c.workers = 2;
  return c;
}

// The camera of a test view: VGA, 1.5 m from the hold axis at azimuth `azimuth` (world), 25 cm below the
// hold point, looking at a point 20 cm below it (tilted up), rolled by 4 degrees.
inline vision::CameraPose testCamera(const Vec3& hold, double azimuth) {
  const Vec3 eye = hold - 1.5 * vision::viewDirection(azimuth) + Vec3(0, 0, -0.25);
  vision::CameraPose pose = vision::CameraPose::lookAt(eye, hold + Vec3(0, 0, -0.2));
  pose.rotation = pose.rotation * Eigen::AngleAxisd(4.0 * kPi / 180.0, Vec3::UnitZ()).toRotationMatrix();
  return pose;
}

/// A stored shape seen by testCamera at `azimuth`: a shaded VGA image with noise (and its rendered depth if
/// `depth`), the hold point and up direction in the camera frame.
inline recognition::CameraObservation renderedObservation(const db::StoredDrapeMesh& mesh, double azimuth,
                                                          bool depth = false) {
  const Vec3 hold = mesh.positions.segment<3>(3 * mesh.held_particle);
  vision::ShadedRenderOptions ro;
  ro.intrinsics = vga();
  ro.camera = testCamera(hold, azimuth);
  ro.noise_sigma = 3.0;
  ro.seed = 7;
  const vision::ShadedImage img = vision::renderShaded(mesh.positions, mesh.triangles, ro);
  recognition::CameraObservation ob;
  ob.image = img.bgr;
  if (depth) ob.depth = img.depth;
  ob.intrinsics = ro.intrinsics;
  ob.hold_camera = ro.camera.toCamera(hold);
  ob.up_camera = ro.camera.rotation.transpose() * Vec3::UnitZ();
  return ob;
}

/// True if `f` throws a RecognitionError with `code` (its message in *msg); false if it throws
/// anything else or nothing.
inline bool throwsCode(const std::function<void()>& f, recognition::RecognitionErrorCode code,
                       std::string* msg = nullptr) {
  try {
    f();
  } catch (const recognition::RecognitionError& e) {
    if (msg) *msg = e.what();
    return e.code() == code;
  } catch (...) {
    return false;
  }
  return false;
}

/// Damages stored views as a flipped disk byte would: one byte (at `offset`, modulo the blob size) of the
/// mask blob of each given view is inverted. Returns the number of views changed.
inline int flipStoredMaskBytes(const std::string& db_path, const std::vector<std::int64_t>& view_ids,
                               std::size_t offset = 40) {
  db::HangingDrapeDatabase database(db_path);
  int changed = 0;
  database.withConnection([&](db::SqlConnection& c) {
    for (std::int64_t id : view_ids) {
      db::SqlStatement q = c.prepare("SELECT mask FROM views WHERE id = ?1");
      q.bind(1, id);
      if (!q.step()) continue;
      std::vector<std::uint8_t> blob = q.getBlob(0);
      if (blob.empty()) continue;
      blob[offset % blob.size()] ^= 0xFF;
      db::SqlStatement u = c.prepare("UPDATE views SET mask = ?1 WHERE id = ?2");
      u.bindBlob(1, blob).bind(2, id);
      u.step();
      ++changed;
    }
  });
  return changed;
}

/// Ids of the stored views of a database, ascending.
inline std::vector<std::int64_t> storedViewIds(const std::string& db_path) {
  db::HangingDrapeDatabase database(db_path);
  std::vector<std::int64_t> ids;
  database.withConnection([&](db::SqlConnection& c) {
    db::SqlStatement q = c.prepare("SELECT id FROM views ORDER BY id");
    while (q.step()) ids.push_back(q.getInt(0));
  });
  return ids;
}

}  // namespace test_support
}  // namespace textile_handling
