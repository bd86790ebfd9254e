#include "textile_handling/bench/thesis_benchmark.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <tuple>

#include "textile_handling/sim/material.h"
#include "textile_handling/db/drape_export.h"
#include "textile_handling/db/drape_match_evaluation.h"
#include "textile_handling/db/drape_match_index.h"
#include "textile_handling/bench/match_benchmark.h"

namespace textile_handling {
namespace db {

namespace {

namespace fs = std::filesystem;

void removeDatabase(const std::string& path) {
  std::error_code ec;
  for (const char* suffix : {"", "-wal", "-shm"}) fs::remove(path + suffix, ec);
}

std::string fmt(double v, int prec = 4) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", prec, v);
  return b;
}

std::string csvField(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

MatchEvaluation merge(const MatchEvaluation& a, const MatchEvaluation& b) {
  MatchEvaluation m = a;
  m.queries += b.queries;
  m.exact += b.exact;
  m.within_one += b.within_one;
  m.within_one_diagonal += b.within_one_diagonal;
  m.top5 += b.top5;
  m.query_ms.insert(m.query_ms.end(), b.query_ms.begin(), b.query_ms.end());
  for (const auto& [k, v] : b.confusion) m.confusion[k] += v;
  return m;
}

BenchmarkRow rowOf(const std::string& experiment, const std::string& variant, const DrapeMatchIndex& index,
                   const MatchEvaluation& e) {
  BenchmarkRow r;
  r.experiment = experiment;
  r.variant = variant;
  r.silhouettes = static_cast<long>(index.matcher.size());
  r.hold_points = static_cast<int>(index.matcher.numGroups());
  r.classes = static_cast<int>(index.classes.size());
  r.queries = e.queries;
  r.exact_rate = e.exactRate();
  r.within_one_rate = e.withinOneRate();
  r.within_one_diagonal_rate = e.withinOneDiagonalRate();
  r.top5_rate = e.top5Rate();
  r.neighbour_share_of_errors = e.neighbourShareOfErrors();
  r.query_ms = e.meanQueryMs();
  r.query_p95_ms = e.percentileQueryMs(95);
  return r;
}

std::string holdText(const Vec2& p) { return "(" + fmt(p.x() * 100, 1) + ", " + fmt(p.y() * 100, 1) + ") cm"; }

}  // namespace

vision::CanonicalFrame benchmarkFrame(const ThesisBenchmarkConfig& cfg) {
  if (cfg.frame_px < 8 || cfg.frame_px > 1024 || !(cfg.frame_metres > 0) || !std::isfinite(cfg.frame_metres))
    throw std::invalid_argument("bench: the frame needs 8..1024 px and a positive size");
  vision::CanonicalFrame f = vision::CanonicalFrame::fromMetric(cfg.frame_metres, cfg.frame_metres, cfg.frame_px);
  f.top_margin_px = 2.0 * cfg.frame_px / 64.0;  // the same metric margin as the 64 px default
  return f;
}

vision::MatchOptions benchmarkMatchOptions(const ThesisBenchmarkConfig& cfg) {
  return metricShiftOptions(benchmarkFrame(cfg), cfg.max_shift_x_m < 0 ? kThesisShiftXMetres : cfg.max_shift_x_m,
                            cfg.max_shift_y_m < 0 ? kThesisShiftYMetres : cfg.max_shift_y_m);
}

std::string benchmarkCsvHeader() {
  return "experiment,variant,silhouettes,hold_points,classes,queries,query_ms,query_p95_ms,exact_rate,within_one_rate,"
         "within_one_diagonal_rate,top5_rate,neighbour_share_of_errors,build_s,simulations,notes";
}

std::string benchmarkCsvRow(const BenchmarkRow& r) {
  std::ostringstream os;
  os << r.experiment << ',' << csvField(r.variant) << ',' << r.silhouettes << ',' << r.hold_points << ',' << r.classes
     << ',' << r.queries << ',' << fmt(r.query_ms, 4) << ',' << fmt(r.query_p95_ms, 4) << ',' << fmt(r.exact_rate, 4)
     << ',' << fmt(r.within_one_rate, 4) << ',' << fmt(r.within_one_diagonal_rate, 4) << ',' << fmt(r.top5_rate, 4)
     << ',' << fmt(r.neighbour_share_of_errors, 4) << ',' << fmt(r.build_s, 2) << ',' << r.simulations << ','
     << csvField(r.notes);
  return os.str();
}

std::vector<BenchmarkRow> runThesisBenchmark(const ThesisBenchmarkConfig& cfg) {
  using Clock = std::chrono::steady_clock;
  const auto t_all = Clock::now();
  std::error_code ec;
  fs::create_directories(cfg.out_dir, ec);
  if (ec) throw std::runtime_error("cannot create '" + cfg.out_dir + "': " + ec.message());
  const std::string db_path = cfg.out_dir + "/bench_towel.sqlite";
  const std::string held_path = cfg.out_dir + "/bench_heldout.sqlite";
  if (!cfg.resume) {
    removeDatabase(db_path);
    removeDatabase(held_path);
  }
  const int nx = cfg.quick ? 3 : cfg.grid_nx, ny = cfg.quick ? 3 : cfg.grid_ny;
  const int pairs = cfg.quick ? 2 : cfg.pairs_per_shape;
  std::ostream& log = std::cout;

  // ---- 1. the database: towel, cotton, nx x ny hold points in one quadrant --------------------
  DrapeBuildConfig base;
  base.textile = presetTextile("towel");
  base.material = Material::cotton();
  base.spacing = cfg.spacing;
  base.workers = cfg.workers;
  base.frame = benchmarkFrame(cfg);
  base.bracket_hold_points = cfg.bracket_hold_points;
  if (!(cfg.max_time_s > 0) || !std::isfinite(cfg.max_time_s)) throw std::invalid_argument("bench: max_time_s must be > 0");
  base.settings.max_time = cfg.max_time_s;
  const TextileSymmetry sym = detectSymmetry(base.textile);
  base.hold_points = fundamentalDomainGrid(base.textile, sym, nx, ny);
  if (cfg.prepare_build) cfg.prepare_build(base);  // the held-out builds below start from copies of base
  log << "== database: towel 64 x 46 cm, cotton, d = " << cfg.spacing * 100 << " cm, "
      << (cfg.bracket_hold_points ? "hold points bracketed by the particles of their grid cells, " : "")
      << base.hold_points.size()
      << " hold points in one quadrant (" << nx << " x " << ny << "), 36 views of " << base.frame.width_px << " x "
      << base.frame.height_px << " px over " << fmt(cfg.frame_metres, 2) << " m\n";
  HangingDrapeDatabase db(db_path);
  DrapeDatabaseBuilder builder(db, base);
  const DrapeBuildReport rep = builder.build();
  log << "   built in " << fmt(rep.wall_seconds, 1) << " s: " << rep.simulated_now << " simulations run ("
      << rep.already_done << " already done, " << rep.failed_now << " failed), " << rep.derived_now
      << " mirrored entries derived; mean simulation wall time "
      << fmt(rep.simulated_now ? rep.simulation_seconds / rep.simulated_now : 0.0, 2) << " s\n";
  for (const auto& f : rep.failures) log << "   failed: " << f << "\n";

  // ---- 2. held-out shapes: perturbed material, other resolution; hold points in random quadrants --
  std::mt19937_64 rng(cfg.seed);
  const std::vector<MirrorKind> group = {MirrorKind::kIdentity, MirrorKind::kMirrorX, MirrorKind::kMirrorY,
                                         MirrorKind::kMirrorXY};
  std::vector<Vec2> held_points;
  for (const Vec2& p : base.hold_points) held_points.push_back(sym.apply(group[rng() % 4], p));
  HangingDrapeDatabase hdb(held_path);
  struct Variant {
    std::string name, textile_name, description;
    DrapeBuildConfig config;
  };
  std::vector<Variant> variants;
  {
    Variant v;
    v.name = "material";
    v.config = base;
    v.config.textile.name = "towel_perturbed_material";
    v.config.material = scaledMaterial(base.material, 1.3, 0.8, 1.1, "cotton_perturbed");
    v.description = "cotton with bending x1.3, shear x0.8, areal density x1.1, d = " + fmt(cfg.spacing * 100, 1) + " cm";
    variants.push_back(v);
  }
  {
    Variant v;
    v.name = "resolution";
    v.config = base;
    v.config.spacing = cfg.heldout_spacing;
    v.description = "cotton at d = " + fmt(cfg.heldout_spacing * 100, 1) + " cm";
    variants.push_back(v);
  }
  double heldout_s = 0;
  std::vector<std::vector<HeldOutShape>> shapes(variants.size());
  for (std::size_t k = 0; k < variants.size(); ++k) {
    Variant& v = variants[k];
    v.config.use_symmetry = false;
    v.config.bracket_hold_points = false;  // held-out shapes: the particle nearest to the true hold point
    v.config.hold_points = held_points;
    v.config.views.count = 1;  // the held-out rows are only used as shapes
    log << "== held-out shapes (" << v.name << "): " << v.description << ", hold points mirrored into random quadrants\n";
    DrapeDatabaseBuilder hb(hdb, v.config);
    const DrapeBuildReport hr = hb.build();
    heldout_s += hr.wall_seconds;
    log << "   " << hr.simulated_now << " simulations in " << fmt(hr.wall_seconds, 1) << " s (" << hr.failed_now
        << " failed)\n";
    const auto textile = hdb.findTextile(v.config.textile.name);
    const std::string params = DrapeDatabaseBuilder::parametersText(v.config);
    for (const SimulationRecord& s : hdb.simulations(textile->id, SimulationStatus::kDone)) {
      if (s.parameters != params) continue;
      HeldOutShape shape = heldOutShapeFromMesh(loadDrapeMesh(hdb, s.id), v.name);
      shape.textile = "towel";  // the database's name for this textile
      shapes[k].push_back(std::move(shape));
    }
  }

  // ---- 3. matching -----------------------------------------------------------------------------
  MatchIndexOptions mio;
  mio.textile = "towel";
  const DrapeMatchIndex index = loadDrapeMatchIndex(db, mio);
  log << "== index: " << index.matcher.size() << " silhouettes, " << index.matcher.numGroups() << " hold points, "
      << index.classes.size() << " classes up to symmetry, loaded in " << fmt(index.load_seconds * 1e3, 1) << " ms\n";
  EvaluationOptions eo;
  eo.pairs_per_shape = pairs;
  eo.seed = cfg.seed;
  eo.match = benchmarkMatchOptions(cfg);
  log << "== matching: shift search +-" << eo.match.max_dx << " px horizontally, +-" << eo.match.max_dy
      << " px vertically (" << fmt(eo.match.max_dx * index.frame.metres_per_pixel * 100, 1) << " / "
      << fmt(eo.match.max_dy * index.frame.metres_per_pixel * 100, 1) << " cm)\n";
  std::vector<MatchEvaluation> single(variants.size()), fused(variants.size());
  std::vector<HeldOutPair> all_pairs;
  std::string skipped;
  for (std::size_t k = 0; k < variants.size(); ++k) {
    // A hold point whose database simulation failed has no class: its held-out shapes cannot be scored.
    // They are left out and named (the run does not stop), so the counts stay honest.
    std::vector<HeldOutShape> usable;
    for (HeldOutShape& s : shapes[k]) {
      if (index.classOf(s.textile, s.hold)) {
        usable.push_back(std::move(s));
        continue;
      }
      skipped += (skipped.empty() ? "" : "; ") + variants[k].name + " " + holdText(s.hold);
      log << "   WARNING: held-out hold point " << holdText(s.hold) << " (" << variants[k].name
          << ") has no class in the database (its simulation failed): left out\n";
    }
    shapes[k] = std::move(usable);
    eo.seed = cfg.seed + 1000 * (k + 1);
    const std::vector<HeldOutPair> p = renderHeldOutPairs(index, shapes[k], eo);
    std::tie(single[k], fused[k]) = evaluatePairs(index, p, eo);
    all_pairs.insert(all_pairs.end(), p.begin(), p.end());
  }
  const MatchEvaluation single_all = merge(single[0], single[1]);
  const MatchEvaluation fused_all = merge(fused[0], fused[1]);

  std::vector<BenchmarkRow> rows;
  const std::string variants_text = "material+resolution";
  auto add = [&](const std::string& exp, const std::string& var, const MatchEvaluation& e, const std::string& notes) {
    BenchmarkRow r = rowOf(exp, var, index, e);
    r.build_s = rep.wall_seconds;
    r.simulations = rep.simulated_now + rep.already_done;
    r.notes = notes;
    rows.push_back(r);
  };
  add("single_view", variants_text, single_all,
      "held-out shapes: " + variants[0].description + "; " + variants[1].description +
          "; camera 4 m, f = 1200 px, noise sigma 6, segmented; azimuths between stored views" +
          (skipped.empty() ? std::string() : "; left out (no database class): " + skipped));
  add("two_view", variants_text, fused_all, "same images as single_view, fused in pairs turned 60-120 deg");
  for (std::size_t k = 0; k < variants.size(); ++k) {
    add("single_view_" + variants[k].name, variants[k].name, single[k], variants[k].description);
    add("two_view_" + variants[k].name, variants[k].name, fused[k], variants[k].description);
  }

  // ---- 4. 10 000 silhouettes: a copy of the towel database plus stored synthetic distractors ------
  // Synthetic hanging textiles (vision/match_benchmark.h: procedural shapes of random size, hold point
  // and folds, not physics) fill the copy up to cfg.entries_10k silhouettes; loading it from disk and
  // querying it with the single_view / two_view images gives the load and query times at that size.
  double load10k_ms = 0;
  {
    const std::string big_path = cfg.out_dir + "/bench_10k.sqlite";
    removeDatabase(big_path);
    db.withConnection([](SqlConnection& conn) {
      conn.exec("PRAGMA wal_checkpoint(TRUNCATE)");
      return 0;
    });
    fs::copy_file(db_path, big_path, fs::copy_options::overwrite_existing);
    HangingDrapeDatabase big_db(big_path);
    TextileOutline distractor;
    distractor.name = "synthetic_distractors";  // an asymmetric outline: no hold points merge
    distractor.outline = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 0.9)};
    // A bracketed database can hold more than entries_10k silhouettes: then the copy drops whole
    // bracket passes, the highest corner first (corner 0 alone covers every hold point), until it fits.
    std::string dropped;
    long towel_kept = static_cast<long>(index.matcher.size());
    const std::vector<std::string> passes = DrapeDatabaseBuilder::parameterTexts(base);
    for (std::size_t k = passes.size(); k-- > 1 && towel_kept > cfg.entries_10k;) {
      big_db.withConnection([&](SqlConnection& conn) {
        SqlTransaction tx(conn);
        SqlStatement n = conn.prepare(
            "SELECT count(*) FROM views v JOIN simulations s ON s.id = v.simulation_id WHERE s.parameters = ?");
        n.bind(1, passes[k]);
        n.step();
        towel_kept -= static_cast<long>(n.getInt(0));
        SqlStatement del = conn.prepare("DELETE FROM simulations WHERE parameters = ?");  // views cascade
        del.bind(1, passes[k]);
        del.run();
        tx.commit();
        return 0;
      });
      dropped += (dropped.empty() ? "" : ", ") + std::to_string(k);
    }
    if (!dropped.empty())
      log << "== 10k row: bracket corner(s) " << dropped << " left out of the copy (" << towel_kept
          << " towel silhouettes kept)\n";
    const std::int64_t tex = big_db.addTextile(distractor, Material::cotton());
    const int need = std::max(0, cfg.entries_10k - static_cast<int>(towel_kept));
    const vision::ViewSet views;
    const int groups = (need + views.count - 1) / views.count;
    std::vector<NewSimulation> planned;
    for (int g = 0; g < groups; ++g) {
      NewSimulation n;
      n.textile_id = tex;
      n.hold = Vec2(0.025 + 0.05 * (g % 19), 0.025 + 0.05 * (g / 19));
      n.lattice_i = g / 19;
      n.lattice_j = g % 19;
      n.model = "synthetic";
      n.integrator = "none";
      n.spacing = 0.02;
      n.parameters = "synthetic hanging shapes (vision::syntheticHangingMesh), seed " + std::to_string(cfg.seed + 77);
      planned.push_back(n);
    }
    const std::vector<std::int64_t> ids = big_db.addSimulations(planned);
    std::mt19937_64 r2(cfg.seed + 77);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<SimulationResult> results;
    int added = 0;
    for (int g = 0; g < groups; ++g) {
      vision::HangingShapeParams hp;
      hp.width = 0.3 + 0.7 * u(r2);
      hp.height = 0.3 + 0.7 * u(r2);
      hp.hold_u = hp.width * u(r2);
      hp.hold_v = hp.height * u(r2);
      hp.gather = 0.3 + 0.3 * u(r2);
      hp.fold_amplitude = 0.05 + 0.15 * u(r2);
      hp.fold_waves = 1.0 + 4.0 * u(r2);
      hp.fold_phase = 6.283185307179586 * u(r2);
      hp.spacing = 0.02;
      const vision::SyntheticMesh mesh = vision::syntheticHangingMesh(hp);
      SimulationResult res;
      res.simulation_id = ids[static_cast<std::size_t>(g)];
      res.positions = mesh.positions;
      res.held_particle = mesh.hold_vertex;
      res.rest_reached = true;
      res.frame = index.frame;
      for (auto& v : vision::renderViews(mesh.positions, mesh.triangles, mesh.hold, views,
                                         vision::SilhouetteProjection::orthographic(), index.frame)) {
        if (added >= need) break;
        res.views.push_back({v.view_angle_deg, std::move(v.mask)});
        ++added;
      }
      results.push_back(std::move(res));
    }
    big_db.storeResults(results);
    const DrapeMatchIndex big = loadDrapeMatchIndex(big_db);  // every textile: towel + distractors
    load10k_ms = big.load_seconds * 1e3;
    log << "== " << big.matcher.size() << " silhouettes (towel + " << added << " synthetic distractors) loaded from "
        << big_path << " in " << fmt(load10k_ms, 1) << " ms\n";
    std::vector<HeldOutPair> big_pairs = all_pairs;  // truth classes re-indexed for this index
    for (HeldOutPair& p : big_pairs) {
      const HoldPointClass& c = index.classes[p.truth_class];
      const auto k = big.classOf(c.textile, c.canonical_hold);
      if (!k) throw std::runtime_error("10k index lost a towel hold point");
      p.truth_class = *k;
    }
    const auto [s10, f10] = evaluatePairs(big, big_pairs, eo);
    BenchmarkRow r = rowOf("query_time_10k", variants_text, big, s10);
    r.build_s = rep.wall_seconds;
    r.simulations = rep.simulated_now + rep.already_done;
    r.notes = "towel database (" + std::to_string(towel_kept) + " silhouettes" +
              (dropped.empty() ? std::string() : ", without bracket corner(s) " + dropped) + ") plus " +
              std::to_string(added) +
              " synthetic hanging-textile silhouettes (distractors) in one file, loaded in " + fmt(load10k_ms, 1) +
              " ms; the single_view images, one thread";
    rows.push_back(r);
    BenchmarkRow r2row = rowOf("query_time_10k_two_view", variants_text, big, f10);
    r2row.build_s = rep.wall_seconds;
    r2row.simulations = r.simulations;
    r2row.notes = "as query_time_10k, two-image fusion";
    rows.push_back(r2row);
  }

  // ---- 5. outputs ------------------------------------------------------------------------------
  {
    const std::string path = cfg.out_dir + "/match_benchmark.csv";
    std::ofstream f(path);
    if (!f) throw std::runtime_error("cannot write '" + path + "'");
    f << benchmarkCsvHeader() << "\n";
    for (const auto& r : rows) f << benchmarkCsvRow(r) << "\n";
    if (!f.flush()) throw std::runtime_error("error writing '" + path + "'");
  }
  {
    const std::string path = cfg.out_dir + "/match_confusion.csv";
    std::ofstream f(path);
    if (!f) throw std::runtime_error("cannot write '" + path + "'");
    f << "experiment,true_x_m,true_y_m,predicted_x_m,predicted_y_m,relation,count\n";
    for (const auto* e : {&single_all, &fused_all})
      for (const auto& [key, n] : e->confusion) {
        const auto& tc = index.classes[key.first];
        std::string rel = "foreign";
        std::string px = "", py = "";
        if (key.second != kForeignClass) {
          const auto& pc = index.classes[key.second];
          px = fmt(pc.canonical_hold.x(), 4);
          py = fmt(pc.canonical_hold.y(), 4);
          rel = key.first == key.second                               ? "exact"
                : index.classesNeighbour(key.first, key.second, false) ? "neighbour"
                : index.classesNeighbour(key.first, key.second, true)  ? "diagonal_neighbour"
                                                                       : "other";
        }
        f << e->experiment << ',' << fmt(tc.canonical_hold.x(), 4) << ',' << fmt(tc.canonical_hold.y(), 4) << ',' << px
          << ',' << py << ',' << rel << ',' << n << "\n";
      }
  }
  // Summary, including the thesis's case: held at the middle of the short side (0, 23 cm).
  std::ostringstream sum;
  sum << "drape_db bench" << (cfg.quick ? " --quick" : "") << ": thesis recognition experiment on held-out renders\n";
  sum << "database: towel 64x46 cm, cotton, d = " << cfg.spacing * 100 << " cm, " << builder.plan().size()
      << " hold points (" << base.hold_points.size() << " in one quadrant"
      << (cfg.bracket_hold_points ? ", each simulated at the particles of its grid cell: " +
                                        std::to_string(rep.to_simulate) + " simulations, " +
                                        std::to_string(rep.planned) + " rows with the mirrors"
                                  : std::string())
      << "), " << index.matcher.size() << " silhouettes of " << index.frame.width_px << " x "
      << index.frame.height_px << " px; shift search +-" << eo.match.max_dx << " / +-" << eo.match.max_dy
      << " px; build " << fmt(rep.wall_seconds, 1) << " s wall (" << rep.simulated_now
      << " simulations now, mean " << fmt(rep.simulated_now ? rep.simulation_seconds / rep.simulated_now : 0.0, 2)
      << " s each); held-out simulations " << fmt(heldout_s, 1) << " s\n";
  for (const auto& r : rows)
    sum << "  " << r.experiment << ": " << r.queries << " queries, exact " << fmt(100 * r.exact_rate, 1)
        << " %, exact or neighbour " << fmt(100 * r.within_one_rate, 1) << " % (8-neighbourhood "
        << fmt(100 * r.within_one_diagonal_rate, 1) << " %), top-5 " << fmt(100 * r.top5_rate, 1)
        << " %, neighbours among errors " << fmt(100 * r.neighbour_share_of_errors, 1) << " %, query "
        << fmt(r.query_ms, 3) << " ms mean / " << fmt(r.query_p95_ms, 3) << " ms p95 (" << r.silhouettes
        << " silhouettes)\n";
  if (const auto tc = index.classOf("towel", Vec2(0.0, 0.23))) {
    for (const auto* e : {&single_all, &fused_all}) {
      int n = 0, ok = 0;
      std::map<std::size_t, int> wrong;
      for (const auto& [key, c] : e->confusion)
        if (key.first == *tc) {
          n += c;
          if (key.second == *tc)
            ok += c;
          else
            wrong[key.second] += c;
        }
      sum << "  thesis case (held at the middle of the short side, " << holdText(Vec2(0.0, 0.23)) << "), "
          << e->experiment << ": " << ok << "/" << n << " exact";
      for (const auto& [cl, c] : wrong)
        sum << "; " << c << "x " << (cl == kForeignClass ? std::string("foreign") : holdText(index.classes[cl].canonical_hold));
      sum << "\n";
    }
  }
  sum << "total bench time " << fmt(std::chrono::duration<double>(Clock::now() - t_all).count(), 1) << " s\n";
  log << sum.str();
  {
    std::ofstream f(cfg.out_dir + "/match_benchmark.txt");
    f << sum.str();
  }
  log << "wrote " << cfg.out_dir << "/match_benchmark.csv, match_confusion.csv, match_benchmark.txt\n";
  return rows;
}

}  // namespace db
}  // namespace textile_handling
