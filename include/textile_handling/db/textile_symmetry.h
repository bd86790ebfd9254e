// Mirror symmetry of flat textiles and the hold points a database build simulates.
//
// A textile outline is mirror-symmetric about the vertical line x = cx ("mirror x": x -> 2cx - x) and/or
// the horizontal line y = cy ("mirror y"), with (cx, cy) the bounding-box centre. The particle model is
// orthotropic with warp along x and weft along y, so both mirrors map the material onto itself: a
// textile held at a mirrored hold point hangs in the mirrored shape. The builder therefore simulates
// only the hold points of the fundamental domain (the quadrant x <= cx, y <= cy for a rectangle; the
// half x <= cx for a shirt) and derives the others by mirroring the final particle positions.
//
// Mirrors in the world: the initial flat sheet maps textile (u, v) to world (u, v, 0) + shift, so a
// textile mirror is the world reflection of the same axis through the hold point (x -> 2hx - x,
// y -> 2hy - y, or both = a half turn about the vertical hold axis).
#pragma once

#include <string>
#include <vector>

#include "textile_handling/sim/textile_geometry.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {
namespace db {

/// One element of the symmetry group: identity, mirror x, mirror y, both (a half turn).
enum class MirrorKind : int { kIdentity = 0, kMirrorX = 1, kMirrorY = 2, kMirrorXY = 3 };
/// "identity", "mirror_x", "mirror_y", "mirror_xy".
std::string toString(MirrorKind m);
/// Parses the strings of toString(); throws std::invalid_argument otherwise.
MirrorKind mirrorKindFromString(const std::string& s);

struct TextileSymmetry {
  bool mirror_x = false;  ///< symmetric under x -> 2 cx - x
  bool mirror_y = false;  ///< symmetric under y -> 2 cy - y
  Real cx = 0, cy = 0;    ///< axes [m], textile frame

  bool any() const { return mirror_x || mirror_y; }
  /// "none", "x", "y" or "xy".
  std::string name() const;
  /// The group elements other than the identity that this symmetry has (0, 1 or 3 of them).
  std::vector<MirrorKind> mirrors() const;
  /// Applies a group element to a textile-frame point [m] (the element must belong to the group).
  Vec2 apply(MirrorKind m, const Vec2& p) const;
  /// True if p lies in the fundamental domain x <= cx + tol (when mirror_x), y <= cy + tol (mirror_y).
  bool inFundamentalDomain(const Vec2& p, Real tol) const;
  /// The image of p in the fundamental domain.
  Vec2 canonical(const Vec2& p) const;
};

/// The symmetry of a textile's full outline: a mirror counts if every vertex of the mirrored outline
/// lies on the original's boundary and vice versa (tolerance `tol` [m]). Named points are ignored.
/// Throws std::invalid_argument for an invalid outline.
TextileSymmetry detectSymmetry(const TextileOutline& textile, Real tol = 1e-9);

/// The fundamental domain of the full outline under `symmetry` as a polygon (the outline clipped to
/// x <= cx and/or y <= cy), or the full outline for no symmetry. Returns an empty vector if clipping
/// does not give a valid simple polygon (callers then filter points instead).
std::vector<Vec2> fundamentalDomainPolygon(const TextileOutline& textile, const TextileSymmetry& symmetry);

/// Default candidate hold points of the fundamental domain: holdPointLattice() of the fundamental-domain
/// polygon with spacing s (so the domain's edges, which include the symmetry axes, carry points). Falls
/// back to the full lattice filtered to the domain if the domain polygon is unavailable. Sorted by y, x.
/// Throws std::invalid_argument for a bad s or outline.
std::vector<Vec2> fundamentalDomainLattice(const TextileOutline& textile, const TextileSymmetry& symmetry,
                                           Real lattice_spacing);

/// An nx x ny rectangular grid over the fundamental domain's bounding box, edges included, keeping the
/// points inside the full outline (e.g. 6 x 6 = the thesis's 36 hold points in one towel quadrant).
/// Throws std::invalid_argument for nx or ny < 1.
std::vector<Vec2> fundamentalDomainGrid(const TextileOutline& textile, const TextileSymmetry& symmetry, int nx, int ny);

/// One hold point of a build plan.
struct PlannedHoldPoint {
  Vec2 position = Vec2::Zero();  ///< [m], textile frame
  int lattice_i = 0;             ///< row (rank of y among all planned hold points)
  int lattice_j = 0;             ///< column (rank of x)
  MirrorKind mirror = MirrorKind::kIdentity;  ///< how it derives from its source (identity = simulated)
  int source = -1;               ///< index (in the plan) of the simulated point it derives from; own index if simulated
};

/// Full set of hold points from the simulated (canonical) ones: every canonical point plus its distinct
/// mirror images (images within 1e-6 m of an already planned point are dropped, e.g. points on an axis).
/// Simulated points come first, in the order given; lattice indices rank x and y over the full set
/// (coordinates within 1e-6 m count as equal).
std::vector<PlannedHoldPoint> planHoldPoints(const std::vector<Vec2>& canonical, const TextileSymmetry& symmetry);

/// For each active particle k of `grid`, the active particle at the mirror image of its rest position,
/// or an empty vector if the grid is not symmetric under m (e.g. a towel side that is not a multiple of d).
std::vector<Index> mirrorPermutation(const ParticleGrid& grid, const TextileSymmetry& symmetry, MirrorKind m);

/// The largest spacing d' in [spacing/2, spacing] at which the particle grid of `textile` is symmetric under
/// every mirror of `symmetry` (mirrorPermutation() succeeds), so that a database build at d' simulates only
/// the fundamental domain's hold points and mirrors the rest. Tried: `spacing`, then the bounding box's width
/// and height divided by whole numbers, largest first, at most 100 of them. Returns `spacing` when the
/// symmetry has no mirror or no tried spacing gives a symmetric grid. Example: the 64 x 46 cm towel at 0.75 cm gives 2/3 cm (96 x 69
/// steps). Throws std::invalid_argument for a spacing that is not finite and > 0.
Real mirrorSymmetricSpacing(const TextileOutline& textile, const TextileSymmetry& symmetry, Real spacing);

/// The mirrored rest shape: particle perm[k] of the result is particle k of `positions` reflected in
/// the world through the vertical plane(s) through `hold_world` that correspond to m.
VecX mirrorPositions(const VecX& positions, const std::vector<Index>& perm, MirrorKind m, const Vec3& hold_world);

/// Textile-frame distance in lattice steps used by the evaluation: true if (i1, j1) and (i2, j2) are
/// equal or 4-neighbours (diagonal = false) / 8-neighbours (diagonal = true).
inline bool latticeNeighbours(int i1, int j1, int i2, int j2, bool diagonal) {
  const int di = i1 > i2 ? i1 - i2 : i2 - i1, dj = j1 > j2 ? j1 - j2 : j2 - j1;
  return diagonal ? (di <= 1 && dj <= 1) : (di + dj <= 1);
}

}  // namespace db
}  // namespace textile_handling
