// The picked-from-a-heap start: isometric folds (no edge longer than at rest), the held particle kept,
// the bundle below the hold, deterministic per seed; scene keys and their validation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/drape_scene.h"
#include "textile_handling/sim/heap_start.h"

using namespace textile_handling;

namespace {

ParticleGrid towelGrid(Real d) {
  std::string err;
  ParticleGrid g = ParticleGrid::rasterize(presetTextile("towel"), d, &err);
  EXPECT_FALSE(g.empty()) << err;
  return g;
}

Vec3 at(const VecX& x, Index i) { return x.segment<3>(3 * i); }

}  // namespace

TEST(HeapStart, FoldsKeepEdgesFromStretchingAndTheHeldParticleInPlace) {
  const Real d = 0.02;
  const ParticleGrid g = towelGrid(d);
  const Index hold = g.nearestActive(Vec2(0.32, 0.46));
  for (int folds : {1, 2, 3}) {
    HeapStart h;
    h.folds = folds;
    h.seed = 7;
    const VecX x = heapStartPositions(g, hold, h, d);
    ASSERT_EQ(x.size(), 3 * g.numActive());
    ASSERT_TRUE(x.allFinite());
    EXPECT_TRUE(at(x, hold).isApprox(Vec3(g.activePosition(hold).x(), g.activePosition(hold).y(), 0), 1e-12));
    // Structural edges stay within 2 % of their rest length (folds wrap along arcs; strain limiting
    // takes out what stacked creases stretch or squeeze).
    const ParticleTopology topo = ParticleTopology::fromGrid(g);
    Real longest = 0, shortest = 1e9;
    double moved = 0;
    for (Index i = 0; i < g.numActive(); ++i) {
      moved = std::max(moved, (at(x, i).head<2>() - g.activePosition(i)).norm());
    }
    for (Index i = 0; i < topo.size(); ++i)
      for (int k : {0, 1}) {  // right and up neighbours: every structural edge once
        const Index j = topo.neighbour[i][k];
        if (j < 0) continue;
        const Real len = (at(x, i) - at(x, j)).norm() / d;
        longest = std::max(longest, len);
        shortest = std::min(shortest, len);
      }
    EXPECT_LE(longest, 1.003) << folds << " folds";
    EXPECT_GT(shortest, 0.979) << folds << " folds";
    EXPECT_GT(moved, 0.05) << folds << " folds: nothing was folded";
    // Lifted: the bundle's centroid hangs below the held particle.
    Vec3 c = Vec3::Zero();
    for (Index i = 0; i < g.numActive(); ++i) c += at(x, i);
    c /= static_cast<Real>(g.numActive());
    EXPECT_LT(c.z(), at(x, hold).z() - 0.05);
  }
}

TEST(HeapStart, TheSameSeedGivesTheSameStartAndAnotherSeedAnother) {
  const ParticleGrid g = towelGrid(0.02);
  const Index hold = g.nearestActive(Vec2(0.0, 0.0));
  HeapStart a;
  a.folds = 2;
  a.seed = 3;
  HeapStart b = a;
  b.seed = 4;
  const VecX xa = heapStartPositions(g, hold, a, 0.02);
  EXPECT_EQ((xa - heapStartPositions(g, hold, a, 0.02)).norm(), 0.0);
  EXPECT_GT((xa - heapStartPositions(g, hold, b, 0.02)).cwiseAbs().maxCoeff(), 0.05);
}

TEST(HeapStart, BadSettingsNameTheField) {
  const ParticleGrid g = towelGrid(0.04);
  HeapStart h;
  h.folds = kMaxHeapFolds + 1;
  EXPECT_THROW(heapStartPositions(g, 0, h, 0.04), std::invalid_argument);
  h.folds = 1;
  h.lift_deg = 0;
  try {
    heapStartPositions(g, 0, h, 0.04);
    FAIL() << "lift_deg 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("heap_lift_deg"), std::string::npos) << e.what();
  }
  h.lift_deg = 75;
  EXPECT_THROW(heapStartPositions(g, g.numActive(), h, 0.04), std::invalid_argument);
  EXPECT_THROW(heapStartPositions(g, 0, h, std::nan("")), std::invalid_argument);
}

TEST(HeapStart, SceneKeysBuildAFoldedStartAndBadValuesAreRefused) {
  const std::string base = "textile: towel\nmaterial: cotton\nspacing_m: 0.04\nhold: {points: [corner_ll]}\n";
  const DrapeSceneSpec spec = parseDrapeSceneYaml(base + "start: {heap_folds: 2, heap_seed: 9, heap_lift_deg: 80}\n");
  EXPECT_EQ(spec.start_heap.folds, 2);
  EXPECT_EQ(spec.start_heap.seed, 9u);
  EXPECT_EQ(spec.start_heap.lift_deg, 80);
  const DrapeScene heap = buildDrapeScene(spec);
  const DrapeScene flat = buildDrapeScene(parseDrapeSceneYaml(base));
  // The held particle is where the flat start has it; the rest is not.
  EXPECT_TRUE(at(heap.x0, heap.hold_particle).isApprox(at(flat.x0, flat.hold_particle), 1e-12));
  EXPECT_GT((heap.x0 - flat.x0).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_TRUE(heap.pins.anchors.front().isApprox(at(flat.x0, flat.hold_particle), 1e-12));
  EXPECT_THROW(parseDrapeSceneYaml(base + "start: {heap_seed: -1}\n"), SceneError);
  EXPECT_THROW(parseDrapeSceneYaml(base + "start: {heap_fold: 2}\n"), SceneError);
  DrapeSceneSpec bad = spec;
  bad.start_heap.folds = 99;
  EXPECT_THROW(buildDrapeScene(bad), SceneError);
  bad = spec;
  bad.start_heap.lift_deg = 200;
  EXPECT_THROW(buildDrapeScene(bad), SceneError);
}
