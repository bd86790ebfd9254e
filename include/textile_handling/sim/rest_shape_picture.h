// PNG pictures of a simulated shape (two orthographic views, shaded cells, the model's yarns). OpenCV
// stays in the .cpp.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "textile_handling/sim/cloth_model.h"
#include "textile_handling/sim/cloth_topology.h"

namespace textile_handling {

/// Colours (RGB) of the yarns in the picture: warp blue, weft green, both far from the cells' warm
/// shades and from the red of the highlighted particles.
constexpr std::array<unsigned char, 3> kPictureWarpRgb{20, 90, 210};
constexpr std::array<unsigned char, 3> kPictureWeftRgb{10, 150, 40};

/// Yarn lines per direction in a picture of `view_px` pixels per view: one per 5 pixels (80 at 400 px).
constexpr int maxPictureYarnLines(int view_px) { return view_px / 5 > 1 ? view_px / 5 : 1; }

/// Writes a PNG with two orthographic views of the shape x (3 per node; front: looking along +y; side:
/// along -x), each `view_px` pixels square, cells shaded by their normal, `highlight` particles drawn as
/// dots (e.g. the held point). `yarns` (ClothModel::drawnYarns(), node indices into x; empty for none)
/// are drawn in both views as 1 px antialiased lines, warp in kPictureWarpRgb and weft in
/// kPictureWeftRgb; a yarn segment is hidden where a cell nearer than the cells around its nodes covers
/// it (a fold in front hides the yarns behind it). Of a direction with more than maxPictureYarnLines(view_px) lines only
/// every k-th line (line % k == 0) is drawn, k the smallest stride that leaves at most that many.
/// Returns false with a message on I/O errors, a non-finite shape or a yarn node outside it.
bool writeRestShapePicture(const std::string& path, const ParticleTopology& topology, const VecX& x,
                           const std::vector<Index>& highlight, const std::vector<DrawnYarn>& yarns, int view_px,
                           std::string* error);

}  // namespace textile_handling
