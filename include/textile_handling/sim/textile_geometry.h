// Flat textile outlines, their validation, and rasterisation onto a square
// particle grid.
//
// All lengths are in metres, areas in m^2. Outlines lie in the 2-D plane of the
// flat (spread) textile; x is the width direction and y the height direction.
// This module is ROS-free and OpenCV-free; it only needs Eigen (via types.h).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "textile_handling/sim/types.h"

namespace textile_handling {

/// A simple polygon given by its vertices in order (either orientation); the
/// closing edge from the last vertex back to the first is implicit.
struct Polygon2 {
  std::vector<Vec2> vertices;  ///< [m]
};

/// Signed shoelace area [m^2] of a closed vertex loop; positive when the
/// vertices run counter-clockwise. Returns 0 for fewer than 3 vertices.
Real polygonSignedArea(const std::vector<Vec2>& vertices);

/// Euclidean distance [m] from point p to the closed segment a-b (all in m).
Real pointSegmentDistance(const Vec2& p, const Vec2& a, const Vec2& b);

/// True when p [m] lies inside the polygon or within boundary_tolerance [m] of
/// its boundary. Uses the even-odd rule, so the polygon should be simple.
bool pointInPolygon(const std::vector<Vec2>& polygon, const Vec2& p, Real boundary_tolerance);

/// Size limits of textile outlines (docs/simulation.md, "Limits"). They bound the work of validation
/// and rasterisation and are checked before anything else (before any allocation or O(n log n) work).
/// A textile outline as given (the half outline of a mirrored textile) has at most this many vertices.
constexpr std::size_t kMaxOutlineVertices = 4096;
/// A polygon given to validatePolygon(): the full outline of a mirrored maximal textile (2n - 2).
constexpr std::size_t kMaxPolygonVertices = 2 * kMaxOutlineVertices - 2;
/// Named points per textile.
constexpr std::size_t kMaxNamedPoints = 256;
/// Longest textile or named-point name (characters).
constexpr std::size_t kMaxTextileNameLength = 64;

/// The name rule of textiles and named points: 1..64 characters, each a letter, a digit, '_', '-' or
/// '.' (safe as a file name, in SQL text, in YAML and in ROS messages). Returns true if `name`
/// follows it; otherwise false and, if `error` is non-null, a reason quoting (the start of) the name.
/// `error` is cleared on success.
bool validateTextileName(const std::string& name, std::string* error);

/// Checks that `vertices` [m] describe a usable simple polygon. Rejects, in this
/// order: more than kMaxPolygonVertices vertices, fewer than 3 vertices,
/// non-finite coordinates, coincident consecutive vertices (also last/first),
/// all vertices collinear, adjacent edges that double back onto each other, two
/// non-adjacent edges that cross or touch (collinear overlaps included; a sweep
/// over the edges' bounding boxes, O(n log n) for outlines whose edges are
/// short against the outline, O(n^2) at worst), and |area| < 1e-12 m^2.
/// Returns true if valid; otherwise false and, if `error` is non-null, a
/// human-readable reason such as "polygon edge 1-2 crosses edge 3-4" (edges are
/// named by their vertex indices). `error` is cleared on success.
/// For a Polygon2 p, call validatePolygon(p.vertices, error).
bool validatePolygon(const std::vector<Vec2>& vertices, std::string* error);

/// The first pair (lowest i, then lowest k > i) of non-adjacent edges of the closed loop `vertices`
/// that cross or come within 1e-12 m of each other; edge i runs from vertex i to vertex (i+1) mod n.
/// Returns false if there is none. Vertices must be finite. Sweep over the edges' bounding boxes
/// sorted by x (what validatePolygon() uses).
bool findEdgeCrossing(const std::vector<Vec2>& vertices, std::size_t* first, std::size_t* second);
/// The same answer by testing every pair, O(n^2): the reference for tests of findEdgeCrossing().
bool findEdgeCrossingBruteForce(const std::vector<Vec2>& vertices, std::size_t* first, std::size_t* second);

/// A labelled point on a textile, e.g. a corner or a grasp point.
struct NamedPoint {
  std::string name;
  std::string kind;                   ///< "corner" or "grasp"
  Vec2 position = Vec2::Zero();       ///< [m], in the outline frame
};

/// Outline of a flat textile.
///
/// If `mirrored` is true, `outline` is only half of the textile, lying on the
/// side x >= mirror_x, and the full shape is the union with its reflection
/// about the vertical line x = mirror_x. The half outline must then start and
/// end on the mirror axis (its first and last vertices, within 1e-9 m) and have
/// all other vertices strictly on the side x > mirror_x; the implicit closing
/// edge of the half outline runs along the axis and disappears in the full
/// shape. `named_points` are always given in full-shape coordinates.
struct TextileOutline {
  std::string name;
  std::vector<Vec2> outline;          ///< [m]
  bool mirrored = false;
  Real mirror_x = 0;                  ///< [m], only used when mirrored
  std::vector<NamedPoint> named_points;
};

/// Non-throwing form of fullOutline(): writes the full polygon [m] to `*full`
/// and returns true, or returns false with a reason in `*error` (if non-null).
/// An outline with more than kMaxOutlineVertices vertices is refused first.
/// For mirrored outlines the result is half[0..n-1] followed by the reflections
/// of half[n-2] .. half[1], so it has 2n-2 vertices and the same orientation
/// as the half outline. The result is validated with validatePolygon().
bool buildFullOutline(const TextileOutline& textile, std::vector<Vec2>* full, std::string* error);

/// Full outline polygon [m] of a textile (see buildFullOutline()).
/// Throws std::invalid_argument with a clear message if the outline is invalid.
std::vector<Vec2> fullOutline(const TextileOutline& textile);

/// Validates the outline (as buildFullOutline()) and additionally checks, in
/// this order: at most kMaxOutlineVertices outline vertices and kMaxNamedPoints
/// named points (first, before any other work), the textile name by
/// validateTextileName() unless it is empty, the outline, then for each named
/// point its name (validateTextileName()), that no name repeats, that its kind
/// is "corner" or "grasp", and that it lies inside or on the full outline
/// (tolerance 1e-9 m). Returns false with a reason in `*error` otherwise.
bool validateTextileOutline(const TextileOutline& textile, std::string* error);

/// Square grid of particle nodes covering a textile outline.
///
/// Node (i, j) sits at origin() + (j*d, i*d) [m], where i is the row (y
/// direction) and j the column (x direction); its row-major index is
/// i*cols() + j. A node is active when it lies inside the full outline or
/// within 1e-9*d of its boundary. Active nodes are numbered compactly
/// 0..numActive()-1 in row-major order.
class ParticleGrid {
 public:
  /// An empty grid (0 x 0, no active nodes); rasterize() returns this on error.
  ParticleGrid() = default;

  /// Rasterises `textile` with node spacing `spacing` [m].
  ///
  /// Grid layout: rows = floor(H/d + 1e-9) + 1 and cols = floor(W/d + 1e-9) + 1
  /// for a bounding box of width W and height H, so every lattice node inside
  /// the box is present. The bottom row lies on the bounding-box minimum y.
  /// Unmirrored: the bounding-box minimum corner is node (0, 0). Mirrored: the
  /// columns are centred on mirror_x instead (a node column on the axis when
  /// cols is odd, the axis midway between two columns when even), and the
  /// activity of the x >= mirror_x half is copied to the other half, so the
  /// active set is exactly mirror-symmetric: active(i, j) == active(i, cols-1-j).
  ///
  /// Each row is tested against only the outline edges that cross or touch it (same arithmetic as
  /// pointInPolygon(), so the same answers), O(rows * n + nodes * k) for an n-gon.
  ///
  /// On failure returns an empty grid and, if `error` is non-null, sets a reason:
  /// spacing not finite or <= 0, invalid outline, grid too large (> 1e8 nodes),
  /// or fewer than 4 active particles. `error` is cleared on success.
  static ParticleGrid rasterize(const TextileOutline& textile, Real spacing, std::string* error);

  /// True if this grid has no nodes (default-constructed or failed rasterize()).
  bool empty() const { return rows_ == 0 || cols_ == 0; }
  Index rows() const { return rows_; }
  Index cols() const { return cols_; }
  /// Node spacing d [m].
  Real spacing() const { return spacing_; }
  /// Position [m] of node (0, 0).
  const Vec2& origin() const { return origin_; }
  /// Full outline polygon [m] that was rasterised.
  const std::vector<Vec2>& polygon() const { return polygon_; }

  /// Whether node (i, j) is active; false for (i, j) outside the grid.
  bool active(Index i, Index j) const { return activeIndex(i, j) >= 0; }
  /// Number of active nodes.
  Index numActive() const { return static_cast<Index>(compact_row_.size()); }
  /// Compact index 0..numActive()-1 of node (i, j), or -1 if inactive or
  /// outside the grid.
  Index activeIndex(Index i, Index j) const;
  /// Position [m] of node (i, j) (any i, j, active or not).
  Vec2 node(Index i, Index j) const {
    return origin_ + Vec2(static_cast<Real>(j) * spacing_, static_cast<Real>(i) * spacing_);
  }

  /// Inverse maps: row / column of each compact index (size numActive()).
  const std::vector<Index>& compactRows() const { return compact_row_; }
  const std::vector<Index>& compactCols() const { return compact_col_; }
  /// Position [m] of active node `compact` (must be in 0..numActive()-1).
  Vec2 activePosition(Index compact) const {
    return node(compact_row_[static_cast<std::size_t>(compact)], compact_col_[static_cast<std::size_t>(compact)]);
  }
  /// Positions [m] of all active nodes, indexed by compact index.
  std::vector<Vec2> activePositions2D() const;

  /// Compact index of the active node nearest to p [m] (ties: lowest index),
  /// or -1 if the grid has no active node. Brute force, O(numActive()).
  Index nearestActive(const Vec2& p) const;

  /// Direction codes for neighbour().
  enum Direction : int { kRight = 0, kUp = 1, kLeft = 2, kDown = 3 };
  /// 4-connected neighbour of active node `compact`: dir 0 = right (+x, +j),
  /// 1 = up (+y, +i), 2 = left, 3 = down. Returns its compact index, or -1 if
  /// it is outside the grid or inactive, or if `compact` or `dir` is invalid.
  Index neighbour(Index compact, int dir) const;

 private:
  Index rows_ = 0;
  Index cols_ = 0;
  Real spacing_ = 0;
  Vec2 origin_ = Vec2::Zero();
  std::vector<Vec2> polygon_;
  std::vector<Index> compact_of_node_;  // row-major, -1 for inactive nodes
  std::vector<Index> compact_row_;
  std::vector<Index> compact_col_;
};

/// Candidate hold (grasp) points [m] for a textile with lattice spacing s [m].
///
/// Points, in priority order (a later point is dropped if it lies within
/// 0.25*s of an earlier kept one):
///  1. every vertex of the full outline;
///  2. square lattice points inside or on the outline (tolerance 1e-9*s). The
///     lattice lines are lo + k*s from the bounding-box minimum corner. If the
///     box size is not a multiple of s, the far edge gets one extra line when
///     the remainder exceeds 0.25*s; otherwise the last line is moved onto the
///     far edge (so that spacing grows to at most 1.25*s). Exactly-fitting sizes
///     end with a line on the far edge, up to rounding;
///  3. boundary samples every s along each edge, starting from its
///     lexicographically smaller (x, then y) endpoint, which makes samples on
///     axis-aligned edges coincide with lattice lines.
/// The result is sorted by y then x (coordinates quantised to 1e-6*s so that
/// rounding noise does not break rows). For a rectangle all boundary samples
/// coincide with lattice points, so the count is (#x lines) * (#y lines).
/// Throws std::invalid_argument if s is not finite or <= 0, the outline is
/// invalid, or the lattice would exceed 1e7 points.
std::vector<Vec2> holdPointLattice(const TextileOutline& textile, Real lattice_spacing);

/// Built-in textile outline by name (see presetTextileNames()):
///  - "towel": 0.64 x 0.46 m rectangle with min corner at (0, 0); corners
///    corner_ll/lr/ul/ur and grasp points short_side_left_mid,
///    short_side_right_mid, long_side_bottom_mid, long_side_top_mid;
///  - "square": 0.30 x 0.30 m, corners + "centre";
///  - "tablecloth": 1.00 x 1.00 m, corners + "centre";
///  - "tshirt": mirrored half outline about x = 0 (body 0.50 m wide, 0.70 m
///    long, sleeves ~0.20 m, neck opening 0.18 m wide and 0.08 m deep), hem at
///    y = 0; corners hem_corner_left/right, grasp points sleeve_end_left/right
///    (cuff middles), shoulder_left/right and collar (front neck middle).
/// Throws std::invalid_argument listing the known names for an unknown name.
TextileOutline presetTextile(const std::string& name);

/// Names accepted by presetTextile(), in a fixed order.
std::vector<std::string> presetTextileNames();

}  // namespace textile_handling
