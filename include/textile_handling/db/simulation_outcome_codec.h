// One simulation's outcome as a single byte message, for handing results from the process that simulated
// them to the process that stores them (the build farm's worker ranks send these to the storing rank).
// Layout, little-endian (docs/database.md, "Blobs"):
//
//   "THSO" | u16 version=1 | u16 reserved=0 | i64 simulation_id | u8 rest_reached
//   | f64 sim_time_s, wall_time_s, render_time_s, hanging_depth_m | i64 steps, rejected_steps
//   | i32 held_particle | str projection | i32 width_px, height_px | f64 metres_per_pixel, top_margin_px
//   | i32 supersample | f64 coverage_threshold | bytes positions (a positions blob, or empty on failure)
//   | u32 view count | per view: f64 angle_deg, bytes mask (a mask blob) | str failure | u32 crc32
//
// str and bytes are a u32 length and that many bytes. The CRC-32 covers every byte before it, and the
// embedded positions and mask blobs carry their own (blob_codec.h), so a truncated or corrupted message is
// reported, never read as garbage.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace db {

constexpr std::uint16_t kSimulationOutcomeVersion = 1;

/// A simulation's result, or why it failed (then `result` holds only its simulation id).
struct SimulationOutcome {
  SimulationResult result;
  std::string failure;  ///< empty: the simulation succeeded
};

/// Encodes an outcome. Throws InvalidInputError for what the store would refuse as well: non-finite
/// positions, a size that is not a multiple of 3, an empty mask or one larger than kMaxMaskSide, and a
/// succeeded outcome without positions.
std::vector<std::uint8_t> encodeSimulationOutcome(const SimulationOutcome& outcome);

/// Decodes a message; `what` names its sender in error messages. Throws BlobFormatError for a wrong tag or
/// version, a truncated or oversized message, a CRC mismatch or a damaged embedded blob.
SimulationOutcome decodeSimulationOutcome(const std::uint8_t* data, std::size_t size, const std::string& what);

}  // namespace db
}  // namespace textile_handling
