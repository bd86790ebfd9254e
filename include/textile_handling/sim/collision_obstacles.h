// Rigid obstacles of the drape simulator (planes, boxes, spheres) handled by a post-step pass with a
// contact distance and Coulomb-like friction, and the chain that runs several post-step passes in
// order (docs/collision.md). Positions are 3 DOFs per particle, lengths in m. ROS-free.
#pragma once

#include <utility>
#include <vector>

#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/integrators.h"
#include "textile_handling/sim/types.h"

namespace textile_handling {

/// Solid half-space {y : (y - point) . normal < 0} (a floor with normal +z).
struct PlaneObstacle {
  Vec3 point = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();  ///< outward, normalised on construction of the pass
  Vec3 velocity = Vec3::Zero();
};

/// Solid box: centre + R * [-half, half]^3 (R = identity: axis-aligned, e.g. a table; a rotated box:
/// a gripper jaw). `velocity` is the obstacle's rigid translation velocity (for moving jaws; the
/// caller updates the pose between runs).
struct BoxObstacle {
  Vec3 centre = Vec3::Zero();
  Vec3 half_extents = Vec3::Constant(0.5);
  Mat3 rotation = Mat3::Identity();  ///< columns: the box axes in world coordinates
  Vec3 velocity = Vec3::Zero();
  static BoxObstacle axisAligned(const Vec3& lo, const Vec3& hi);
  /// True when p lies inside the box enlarged by `margin` (closed).
  bool contains(const Vec3& p, Real margin = 0) const;
};

struct SphereObstacle {
  Vec3 centre = Vec3::Zero();
  Real radius = 0.05;
  Vec3 velocity = Vec3::Zero();
};

/// The plane with its normal normalised. Throws SimError for a zero or non-finite normal, or a non-finite
/// point or velocity. Every user of obstacles validates with these three functions.
PlaneObstacle validatedPlane(const PlaneObstacle& p);
/// Throws SimError for a non-finite centre, size or velocity, a negative size, or a rotation that is not
/// orthonormal.
void validateBox(const BoxObstacle& b);
/// Throws SimError for a non-finite centre or velocity, or a radius that is not finite and positive.
void validateSphere(const SphereObstacle& s);

struct ObstacleOptions {
  /// Particles closer than this to a surface (or inside) are projected to this distance [m].
  Real contact_distance = 1e-3;
  /// Coulomb-like friction coefficient mu: on contact the tangential velocity (relative to the
  /// obstacle) is reduced by mu times the removed normal velocity, never reversed. 0 = frictionless.
  Real friction = 0.0;
};

/// Obstacle pass: after every step, each free particle that ends inside an obstacle or within the
/// contact distance of it is projected onto the contact surface (distance contact_distance), its
/// normal velocity into the obstacle is removed and friction is applied. A box entered during the
/// step is left through the face it was entered by (continuous choice from x_old), not the nearest.
/// Particles are independent, so the pass runs in parallel and deterministically.
class ObstaclePass : public PostStepPass {
 public:
  ObstaclePass(std::vector<char> pinned_mask, ObstacleOptions options = {});
  ObstaclePass(Index num_particles, const PinnedNodes& pins, ObstacleOptions options = {});

  void addPlane(const PlaneObstacle& p);
  void addBox(const BoxObstacle& b);
  void addSphere(const SphereObstacle& s);
  std::vector<PlaneObstacle>& planes() { return planes_; }
  std::vector<BoxObstacle>& boxes() { return boxes_; }
  std::vector<SphereObstacle>& spheres() { return spheres_; }
  const ObstacleOptions& options() const { return options_; }

  /// Returns the number of (particle, obstacle) contacts handled.
  long apply(const VecX& x_old, VecX& x, VecX& v) override;
  /// Number of free particles strictly inside any obstacle (a check for tests).
  long countInside(const VecX& x, Real margin = 0) const;

 private:
  std::vector<char> pinned_;
  ObstacleOptions options_;
  std::vector<PlaneObstacle> planes_;
  std::vector<BoxObstacle> boxes_;
  std::vector<SphereObstacle> spheres_;
};

/// Runs several passes in order (e.g. obstacles, then self-collision) and sums their event counts.
/// Non-owning. Recommended order: obstacles first, then self-collision, because the self-collision
/// rollback returns particles to x_old, which already satisfied the obstacles.
class PostStepPassChain : public PostStepPass {
 public:
  PostStepPassChain() = default;
  explicit PostStepPassChain(std::vector<PostStepPass*> passes) : passes_(std::move(passes)) {}
  void add(PostStepPass* p) { passes_.push_back(p); }
  long apply(const VecX& x_old, VecX& x, VecX& v) override;

 private:
  std::vector<PostStepPass*> passes_;
};

}  // namespace textile_handling
