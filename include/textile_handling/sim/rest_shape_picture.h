// PNG pictures of a simulated shape (two orthographic views, shaded cells). OpenCV stays in the .cpp.
#pragma once

#include <string>
#include <vector>

#include "textile_handling/sim/cloth_topology.h"

namespace textile_handling {

/// Writes a PNG with two orthographic views of the shape x (front: looking along +y; side: along -x),
/// each `view_px` pixels square, cells shaded by their normal, `highlight` particles drawn as dots
/// (e.g. the held point). Returns false with a message on I/O errors.
bool writeRestShapePicture(const std::string& path, const ParticleTopology& topology, const VecX& x,
                           const std::vector<Index>& highlight, int view_px, std::string* error);

}  // namespace textile_handling
