// Self-collision and obstacle handling for the drape simulator (thesis section 3.3 / summary section 7),
// as post-step passes run by DrapeSimulation after every accepted step. ROS-free. See docs/collision.md
// for the algorithms, the decisions on the thesis's open points and the known failure cases.
//
//  - ClothTriangles: the thesis triangulation of the particle grid (each particle p0 owns the
//    triangles (p0, right, up) and (p0, left, down)), its edges and adjacency;
//  - SelfCollisionPass: the three versions of the thesis (v1 point path, v2 edge test, v3 edge test
//    with candidate set and rollback), with a spatial-hash broad phase; v3 adds a proximity stage
//    that keeps resting cloth-on-cloth contact at a thickness (persistent contact);
//  - ContactForceModel / withContactForces(): feed the proximity stage's contact forces into the
//    implicit solve, which makes resting contact a fixed point;
//  - ObstaclePass: planes, boxes and spheres with a contact distance and Coulomb-like friction;
//  - PostStepPassChain: runs several passes in order and sums their event counts;
//  - countIntersectingTrianglePairs(): an independent exact checker (Devillers-Guigue).
//
// Positions are 3 DOFs per particle (ParticleClothModel). Lengths in m, velocities in m/s.
//
// This header only gathers the collision headers (one job each) for code that uses several of them.
#pragma once

#include "textile_handling/sim/cloth_triangles.h"
#include "textile_handling/sim/collision_check.h"
#include "textile_handling/sim/collision_geometry.h"
#include "textile_handling/sim/collision_obstacles.h"
#include "textile_handling/sim/contact_force_model.h"
#include "textile_handling/sim/self_collision_options.h"
#include "textile_handling/sim/self_collision_pass.h"
