// build_eta_replay: how right a build's ETA was, replayed from a finished database build.
//
//   build_eta_replay DATABASE [--textile NAME] [--workers N] [--out DIR]
//
// Reads the simulated (not mirrored) rows of the textile's active generation that are done or failed,
// reconstructs each simulation's start as finished_at - (wall_time_s + render_time_s), and replays the
// build's starts and finishes in time order. At every finish it compares the true remaining time (the
// last finish minus now) with two estimates: BuildTimeEstimate (the builder's, median-based with the
// running simulations credited and the queue scheduled on N workers) and the plain rate estimate
// elapsed / finished x remaining count (what the progress bar showed before). The time between a
// simulation's result and its row's finished_at (storing the views) is not in wall/render time, so
// reconstructed starts are a few milliseconds late. Rows: DIR/eta_replay.csv; chart: DIR/eta_replay.png
// (absolute error of the predicted finish time in % of the build's wall time against simulations done).
// A benchmark, not a test. Exit status: 0 done, 2 usage or no rows, 4 outputs cannot be written.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/db/build_time_estimate.h"
#include "textile_handling/db/hanging_drape_database.h"

using namespace textile_handling;

namespace {

// "2026-12-03T09:32:53.602Z" -> seconds since the epoch (UTC); NaN if it does not parse.
double isoSeconds(const std::string& text) {
  int y, mo, d, h, mi;
  double s;
  if (std::sscanf(text.c_str(), "%d-%d-%dT%d:%d:%lf", &y, &mo, &d, &h, &mi, &s) != 6) return std::nan("");
  std::tm tm{};
  tm.tm_year = y - 1900;
  tm.tm_mon = mo - 1;
  tm.tm_mday = d;
  tm.tm_hour = h;
  tm.tm_min = mi;
  return static_cast<double>(timegm(&tm)) + s;
}

struct Run {
  std::int64_t id;
  double start, finish;
};

int usage(const std::string& problem) {
  std::cerr << "build_eta_replay: " << problem
            << "\nusage: build_eta_replay DATABASE [--textile NAME] [--workers N] [--out DIR]\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage("no database given");
  std::string path = argv[1], textile, out = "out/build_eta_replay";
  int workers = 2;
  for (int i = 2; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage(a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--textile") textile = v;
    else if (a == "--out") out = v;
    else if (a == "--workers") {
      workers = std::atoi(v.c_str());
      if (workers < 1) return usage("--workers must be a positive whole number, got '" + v + "'");
    } else return usage("unknown option " + a);
  }
  std::vector<Run> runs;
  try {
    db::DatabaseOpenOptions options;
    options.read_only = true;
    options.create = false;
    db::HangingDrapeDatabase database(path, options);
    std::int64_t textile_id = 0;
    if (!textile.empty()) {
      const auto record = database.findTextile(textile);
      if (!record) return usage("no textile named '" + textile + "' in " + path);
      textile_id = record->id;
    }
    for (const db::SimulationRecord& r : database.simulations(textile_id)) {
      if (!r.active || r.source != db::MirrorKind::kIdentity || r.status == db::SimulationStatus::kPending) continue;
      const double finish = isoSeconds(r.finished_at);
      if (!std::isfinite(finish)) continue;
      runs.push_back({r.id, finish - (r.wall_time_s + r.render_time_s), finish});
    }
  } catch (const std::exception& e) {
    return usage(e.what());
  }
  if (runs.size() < 2) return usage("fewer than two finished simulated rows in " + path);
  std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) { return a.finish < b.finish; });
  double t0 = runs.front().start;
  for (const Run& r : runs) t0 = std::min(t0, r.start);
  const double end = runs.back().finish - t0;
  const int n = static_cast<int>(runs.size());

  std::error_code ec;
  std::filesystem::create_directories(out, ec);
  std::ofstream csv(out + "/eta_replay.csv");
  if (!csv) {
    std::cerr << "build_eta_replay: cannot write " << out << "/eta_replay.csv\n";
    return 4;
  }
  csv << "done,total,elapsed_s,true_remaining_s,estimate_s,rate_estimate_s,estimate_finish_error,rate_finish_error\n";
  std::vector<ChartPoint> points;
  db::BuildTimeEstimate estimate(workers, n);
  std::size_t next_start = 0;
  std::vector<Run> by_start = runs;
  std::sort(by_start.begin(), by_start.end(), [](const Run& a, const Run& b) { return a.start < b.start; });
  double worst = 0, worst_rate = 0;
  for (int k = 0; k + 1 < n; ++k) {
    const double now = runs[k].finish - t0;
    while (next_start < by_start.size() && by_start[next_start].start - t0 <= now + 1e-9) {
      estimate.started(by_start[next_start].id, by_start[next_start].start - t0);
      ++next_start;
    }
    estimate.finished(runs[k].id, now);
    const double truth = end - now, est = estimate.remainingSeconds(now), rate = now / (k + 1) * (n - k - 1);
    const double err = (now + est - end) / end, err_rate = (now + rate - end) / end;
    worst = std::max(worst, std::abs(err));
    worst_rate = std::max(worst_rate, std::abs(err_rate));
    csv << k + 1 << "," << n << "," << now << "," << truth << "," << est << "," << rate << "," << err << ","
        << err_rate << "\n";
    points.push_back({static_cast<double>(k + 1), std::max(0.1, 100 * std::abs(err)), "", "BuildTimeEstimate"});
    points.push_back({static_cast<double>(k + 1), std::max(0.1, 100 * std::abs(err_rate)), "", "rate (elapsed/done)"});
  }
  std::printf("%d simulations, %.1f s wall on %d worker(s): largest finish-time error %.1f %% (BuildTimeEstimate), "
              "%.1f %% (rate)\n",
              n, end, workers, 100 * worst, 100 * worst_rate);
  std::string error;
  if (!writeLogLogChart(out + "/eta_replay.png", points, "simulations done", "|predicted - true finish| / build time [%]",
                        "Build ETA replayed from " + path.substr(path.find_last_of('/') + 1), &error))
    std::cerr << "build_eta_replay: chart: " << error << "\n";
  return 0;
}
