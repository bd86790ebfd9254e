// The yarns of a woven fabric laid inside a textile outline: straight warp yarns along the textile's x
// axis and weft yarns along its y axis at the fabric's spacings, clipped to the outline, with free ends
// where they leave it (notes section 1.2, "cloth boundaries ... leave the yarn ends hanging free"), or
// sewn to a seam yarn along the outline edges the caller names ("seams: place one extra seam yarn along
// each seam"). The crossings are the yarn-level model's 5-DOF nodes, the ends its 3-DOF nodes.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"
#include "textile_handling/sim/woven_fabric.h"

namespace textile_handling {

/// Largest number of crossings a grid may have (about 1 GB of simulation state and Jacobian at 5 DOFs
/// per node): 16 times the 62 500 of the source's 25 x 25 cm sheet at 1 yarn/mm.
constexpr std::size_t kMaxYarnCrossings = 1000000;

struct YarnCrossing {
  Vec2 position = Vec2::Zero();  ///< flat position in the outline frame [m]
  std::size_t warp = 0;          ///< warp line index (counted over the outline's bounding box, from low y)
  std::size_t weft = 0;          ///< weft line index (from low x)
  bool warp_on_top = false;      ///< WeavePattern::warpOnTop(warp, weft)
};

/// One yarn piece: a straight run of one warp or weft line inside the outline (a line that leaves and
/// re-enters a concave outline gives several pieces). `nodes` in order of increasing arc length: node
/// k < crossings.size() is that crossing, node crossings.size() + e is end e. `arc_length_m[k]` is the
/// flat arc-length coordinate (u for a warp, v for a weft) of nodes[k], measured along the textile's x
/// (warp) or y (weft) axis from the outline frame's origin.
///
/// A seam piece (`seam`) is a seam yarn along outline edge `line`: its nodes are end nodes of warp and
/// weft pieces (shared with them), in order along the edge, and `arc_length_m[k]` is the distance of
/// nodes[k] from the edge's first vertex. Its arc length lives in the coordinate its node's own yarn
/// leaves unused, which `slide_offsets` names per node (a warp end's v, a weft end's u); `warp` is unused.
struct YarnPiece {
  bool warp = true;
  std::size_t line = 0;               ///< warp or weft line index; a seam's outline edge index
  std::vector<std::size_t> nodes;
  std::vector<Real> arc_length_m;
  bool seam = false;
  /// Seam pieces only, one per node: the node-local offset of the seam's arc length (3 = u, 4 = v).
  std::vector<int> slide_offsets;

  /// The node-local offset (3 = u, 4 = v) of this piece's arc-length coordinate at nodes[k].
  int slideOffset(std::size_t k) const { return seam ? slide_offsets[k] : (warp ? 3 : 4); }
};

struct YarnGrid {
  std::vector<YarnCrossing> crossings;
  std::vector<Vec2> ends;             ///< yarn ends on the outline [m] (free, or sewn to a seam)
  /// warp pieces first (by line, then along x), then weft pieces, then seams (in seam_edges order)
  std::vector<YarnPiece> pieces;
  Real warp_spacing_m = 0, weft_spacing_m = 0;
  std::size_t warp_lines = 0, weft_lines = 0;  ///< lines over the bounding box (some may miss the outline)

  std::size_t nodeCount() const { return crossings.size() + ends.size(); }
  bool isEnd(std::size_t node) const { return node >= crossings.size(); }
  /// Flat position of node k [m] (a crossing's or an end's).
  Vec2 nodePosition(std::size_t node) const {
    return isEnd(node) ? ends[node - crossings.size()] : crossings[node].position;
  }
};

/// Options of layYarnGrid().
struct YarnGridOptions {
  /// An end closer than this fraction of the spacing to its piece's last crossing is dropped: the yarn
  /// then ends at that crossing (a very short end segment would set the stiffest spring of the sheet
  /// and the stable time step).
  Real min_end_segment_fraction = 0.25;
  /// Sewn edges of the outline (edge i from vertex i to vertex (i + 1) mod n; each index at most once).
  /// A seam yarn runs along each through the ends of the yarns that end on it (docs/yarn_model.md,
  /// "Seams"); an edge with fewer than two such ends gets none. The other edges keep free ends.
  std::vector<std::size_t> seam_edges;
};

/// Lays `fabric`'s yarns inside the closed polygon `outline` [m] (a textile's full outline, e.g.
/// fullOutline()): warp line i at y = y_min + (i + 1/2) L_warp, weft line j at x = x_min + (j + 1/2)
/// L_weft over the polygon's bounding box (so no yarn runs along an axis-parallel edge). Every grid
/// point inside the polygon is a crossing; each line's runs inside the polygon (even-odd rule) are
/// pieces, with an end node where they meet the boundary; a run with no crossing is left out. Each
/// seam edge of `options` gets a seam piece through the end nodes on it, ordered along the edge (an end
/// less than min_end_segment_fraction of the smaller spacing along the edge from the previous sewn end
/// stays free). Throws SimError for an invalid polygon (validatePolygon()), an invalid fabric
/// (validateWovenFabric()), a seam edge index out of range or repeated (naming it), or a grid that
/// would have more than kMaxYarnCrossings crossings (checked from the bounding box before any
/// allocation), naming the sizes.
YarnGrid layYarnGrid(const std::vector<Vec2>& outline, const WovenFabric& fabric, const YarnGridOptions& options = {});

/// Counts of a grid's segments between neighbouring crossings of one piece: `interlaced` where the yarn
/// changes side between them (the weave flag differs), `floats` where it stays on the same side (notes
/// section 1.3). Plain weave has no floats.
struct WeaveSegmentCounts {
  std::size_t interlaced = 0, floats = 0;
};
WeaveSegmentCounts countWeaveSegments(const YarnGrid& grid);

}  // namespace textile_handling
