// Picture-frame shear test of the yarn_woven model (yarn_shear_frame.h).
#include "textile_handling/bench/yarn_shear_frame.h"

#include <Eigen/LU>
#include <cmath>
#include <ostream>

#include "textile_handling/sim/cloth_topology.h"
#include "textile_handling/sim/drape_simulation.h"
#include "textile_handling/sim/sim_errors.h"
#include "textile_handling/sim/textile_geometry.h"

namespace textile_handling {

namespace {

constexpr int kB = kYarnDofsPerNode;

// The frame's map of flat sheet coordinates (x, y) at angle phi: the warp side stays along x, the weft
// side turns to (cos phi, sin phi), both keep their lengths.
Eigen::Matrix2d frameMap(Real phi) {
  Eigen::Matrix2d a;
  a << 1, std::cos(phi), 0, std::sin(phi);
  return a;
}

YarnWovenModel squareSheet(const ShearFrameSpec& spec, ParticleTopology* topology) {
  const Real L = spec.model.fabric.warpSpacing();
  const Real side = (spec.yarns - 1) * L;
  TextileOutline t;
  t.name = "shear_frame_square";
  t.outline = {Vec2(0, 0), Vec2(side, 0), Vec2(side, side), Vec2(0, side)};
  std::string error;
  const ParticleGrid grid = ParticleGrid::rasterize(t, L, &error);
  if (grid.empty()) throw SimError("shear frame: " + error);
  *topology = ParticleTopology::fromGrid(grid);
  YarnWovenOptions o = spec.model;
  o.gravity = false;
  return YarnWovenModel(buildYarnSheet(yarnGridOnParticles(*topology, o.fabric.weave)),
                        yarnBundleFabric(o.fabric, L), o);
}

}  // namespace

std::vector<ShearFramePoint> runShearFrame(const ShearFrameSpec& spec) {
  if (!(spec.min_angle > 0 && spec.min_angle < kPi / 2) || !(spec.angle_step > 0) || spec.yarns < 3)
    throw SimError("shear frame: min_angle must be in (0, pi/2), angle_step > 0 and yarns >= 3");
  ParticleTopology topology;
  YarnWovenModel model = squareSheet(spec, &topology);
  const Index n = model.numNodes();
  std::vector<Index> clamped;
  for (Index i = 0; i < n; ++i)
    for (Index nb : topology.neighbour[i])
      if (nb < 0) {
        clamped.push_back(i);
        break;
      }
  // The load path: pi / 2 down to min_angle and back.
  std::vector<std::pair<Real, bool>> path;
  for (Real phi = kPi / 2 - spec.angle_step; phi > spec.min_angle - 1e-12; phi -= spec.angle_step) path.emplace_back(phi, true);
  if (spec.unload) {
    const Real lowest = path.empty() ? kPi / 2 : path.back().first;
    for (Real phi = lowest + spec.angle_step; phi < kPi / 2 + 1e-12; phi += spec.angle_step) path.emplace_back(phi, false);
  }
  SimulationSettings settings;
  settings.integrator = IntegratorType::kSemiImplicitEuler;
  settings.policy = StepPolicy::kFixed;
  settings.dt = spec.dt;
  settings.max_time = spec.relax_time;
  settings.rest_duration = 1e9;  // relax for the whole time

  VecX x = VecX::Zero(model.numDofs());
  for (Index i = 0; i < n; ++i) x.segment<3>(kB * i) = model.sheet().rest.segment<3>(kB * i);
  Real phi_now = kPi / 2;
  std::vector<ShearFramePoint> points;
  for (const auto& [phi, loading] : path) {
    // Every node follows the frame's incremental map (the interior starts near its new equilibrium);
    // the border crossings are then held there.
    const Eigen::Matrix2d step = frameMap(phi) * frameMap(phi_now).inverse();
    for (Index i = 0; i < n; ++i) x.segment<2>(kB * i) = step * x.segment<2>(kB * i);
    phi_now = phi;
    PinnedNodes pins;
    for (Index i : clamped) {
      pins.nodes.push_back(i);
      pins.anchors.push_back(x.segment<3>(kB * i));
    }
    DrapeSimulation sim(model, pins, settings, x, VecX::Zero(x.size()));
    const RunResult r = sim.run();
    if (r.diverged) throw SimError("shear frame: relaxation at phi = " + std::to_string(phi) + " diverged: " + r.divergence_reason);
    x = sim.state();
    VecX f;
    model.computeForces(x, VecX::Zero(x.size()), f, nullptr);
    ShearFramePoint p;
    p.frame_angle = phi;
    p.shear_angle = kPi / 2 - phi;
    p.loading = loading;
    p.kinetic_energy = r.kinetic_energy;
    // d x_i / d(shear) = -d x_i / d phi = (y sin phi, -y cos phi) with y the flat weft coordinate.
    for (Index i : clamped) {
      const Real y = model.sheet().rest[kB * i + 1];
      p.moment -= f[kB * i] * y * std::sin(phi) - f[kB * i + 1] * y * std::cos(phi);
    }
    points.push_back(p);
  }
  return points;
}

void writeShearFrameCsv(std::ostream& os, const std::string& weave, const std::vector<ShearFramePoint>& points) {
  os << "weave,frame_angle_rad,shear_angle_rad,loading,moment_N_m,kinetic_energy_J\n";
  for (const ShearFramePoint& p : points)
    os << weave << ',' << p.frame_angle << ',' << p.shear_angle << ',' << (p.loading ? 1 : 0) << ',' << p.moment << ','
       << p.kinetic_energy << '\n';
}

}  // namespace textile_handling
