// Exports of stored simulations: the rest shape as a triangle mesh (PLY or OBJ) and the silhouettes as
// PNG images. The mesh connectivity is rebuilt from the stored textile and particle spacing (the
// rasterisation is deterministic); a mismatch with the stored particle count is reported.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/vision/silhouette_renderer.h"

namespace textile_handling {
namespace db {

/// A done simulation with its mesh.
struct StoredDrapeMesh {
  SimulationRecord record;
  TextileRecord textile;
  VecX positions;                           ///< 3 per particle [m], world frame
  std::vector<vision::Triangle> triangles;  ///< trianglesFromTopology of the particle grid
  Index held_particle = -1;
};

/// Loads a done simulation and rebuilds its mesh. Throws NotFoundError (unknown or unfinished row),
/// BlobFormatError (damaged positions or particle count not matching the textile's grid).
StoredDrapeMesh loadDrapeMesh(const HangingDrapeDatabase& db, std::int64_t simulation_id);

/// Writes an ASCII PLY (vertices x y z in metres, triangular faces). Throws std::runtime_error on I/O errors.
void writePly(const std::string& path, const VecX& positions, const std::vector<vision::Triangle>& triangles);
/// Writes a Wavefront OBJ (v / f lines, 1-based). Throws std::runtime_error on I/O errors.
void writeObj(const std::string& path, const VecX& positions, const std::vector<vision::Triangle>& triangles);

/// Writes every stored view of a simulation as DIR/sim<ID>_view<AAA>.png (AAA: whole degrees, three
/// digits; a fractional angle is written with three decimals, e.g. _view012.500.png), 255 = textile, at
/// the canonical resolution, plus DIR/sim<ID>_views.png, a contact sheet of all views scaled by
/// `sheet_scale`. Creates DIR. Returns the written paths. Throws NotFoundError for an unknown or
/// unfinished simulation, std::runtime_error on I/O errors.
std::vector<std::string> exportViewPngs(const HangingDrapeDatabase& db, std::int64_t simulation_id,
                                        const std::string& dir, int sheet_scale = 2);

}  // namespace db
}  // namespace textile_handling
