// foreign_drape_bench: recognition on drapes the database did not make (bench/include/textile_handling/
// bench/foreign_drapes.h; docs/recognition.md, "Foreign drapes").
//
//   foreign_drape_bench --database DB [--out DIR] [--holds N] [--views N] [--seed S] [--no-depth]
//                       [--workers N] [--variants NAME,NAME,...] [--max-time S] [--no-localisation]
//                       [--search-radius M] [--odd-pairs]
//
// Builds (or resumes) the held-out drapes into DIR/foreign_drapes.sqlite: N hold points per variant
// anywhere on the towel (default 6; variants: Choi-Ko; two materials; d = 0.8 cm with self-collision and
// a tilted start; Choi-Ko with self-collision and a tilted start; picked from a heap at d = 0.8 cm; and
// the thesis experiment's kind: the database's own model and material at d = 0.8 cm).
// Renders each drape from `--views` random camera azimuths (default 3) with colour, depth and noise, plus
// for each a second image after a gripper turn of 90 degrees, and recognises every image alone and every
// pair fused, with the recognizer's defaults against DB. Rows: DIR/foreign_drapes.csv (one per recognition); charts:
// DIR/foreign_hold_vs_corner.png (hold-point error against lowest-corner error, one view and two);
// DIR/foreign_corners.csv (one row per reported corner: observation, evidence, uncertainty, safe flag and
// error); DIR/foreign_calibration.{csv,png} (corner error against reported uncertainty);
// DIR/foreign_one_vs_two.png (per drape and azimuth: one image's error against two images');
// headline figures on stdout. --odd-pairs: also, per drape, one pair whose second image shows another
// drape (a hold point >= 10 cm away under every mirror): a view that really contradicts the first, rows
// in DIR/foreign_odd_pairs.csv, to set the contradiction test against the consistent pairs' coverage gaps
// (column coverage_gap of foreign_drapes.csv). A benchmark, not a test: nothing asserts. Set OMP_WAIT_POLICY=passive.
// Exit status: 0 done, 2 usage, 4 outputs cannot be written, 5 unexpected error.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/bench/foreign_drapes.h"
#include "textile_handling/sim/timing.h"

using namespace textile_handling;

namespace {

struct Options {
  std::string database, out = "out/foreign_drape_bench";
  int holds = 6, views = 3, workers = 0;
  double max_time_s = 30.0;
  std::vector<std::string> variants;  ///< empty = all
  std::uint64_t seed = 1;
  bool depth = true;
  bool localisation = true;       ///< --no-localisation: corners stay where the matched shape puts them
  double search_radius_m = -1;    ///< --search-radius M: GraspPointLocalisationOptions::search_radius_m (< 0 = default)
  bool odd_pairs = false;         ///< --odd-pairs: also pairs whose second image shows another drape
};

int usage(const std::string& problem) {
  std::cerr << "foreign_drape_bench: " << problem
            << "\nusage: foreign_drape_bench --database DB [--out DIR] [--holds N] [--views N] [--seed S] [--no-depth] "
               "[--workers N] [--variants NAME,...] [--max-time S] [--no-localisation] [--search-radius M] [--odd-pairs]\n";
  return 2;
}

struct Summary {
  int results = 0, failures = 0, hold_within_5cm = 0, lowest_within_3cm = 0, best_within_3cm = 0, all_within_5cm = 0;
  int with_safe_corner = 0, safe_corners = 0, safe_within_3cm = 0;
  std::vector<double> hold_errors, corner_errors, ms;
  /// Per reported corner: (uncertainty, error, evidence) for the calibration.
  std::vector<std::tuple<double, double, std::string>> calibration;
  void add(const bench::ForeignScore& s) {
    ++results;
    if (!s.success) {
      ++failures;
      return;
    }
    bool any_safe = false;
    for (std::size_t c = 0; c < s.corner_poses.size(); ++c) {
      const recognition::GraspPose& gp = s.corner_poses[c];
      calibration.emplace_back(gp.uncertainty_m, s.corner_error_m[c], recognition::toString(gp.evidence));
      if (!gp.safe) continue;
      any_safe = true;
      ++safe_corners;
      if (s.corner_error_m[c] <= 0.03) ++safe_within_3cm;
    }
    if (any_safe) ++with_safe_corner;
    ms.push_back(s.processing_ms);
    hold_errors.push_back(s.hold_error_m);
    if (s.hold_error_m <= 0.05) ++hold_within_5cm;
    if (s.lowest_corner_error_m >= 0 && s.lowest_corner_error_m <= 0.03) ++lowest_within_3cm;
    if (s.best_corner_error_m >= 0 && s.best_corner_error_m <= 0.03) ++best_within_3cm;
    if (s.max_corner_error_m >= 0 && s.max_corner_error_m <= 0.05) ++all_within_5cm;
    corner_errors.insert(corner_errors.end(), s.corner_error_m.begin(), s.corner_error_m.end());
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return -1;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

std::string pct(int k, int n) {
  char b[32];
  std::snprintf(b, sizeof b, "%.0f %%", n > 0 ? 100.0 * k / n : 0.0);
  return b;
}

void printSummary(const std::string& what, const Summary& s) {
  std::printf("%-10s %3d results (%d not a success): hold within 5 cm %s (median %.1f cm); corners median %.1f cm; "
              "lowest corner within 3 cm %s; best corner within 3 cm %s; all corners within 5 cm %s; %.0f ms median\n",
              what.c_str(), s.results, s.failures, pct(s.hold_within_5cm, s.results).c_str(), 100 * median(s.hold_errors),
              100 * median(s.corner_errors), pct(s.lowest_within_3cm, s.results).c_str(),
              pct(s.best_within_3cm, s.results).c_str(), pct(s.all_within_5cm, s.results).c_str(), median(s.ms));
  std::printf("%-10s at least one corner safe in %s of results; %d safe corners, %s within 3 cm\n", what.c_str(),
              pct(s.with_safe_corner, s.results).c_str(), s.safe_corners, pct(s.safe_within_3cm, s.safe_corners).c_str());
}

// Calibration of the reported uncertainty: corners binned by it (CSV) and every corner's error against
// its uncertainty (chart, with the diagonal: points below it lie within their bound).
void writeCalibration(const std::string& out, const Summary& one, const Summary& two) {
  std::ofstream csv(out + "/foreign_calibration.csv");
  csv << "views,uncertainty_from_m,uncertainty_to_m,corners,median_error_m,within_uncertainty,within_3cm\n";
  const std::vector<double> edges = {0, 0.02, 0.03, 0.05, 0.1, 0.2, 1e9};
  std::vector<ChartPoint> chart;
  for (const Summary* s : {&one, &two}) {
    const int n = s == &one ? 1 : 2;
    for (std::size_t b = 0; b + 1 < edges.size(); ++b) {
      std::vector<double> err;
      int within_u = 0, within_3 = 0;
      for (const auto& [u, e, ev] : s->calibration) {
        if (u < edges[b] || u >= edges[b + 1]) continue;
        err.push_back(e);
        within_u += e <= u;
        within_3 += e <= 0.03;
      }
      const double k = std::max<std::size_t>(1, err.size());
      csv << n << "," << edges[b] << "," << (edges[b + 1] > 1e8 ? -1 : edges[b + 1]) << "," << err.size() << ","
          << median(err) << "," << within_u / k << "," << within_3 / k << "\n";
    }
    for (const auto& [u, e, ev] : s->calibration)
      if (u > 0) chart.push_back({100 * u, std::max(0.05, 100 * e), "", ev});  // one and two images alike
  }
  for (double u = 1.0; u <= 40.0; u *= 1.25) chart.push_back({u, u, "", "error = uncertainty"});
  std::string err;
  if (!writeLogLogChart(out + "/foreign_calibration.png", chart, "reported uncertainty [cm]", "corner error [cm]",
                        "Foreign drapes: corner error against reported uncertainty", &err))
    std::cerr << "foreign_drape_bench: calibration chart: " << err << "\n";
}

// One recognition of `views` (the first image's camera is the result's frame), scored against `d`.
bench::ForeignScore recogniseViews(const recognition::TextileRecognizer& rec, const bench::ForeignDrape& d,
                                   const std::vector<bench::ForeignView>& views) {
  std::vector<recognition::CameraObservation> obs;
  for (const auto& v : views) obs.push_back(v.observation);
  bench::ForeignScore s;
  try {
    s = bench::scoreRecognition(d, views.front().camera, obs.size() == 1 ? rec.recognize(obs.front()) : rec.recognize(obs));
  } catch (const recognition::RecognitionError& e) {
    s.success = false;
    s.reason = e.what();
  }
  return s;
}

// `first` at azimuth a and `second` after the gripper turn vo.turn_deg, with their relative views set.
std::vector<bench::ForeignView> renderPair(const bench::ForeignDrape& first, const bench::ForeignDrape& second, double a,
                                           const bench::ForeignViewOptions& vo, std::uint64_t seed) {
  std::vector<bench::ForeignView> pair = {bench::renderForeignView(first, a, vo, seed),
                                          bench::renderForeignView(second, a + vo.turn_deg, vo, seed + 1)};
  pair[0].observation.relative_view_deg = 0.0;
  pair[1].observation.relative_view_deg = vo.turn_deg;
  return pair;
}

// --odd-pairs: per drape, the first image of a random azimuth fused with an image of the next drape in
// the list whose hold point lies >= 10 cm from this one's under every mirror (after the same 90 degree
// turn). Rows in DIR/foreign_odd_pairs.csv; the flag rate on stdout.
void runOddPairs(const Options& o, const std::vector<bench::ForeignDrape>& drapes, const recognition::TextileRecognizer& rec,
                 const bench::ForeignViewOptions& vo) {
  std::ofstream csv(o.out + "/foreign_odd_pairs.csv");
  csv << "variant,hold_x_m,hold_y_m,other_variant,other_hold_x_m,other_hold_y_m,hold_distance_m,azimuth_deg,success,reason,"
         "hold_error_m,one_image_hold_error_m,contradicting_images,coverage_gap,max_image_regret,confidence,safe_corners,safe_within_3cm\n";
  std::mt19937_64 rng(o.seed + 7);
  std::uniform_real_distribution<double> az(0.0, 360.0);
  int pairs = 0, flagged = 0, held = 0, held_one = 0;
  for (std::size_t i = 0; i < drapes.size(); ++i) {
    const bench::ForeignDrape& d = drapes[i];
    const bench::ForeignDrape* other = nullptr;
    double distance = 0;
    for (std::size_t k = 1; k < drapes.size() && !other; ++k) {
      distance = bench::mirrorDistance(d, drapes[(i + k) % drapes.size()].hold);
      if (distance >= 0.10) other = &drapes[(i + k) % drapes.size()];
    }
    if (!other) continue;
    const double a = az(rng);
    const std::uint64_t seed = rng();
    const std::vector<bench::ForeignView> pair = renderPair(d, *other, a, vo, seed);
    const bench::ForeignScore one = recogniseViews(rec, d, {pair[0]}), two = recogniseViews(rec, d, pair);
    int safe = 0, safe_within = 0;
    for (std::size_t c = 0; c < two.corner_poses.size(); ++c)
      if (two.corner_poses[c].safe) {
        ++safe;
        safe_within += two.corner_error_m[c] <= 0.03;
      }
    std::string reason = two.reason;
    std::replace(reason.begin(), reason.end(), '"', '\'');
    csv << d.variant << "," << d.hold.x() << "," << d.hold.y() << "," << other->variant << "," << other->hold.x() << ","
        << other->hold.y() << "," << distance << "," << a << "," << two.success << ",\"" << reason << "\","
        << two.hold_error_m << "," << one.hold_error_m << "," << two.contradicting_images << "," << two.coverage_gap << "," << two.max_image_regret << ","
        << two.confidence << "," << safe << "," << safe_within << "\n";
    ++pairs;
    flagged += two.success && two.contradicting_images > 0;
    held += two.success && two.hold_error_m >= 0 && two.hold_error_m <= 0.05;
    held_one += one.success && one.hold_error_m >= 0 && one.hold_error_m <= 0.05;
  }
  std::printf("odd pairs (second image of another drape): %d, flagged contradicting in %s; hold point within 5 cm of the "
              "first image's drape in %s (the first image alone: %s)\n",
              pairs, pct(flagged, pairs).c_str(), pct(held, pairs).c_str(), pct(held_one, pairs).c_str());
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--no-depth") {
      o.depth = false;
      continue;
    }
    if (a == "--no-localisation") {
      o.localisation = false;
      continue;
    }
    if (a == "--odd-pairs") {
      o.odd_pairs = true;
      continue;
    }
    if (i + 1 >= argc) return usage(a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--database") o.database = v;
    else if (a == "--out") o.out = v;
    else if (a == "--holds") o.holds = std::atoi(v.c_str());
    else if (a == "--views") o.views = std::atoi(v.c_str());
    else if (a == "--workers") o.workers = std::atoi(v.c_str());
    else if (a == "--seed") o.seed = std::strtoull(v.c_str(), nullptr, 10);
    else if (a == "--max-time") o.max_time_s = std::atof(v.c_str());
    else if (a == "--search-radius") o.search_radius_m = std::atof(v.c_str());
    else if (a == "--variants") {
      std::stringstream ss(v);
      for (std::string name; std::getline(ss, name, ',');) o.variants.push_back(name);
    }
    else return usage("unknown option " + a);
  }
  if (o.database.empty()) return usage("--database is required");
  if (o.holds < 1 || o.views < 1 || o.workers < 0 || !(o.max_time_s > 0))
    return usage("--holds and --views must be >= 1, --workers >= 0, --max-time > 0");
  std::error_code ec;
  std::filesystem::create_directories(o.out, ec);
  std::ofstream csv(o.out + "/foreign_drapes.csv"), corners_csv(o.out + "/foreign_corners.csv"),
      candidates_csv(o.out + "/foreign_candidates.csv");
  if (!csv || !corners_csv || !candidates_csv) {
    std::cerr << "foreign_drape_bench: cannot write " << o.out << "/foreign_drapes.csv\n";
    return 4;
  }
  try {
    bench::ForeignDrapeSetOptions so;
    so.holds_per_variant = o.holds;
    so.seed = o.seed;
    so.workers = o.workers;
    so.max_time_s = o.max_time_s;
    std::vector<bench::ForeignDrapeVariant> variants;
    for (auto& v : bench::foreignDrapeVariants(so))
      if (o.variants.empty() || std::find(o.variants.begin(), o.variants.end(), v.name) != o.variants.end())
        variants.push_back(std::move(v));
    if (variants.empty()) return usage("no variant of that name (choi_ko, stiff_light, soft_heavy, fine_collision, choi_ko_collision, heap, thesis)");
    int failed = 0;
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<bench::ForeignDrape> drapes = bench::buildForeignDrapes(
        o.out + "/foreign_drapes.sqlite", variants, &failed, [](const std::string& m) { std::cerr << m << "\n"; });
    std::cerr << drapes.size() << " held-out drapes (" << failed << " simulations failed) in "
              << secondsSince(t0) << " s\n";

    recognition::RecognizerOptions ro;
    ro.textile_name = "towel";
    ro.localisation.enabled = o.localisation;
    if (o.search_radius_m >= 0) ro.localisation.search_radius_m = o.search_radius_m;
    const recognition::TextileRecognizer rec(o.database, ro);
    bench::ForeignViewOptions vo;
    vo.depth = o.depth;
    csv << "variant,rest_reached,hold_x_m,hold_y_m,views,azimuth_deg,success,reason,hold_error_m,lowest_corner_error_m,"
           "best_corner_error_m,max_corner_error_m,mean_corner_error_m,score,confidence,processing_ms,segmentation_ms,query_ms,"
           "refine_ms,contradicting_images,coverage_gap,max_image_regret\n";
    corners_csv << "variant,views,hold_error_m,score,corner,observed,images_observed,images_in_mask,depth_gap_m,evidence,located_shift_m,"
                   "label_margin_m,located_images,uncertainty_m,safe,error_m,any_truth_corner_m,truth_surface_m,disagreeing_images,disagreement_m,"
                   "tip_angle_deg,tip_roughness_m\n";
    candidates_csv << "variant,hold_x_m,hold_y_m,views,azimuth_deg,rank,candidate_x_m,candidate_y_m,candidate_hold_error_m,score,refined\n";
    Summary one, two;
    // Corner errors split by the observation flag, per number of images.
    std::vector<double> seen_err[3], unseen_err[3];
    std::vector<ChartPoint> chart, paired;  // paired: the same drape and azimuth, one image (x) against two (y)
    std::mt19937_64 rng(o.seed + 99);
    std::uniform_real_distribution<double> az(0.0, 360.0);
    for (const bench::ForeignDrape& d : drapes) {
      for (int k = 0; k < o.views; ++k) {
        const double a = (k + az(rng) / 360.0) * 360.0 / o.views;  // stratified: every view count covers the circle
        const std::uint64_t seed = rng();
        const std::vector<bench::ForeignView> pair = renderPair(d, d, a, vo, seed);
        const bench::ForeignScore s1 = recogniseViews(rec, d, {pair[0]});
        const bench::ForeignScore s2 = recogniseViews(rec, d, pair);
        for (const auto* s : {&s1, &s2}) {
          const int n = s == &s1 ? 1 : 2;
          (n == 1 ? one : two).add(*s);
          double mean = 0;
          for (double e : s->corner_error_m) mean += e / s->corner_error_m.size();
          std::string reason = s->reason;
          std::replace(reason.begin(), reason.end(), '"', '\'');
          csv << d.variant << "," << d.rest_reached << "," << d.hold.x() << "," << d.hold.y() << "," << n << "," << a << "," << s->success << ",\""
              << reason << "\"," << s->hold_error_m << "," << s->lowest_corner_error_m << "," << s->best_corner_error_m << ","
              << s->max_corner_error_m << "," << (s->corner_error_m.empty() ? -1 : mean) << "," << s->score << ","
              << s->confidence << "," << s->processing_ms << "," << s->segmentation_ms << "," << s->query_ms << ","
              << s->refine_ms << "," << s->contradicting_images << "," << s->coverage_gap << "," << s->max_image_regret << "\n";
          for (std::size_t c = 0; c < s->corner_error_m.size(); ++c) {
            const recognition::GraspPose& gp = s->corner_poses[c];
            const auto& ob = gp.observation;
            corners_csv << d.variant << "," << n << "," << s->hold_error_m << "," << s->score << "," << s->corner_names[c] << "," << ob.observed() << ","
                        << ob.images_observed << "," << ob.images_in_mask << "," << ob.depth_gap_m << ","
                        << recognition::toString(gp.evidence) << "," << gp.located_shift_m << ","
                        << (std::isfinite(gp.label_margin_m) ? gp.label_margin_m : -1) << "," << gp.located_images << ","
                        << gp.uncertainty_m << ","
                        << gp.safe << "," << s->corner_error_m[c] << "," << s->corner_any_truth_corner_m[c] << ","
                        << s->corner_truth_surface_m[c] << "," << gp.disagreeing_images << "," << gp.disagreement_m << ","
                        << gp.tip_angle_deg << "," << gp.tip_roughness_m << "\n";
            (ob.observed() ? seen_err[n] : unseen_err[n]).push_back(s->corner_error_m[c]);
          }
          for (std::size_t rank = 0; rank < s->candidates.size(); ++rank) {
            const auto& c = s->candidates[rank];
            candidates_csv << d.variant << "," << d.hold.x() << "," << d.hold.y() << "," << n << "," << a << "," << rank << ","
                           << c.hold_point.x() << "," << c.hold_point.y() << "," << c.hold_error_m << "," << c.score << ","
                           << c.refined << "\n";
          }
          if (s->success && s->lowest_corner_error_m >= 0)
            chart.push_back({std::max(1e-3, 100 * s->hold_error_m), std::max(1e-2, 100 * s->lowest_corner_error_m), "",
                             n == 1 ? "one image" : "two images, 90 deg turn"});
        }
        if (s1.success && s2.success) {
          paired.push_back({std::max(0.05, 100 * s1.hold_error_m), std::max(0.05, 100 * s2.hold_error_m), "", "hold point"});
          if (s1.lowest_corner_error_m >= 0 && s2.lowest_corner_error_m >= 0)
            paired.push_back({std::max(0.05, 100 * s1.lowest_corner_error_m), std::max(0.05, 100 * s2.lowest_corner_error_m), "",
                              "lowest corner"});
        }
        std::cerr << d.variant << " hold (" << d.hold.x() << ", " << d.hold.y() << ") az " << a << ": one image "
                  << (s1.success ? std::to_string(100 * s1.hold_error_m) + " cm" : "failed") << ", two "
                  << (s2.success ? std::to_string(100 * s2.hold_error_m) + " cm" : "failed") << "\n";
      }
    }
    printSummary("one image", one);
    printSummary("two images", two);
    if (o.odd_pairs) runOddPairs(o, drapes, rec, vo);
    for (int n = 1; n <= 2; ++n) {
      auto within = [](const std::vector<double>& v) {
        return static_cast<int>(std::count_if(v.begin(), v.end(), [](double e) { return e <= 0.03; }));
      };
      std::printf("%d image(s): observed corners %zu (median error %.1f cm, within 3 cm %s), not observed %zu (median "
                  "%.1f cm, within 3 cm %s)\n",
                  n, seen_err[n].size(), 100 * median(seen_err[n]), pct(within(seen_err[n]), static_cast<int>(seen_err[n].size())).c_str(),
                  unseen_err[n].size(), 100 * median(unseen_err[n]),
                  pct(within(unseen_err[n]), static_cast<int>(unseen_err[n].size())).c_str());
    }
    writeCalibration(o.out, one, two);
    for (double u = 0.1; u <= 40.0; u *= 1.5) paired.push_back({u, u, "", "equal"});
    std::string err;
    if (!writeLogLogChart(o.out + "/foreign_one_vs_two.png", paired, "one image: error [cm]", "two images: error [cm]",
                          "Foreign drapes: one image against two (below the diagonal: two are better)", &err))
      std::cerr << "foreign_drape_bench: chart: " << err << "\n";
    if (!writeLogLogChart(o.out + "/foreign_hold_vs_corner.png", chart, "hold-point error [cm]",
                          "lowest-corner error [cm]", "Foreign drapes: hold point vs lowest corner", &err))
      std::cerr << "foreign_drape_bench: chart: " << err << "\n";
  } catch (const std::exception& e) {
    std::cerr << "foreign_drape_bench: " << e.what() << "\n";
    return 5;
  }
  return 0;
}
