#include "textile_handling/bench/match_benchmark.h"

#include <algorithm>
#include <chrono>
#include <ctime>
#include <cmath>
#include <iomanip>
#include <random>
#include <sstream>
#include <stdexcept>

#include "textile_handling/sim/timing.h"
#include "textile_handling/vision/vision_errors.h"

namespace textile_handling {
namespace vision {

SyntheticMesh syntheticHangingMesh(const HangingShapeParams& p, const Vec3& hold) {
  if (!(p.width > 0) || !(p.height > 0) || !(p.spacing > 0) || !std::isfinite(p.width) || !std::isfinite(p.height) ||
      !std::isfinite(p.spacing))
    throw InvalidArgumentError("syntheticHangingMesh", "p.width/height/spacing", "p.width, p.height and p.spacing must be finite and > 0");
  if (!hold.allFinite()) throw InvalidArgumentError("syntheticHangingMesh", "hold", "hold point is not finite");
  const int nx = std::max(2, static_cast<int>(std::lround(p.width / p.spacing)) + 1);
  const int ny = std::max(2, static_cast<int>(std::lround(p.height / p.spacing)) + 1);
  Vec2 c(0.5 * p.width - p.hold_u, 0.5 * p.height - p.hold_v);
  if (c.norm() < 1e-9) c = Vec2(0, -1);
  const double gamma = std::atan2(c.y(), c.x());
  SyntheticMesh m;
  m.hold = hold;
  m.positions.resize(3 * nx * ny);
  double best_r = 1e300;
  for (int i = 0; i < ny; ++i) {
    for (int j = 0; j < nx; ++j) {
      const double u = p.width * j / (nx - 1), v = p.height * i / (ny - 1);
      const Vec2 q(u - p.hold_u, v - p.hold_v);
      const double r = q.norm();
      double beta = r > 0 ? std::atan2(q.y(), q.x()) - gamma : 0.0;
      while (beta > kPi) beta -= 2 * kPi;
      while (beta <= -kPi) beta += 2 * kPi;
      const double b2 = p.gather * beta;
      const double x = r * std::sin(b2), depth = r * std::cos(b2);
      const double y = p.fold_amplitude * r * std::sin(2.0 * p.fold_waves * beta + p.fold_phase);
      const Index idx = i * nx + j;
      node3(m.positions, idx) = hold + Vec3(x, y, -depth);
      if (r < best_r) {
        best_r = r;
        m.hold_vertex = idx;
      }
    }
  }
  for (int i = 0; i + 1 < ny; ++i)
    for (int j = 0; j + 1 < nx; ++j) {
      const Index a = i * nx + j, b = a + 1, up = a + nx, ru = up + 1;
      m.triangles.push_back({a, b, ru});
      m.triangles.push_back({a, ru, up});
    }
  return m;
}

namespace {

BitMask randomBlob(std::mt19937_64& rng, const CanonicalFrame& f) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  BitMask m(f.width_px, f.height_px);
  const double sx = f.width_px / 64.0, sy = f.height_px / 64.0;
  const int k = 2 + static_cast<int>(U(rng) * 4);
  for (int e = 0; e < k; ++e) {
    const double cx = 0.5 * f.width_px + (U(rng) * 20 - 10) * sx;
    const double cy = f.top_margin_px + (e == 0 ? 8 : 5 + U(rng) * 35) * sy;
    const double rx = (3 + U(rng) * 11) * sx, ry = (4 + U(rng) * 16) * sy;
    for (int y = 0; y < f.height_px; ++y) {
      const double t = (y + 0.5 - cy) / ry;
      if (std::abs(t) >= 1) continue;
      const double hw = rx * std::sqrt(1 - t * t);
      m.setSpan(y, static_cast<int>(std::ceil(cx - hw - 0.5)), static_cast<int>(std::floor(cx + hw - 0.5)) + 1);
    }
  }
  return m;
}

struct GroupSpec {
  std::string textile, hold;
  HangingShapeParams params;
};

std::vector<GroupSpec> hangingGroups(int n_groups, std::mt19937_64& rng) {
  struct Size {
    const char* name;
    double w, h;
  };
  const Size sizes[] = {{"towel", 0.64, 0.46}, {"square", 0.30, 0.30}, {"shirt", 0.50, 0.70}, {"cloth", 0.90, 0.60}};
  const int per = (n_groups + 3) / 4;
  const int lat = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(per)))));
  std::uniform_real_distribution<double> U(0.0, 1.0);
  std::vector<GroupSpec> gs;
  for (const Size& s : sizes) {
    for (int k = 0; k < per && static_cast<int>(gs.size()) < n_groups; ++k) {
      GroupSpec g;
      g.textile = s.name;
      const int iu = k % lat, iv = k / lat;
      HangingShapeParams& p = g.params;
      p.width = s.w;
      p.height = s.h;
      p.hold_u = lat > 1 ? s.w * iu / (lat - 1) : 0.0;
      p.hold_v = lat > 1 ? s.h * std::min(1.0, static_cast<double>(iv) / (lat - 1)) : s.h;
      p.gather = 0.3 + 0.3 * U(rng);
      p.fold_amplitude = 0.05 + 0.15 * U(rng);
      p.fold_waves = 2 + std::floor(3 * U(rng));
      p.fold_phase = 2 * kPi * U(rng);
      p.spacing = 0.025;
      std::ostringstream os;
      os << std::fixed << std::setprecision(3) << p.hold_u << "," << p.hold_v;
      g.hold = os.str();
      gs.push_back(g);
    }
  }
  return gs;
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const std::size_t i = std::min(v.size() - 1, static_cast<std::size_t>(std::floor(q * (v.size() - 1) + 0.5)));
  return v[i];
}

bool sameResult(const QueryResult& a, const QueryResult& b) {
  if (a.matches.size() != b.matches.size()) return false;
  for (std::size_t i = 0; i < a.matches.size(); ++i) {
    const MatchResult &x = a.matches[i], &y = b.matches[i];
    if (x.entry != y.entry || x.dx != y.dx || x.dy != y.dy || x.score != y.score || x.margin != y.margin) return false;
  }
  return a.margin == b.margin;
}

}  // namespace

MatchBenchmarkReport benchmarkQueries(const SilhouetteMatcher& matcher, const std::vector<BitMask>& queries,
                                      const MatchOptions& options, const std::vector<std::string>& truth,
                                      int verify_queries) {
  if (queries.empty()) throw InvalidArgumentError("benchmarkQueries", "queries", "no queries");
  if (!truth.empty() && truth.size() != queries.size())
    throw InvalidArgumentError("benchmarkQueries", "truth", "truth must be empty or have one label per query");
  MatchBenchmarkReport r;
  r.entries = matcher.size();
  r.groups = matcher.numGroups();
  r.width = matcher.width();
  r.height = matcher.height();
  r.queries = static_cast<int>(queries.size());
  MatchOptions opt = options;
  opt.exhaustive = false;
  (void)matcher.query(queries.front(), opt);  // warm caches
  std::vector<double> ms, cpu;
  ms.reserve(queries.size());
  cpu.reserve(queries.size());
  double evaluated = 0, shifts = 0;
  int correct = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const std::clock_t c0 = std::clock();
    const auto t0 = std::chrono::steady_clock::now();
    const QueryResult res = matcher.query(queries[i], opt);
    const auto t1 = std::chrono::steady_clock::now();
    const std::clock_t c1 = std::clock();
    ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
    cpu.push_back(1000.0 * static_cast<double>(c1 - c0) / CLOCKS_PER_SEC);
    evaluated += static_cast<double>(res.stats.evaluated);
    shifts += static_cast<double>(res.stats.shifts_evaluated);
    if (!truth.empty() && !res.matches.empty() &&
        res.matches[0].textile_id + "/" + res.matches[0].hold_point_id == truth[i])
      ++correct;
  }
  double sum = 0;
  for (double v : ms) sum += v;
  r.mean_ms = sum / ms.size();
  r.median_ms = percentile(ms, 0.5);
  r.p95_ms = percentile(ms, 0.95);
  r.max_ms = *std::max_element(ms.begin(), ms.end());
  double csum = 0;
  for (double v : cpu) csum += v;
  r.mean_cpu_ms = csum / cpu.size();
  r.p95_cpu_ms = percentile(cpu, 0.95);
  r.max_cpu_ms = *std::max_element(cpu.begin(), cpu.end());
  r.mean_entries_evaluated = evaluated / ms.size();
  r.mean_shifts_evaluated = shifts / ms.size();
  r.top1_correct = truth.empty() ? -1 : correct;
  MatchOptions ex = opt;
  ex.exhaustive = true;
  for (int i = 0; i < verify_queries && i < static_cast<int>(queries.size()); ++i) {
    ++r.verified;
    if (!sameResult(matcher.query(queries[static_cast<std::size_t>(i)], opt),
                    matcher.query(queries[static_cast<std::size_t>(i)], ex)))
      ++r.verify_mismatches;
  }
  return r;
}

MatchBenchmarkReport runMatchBenchmark(const MatchBenchmarkConfig& cfg) {
  if (cfg.entries < 1 || cfg.queries < 1) throw InvalidArgumentError("runMatchBenchmark", "cfg.entries/queries", "cfg.entries and cfg.queries must be >= 1");
  cfg.frame.validate();
  const auto t0 = std::chrono::steady_clock::now();
  std::mt19937_64 rng(cfg.seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  SilhouetteMatcher matcher;
  std::vector<BitMask> queries;
  std::vector<std::string> truth;
  std::string name;

  if (cfg.database == BenchmarkDatabase::kRandomBlobs) {
    name = "random_blobs";
    matcher.reserve(static_cast<std::size_t>(cfg.entries));
    for (int e = 0; e < cfg.entries; ++e) {
      SilhouetteEntry en;
      en.textile_id = "blob";
      en.hold_point_id = std::to_string(e / 36);
      en.view_angle_deg = 10.0 * (e % 36);
      en.mask = randomBlob(rng, cfg.frame);
      matcher.add(en);
    }
    for (int q = 0; q < cfg.queries; ++q) queries.push_back(randomBlob(rng, cfg.frame));
  } else {
    name = "hanging_shapes";
    const ViewSet views;  // 36 x 10 deg
    const int n_groups = (cfg.entries + views.count - 1) / views.count;
    const std::vector<GroupSpec> groups = hangingGroups(n_groups, rng);
    std::vector<SilhouetteEntry> entries(static_cast<std::size_t>(cfg.entries));
#pragma omp parallel for schedule(dynamic)
    for (int e = 0; e < cfg.entries; ++e) {
      const GroupSpec& g = groups[static_cast<std::size_t>(e / views.count)];
      const SyntheticMesh mesh = syntheticHangingMesh(g.params);
      SilhouetteEntry& en = entries[static_cast<std::size_t>(e)];
      en.textile_id = g.textile;
      en.hold_point_id = g.hold;
      en.view_angle_deg = views.start_deg + views.step_deg * (e % views.count);
      en.mask = renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, en.view_angle_deg, {}, cfg.frame);
    }
    matcher.reserve(entries.size());
    for (const auto& en : entries) matcher.add(en);
    // Queries: a stored shape with perturbed folds, an arbitrary view angle and a small offset.
    std::uniform_int_distribution<int> pick(0, static_cast<int>(groups.size()) - 1);
    std::uniform_int_distribution<int> sdx(-3, 3), sdy(-2, 2);
    for (int q = 0; q < cfg.queries; ++q) {
      const GroupSpec& g = groups[static_cast<std::size_t>(pick(rng))];
      HangingShapeParams p = g.params;
      p.gather *= 0.95 + 0.1 * U(rng);
      p.fold_amplitude *= 0.9 + 0.2 * U(rng);
      p.fold_phase += 0.3 * (U(rng) - 0.5);
      const SyntheticMesh mesh = syntheticHangingMesh(p);
      const double angle = 360.0 * U(rng);
      const BitMask m = renderSilhouette(mesh.positions, mesh.triangles, mesh.hold, angle, {}, cfg.frame);
      queries.push_back(m.shifted(sdx(rng), sdy(rng)));
      truth.push_back(g.textile + "/" + g.hold);
    }
  }
  const double build_s = secondsSince(t0);
  MatchBenchmarkReport r = benchmarkQueries(matcher, queries, cfg.options, truth, cfg.verify_queries);
  r.database = name;
  r.build_seconds = build_s;
  return r;
}

std::string formatReport(const MatchBenchmarkReport& r) {
  std::ostringstream os;
  os << std::fixed << std::setprecision(3);
  os << "silhouette match benchmark (" << r.database << ")\n"
     << "  database: " << r.entries << " silhouettes of " << r.width << "x" << r.height << " px, " << r.groups
     << " (textile, hold point) groups, built in " << r.build_seconds << " s\n"
     << "  queries: " << r.queries << " (single thread)\n"
     << "  query time [ms]: mean " << r.mean_ms << ", median " << r.median_ms << ", p95 " << r.p95_ms << ", max "
     << r.max_ms << "\n"
     << "  query cpu time [ms]: mean " << r.mean_cpu_ms << ", p95 " << r.p95_cpu_ms << ", max " << r.max_cpu_ms << "\n"
     << std::setprecision(1) << "  per query: " << r.mean_entries_evaluated << " exact shift searches, "
     << r.mean_shifts_evaluated << " shift evaluations\n";
  if (r.top1_correct >= 0) os << "  top-1 correct: " << r.top1_correct << " / " << r.queries << "\n";
  if (r.verified > 0)
    os << "  exhaustive check: " << r.verified << " queries, " << r.verify_mismatches << " mismatches\n";
  return os.str();
}

}  // namespace vision
}  // namespace textile_handling
