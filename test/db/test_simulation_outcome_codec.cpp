// Simulation outcomes as byte messages (db/simulation_outcome_codec.h): exact round trips of a result and
// of a failure; every truncation and every flipped byte reported as BlobFormatError, never decoded.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "textile_handling/db/simulation_outcome_codec.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

SimulationOutcome sampleOutcome() {
  SimulationOutcome o;
  SimulationResult& r = o.result;
  r.simulation_id = 4242;
  r.positions = VecX(9);
  r.positions << 0.1, -0.2, 1.0 / 3.0, 1e-300, -0.0, 2.5, 0.64, 0.46, -1.25;
  r.rest_reached = true;
  r.sim_time_s = 3.125;
  r.wall_time_s = 0.1 + 0.2;
  r.render_time_s = 1e-3;
  r.hanging_depth_m = 0.59;
  r.steps = 123456789012;
  r.rejected_steps = 7;
  r.held_particle = 2;
  r.projection = "pinhole";
  r.frame.width_px = 70;
  r.frame.height_px = 3;
  r.frame.metres_per_pixel = 0.01;
  r.frame.top_margin_px = 2.5;
  r.frame.supersample = 3;
  r.frame.coverage_threshold = 0.3;
  for (double angle : {0.0, 22.5}) {
    ViewInput v;
    v.view_angle_deg = angle;
    v.mask = vision::BitMask(70, 3);
    v.mask.set(0, 0);
    v.mask.set(69, 2);  // a bit in the second word of a row
    v.mask.set(static_cast<int>(angle), 1);
    r.views.push_back(v);
  }
  return o;
}

void expectSame(const SimulationOutcome& a, const SimulationOutcome& b) {
  const SimulationResult &x = a.result, &y = b.result;
  EXPECT_EQ(x.simulation_id, y.simulation_id);
  ASSERT_EQ(x.positions.size(), y.positions.size());
  for (Eigen::Index k = 0; k < x.positions.size(); ++k) {
    EXPECT_EQ(x.positions[k], y.positions[k]) << k;
    EXPECT_EQ(std::signbit(x.positions[k]), std::signbit(y.positions[k])) << k;
  }
  EXPECT_EQ(x.rest_reached, y.rest_reached);
  EXPECT_EQ(x.sim_time_s, y.sim_time_s);
  EXPECT_EQ(x.wall_time_s, y.wall_time_s);
  EXPECT_EQ(x.render_time_s, y.render_time_s);
  EXPECT_EQ(x.hanging_depth_m, y.hanging_depth_m);
  EXPECT_EQ(x.steps, y.steps);
  EXPECT_EQ(x.rejected_steps, y.rejected_steps);
  EXPECT_EQ(x.held_particle, y.held_particle);
  EXPECT_EQ(x.projection, y.projection);
  EXPECT_EQ(x.frame.width_px, y.frame.width_px);
  EXPECT_EQ(x.frame.height_px, y.frame.height_px);
  EXPECT_EQ(x.frame.metres_per_pixel, y.frame.metres_per_pixel);
  EXPECT_EQ(x.frame.top_margin_px, y.frame.top_margin_px);
  EXPECT_EQ(x.frame.supersample, y.frame.supersample);
  EXPECT_EQ(x.frame.coverage_threshold, y.frame.coverage_threshold);
  ASSERT_EQ(x.views.size(), y.views.size());
  for (std::size_t v = 0; v < x.views.size(); ++v) {
    EXPECT_EQ(x.views[v].view_angle_deg, y.views[v].view_angle_deg);
    ASSERT_TRUE(x.views[v].mask.sameSize(y.views[v].mask));
    for (int row = 0; row < x.views[v].mask.height(); ++row)
      for (int col = 0; col < x.views[v].mask.width(); ++col)
        EXPECT_EQ(x.views[v].mask.get(col, row), y.views[v].mask.get(col, row)) << v << " " << col << "," << row;
  }
  EXPECT_EQ(a.failure, b.failure);
}

}  // namespace

TEST(SimulationOutcomeCodec, AResultRoundTripsBitForBit) {
  const SimulationOutcome o = sampleOutcome();
  const std::vector<std::uint8_t> bytes = encodeSimulationOutcome(o);
  expectSame(o, decodeSimulationOutcome(bytes.data(), bytes.size(), "rank 2"));
}

TEST(SimulationOutcomeCodec, AFailureRoundTripsWithoutPositions) {
  SimulationOutcome o;
  o.result.simulation_id = 17;
  o.failure = "no rest within max_time 20 s; retry with dt_max 0.01 s: diverged (energy 1e12 J)";
  const std::vector<std::uint8_t> bytes = encodeSimulationOutcome(o);
  const SimulationOutcome back = decodeSimulationOutcome(bytes.data(), bytes.size(), "rank 1");
  expectSame(o, back);
  EXPECT_EQ(back.result.positions.size(), 0);
}

TEST(SimulationOutcomeCodec, EveryTruncationAndFlippedByteIsReported) {
  const std::vector<std::uint8_t> good = encodeSimulationOutcome(sampleOutcome());
  for (std::size_t n = 0; n < good.size(); ++n)
    EXPECT_THROW(decodeSimulationOutcome(good.data(), n, "rank 3"), BlobFormatError) << "truncated to " << n;
  for (std::size_t k = 0; k < good.size(); ++k) {
    std::vector<std::uint8_t> bad = good;
    bad[k] ^= 0x10;
    EXPECT_THROW(decodeSimulationOutcome(bad.data(), bad.size(), "rank 3"), BlobFormatError) << "byte " << k;
  }
  std::vector<std::uint8_t> longer = good;
  longer.push_back(0);
  EXPECT_THROW(decodeSimulationOutcome(longer.data(), longer.size(), "rank 3"), BlobFormatError);
  EXPECT_THROW(decodeSimulationOutcome(nullptr, 40, "rank 3"), BlobFormatError);
  try {
    decodeSimulationOutcome(good.data(), good.size() / 2, "rank 3");
    ADD_FAILURE() << "half a message decoded";
  } catch (const BlobFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("rank 3"), std::string::npos) << e.what();
  }
}

TEST(SimulationOutcomeCodec, WhatTheStoreWouldRefuseIsRefusedAtTheSender) {
  SimulationOutcome o = sampleOutcome();
  o.result.positions[4] = std::nan("");
  EXPECT_THROW(encodeSimulationOutcome(o), InvalidInputError);
  o = sampleOutcome();
  o.result.positions = VecX(4);
  o.result.positions.setZero();
  EXPECT_THROW(encodeSimulationOutcome(o), InvalidInputError);
  o = sampleOutcome();
  o.result.positions = VecX();
  EXPECT_THROW(encodeSimulationOutcome(o), InvalidInputError);  // succeeded without positions
  o = sampleOutcome();
  o.result.views[1].mask = vision::BitMask();
  EXPECT_THROW(encodeSimulationOutcome(o), InvalidInputError);
}
