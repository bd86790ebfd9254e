// farm_bench: build throughput of the MPI build farm (docs/build_farm.md) for several rank counts on
// the SQLite and the PostgreSQL backend, recognizer start-up and reload on both, and a planning table
// for a plant.
//
//   farm_bench --out DIR --drape-db EXE [--mpirun EXE] [--postgres URL] [--ranks 1,2,4] [--rounds 3]
//              [--textile towel] [--spacing 0.02] [--grid 6x6] [--load-repeats 5] [--cost-db DB]
//   farm_bench --chart-from DIR/farm_builds.csv --out DIR [--cost-db DB]   (redraws the chart and, with
//   --cost-db, the planning table from stored rows)
//
// Builds: every round runs every (backend, ranks) pair once, in one interleaved order, each on a fresh
//   database (an SQLite file, or a schema of its own on the server): `mpirun -np R drape_db build --mpi`
//   of the textile's grid. Per build: wall time, simulations run, throughput (simulations / s), and the
//   fixed cost: the same command run again on the finished database (MPI start-up, opening, planning;
//   nothing left to simulate). Speed is reported as ratios within a round (throughput with R ranks over
//   throughput with 1 rank, same backend) and the efficiency ratio / min(R, cores), for the whole wall
//   time and for the simulating part (wall time minus the fixed cost). Rows: DIR/farm_builds.csv;
//   DIR/farm_throughput.png.
// Recognizer: the last round's 1-rank database of each backend loaded by TextileRecognizer
//   --load-repeats times (start-up) and reloaded as often (reload()), the backends alternating. Rows:
//   DIR/recognizer_load.csv.
// Planning: DIR/planning.csv, hours for a plant (textiles x hold points x shapes) on N machines of 8
//   cores each, from the seconds per simulation (the median wall time of the simulated rows stored in
//   --cost-db, a database built at production settings; else of the 1-rank SQLite builds here) and the
//   simulating part's median efficiency at the most ranks, the smaller of the backends', at most 1 (a
//   build of hours has no other part worth counting).
// A benchmark, not a test: nothing here asserts timings. Set OMP_WAIT_POLICY=passive.
//
// Exit status: 0 done, 2 usage, 4 outputs cannot be written, 5 a build failed.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "textile_handling/bench/bench_chart.h"
#include "textile_handling/db/postgres_connection.h"
#include "textile_handling/recognition/textile_recognizer.h"
#include "textile_handling/sim/timing.h"

using namespace textile_handling;

namespace {

struct Options {
  std::string out, drape_db, mpirun = "mpirun", postgres, textile = "towel", grid = "6x6", chart_from;
  std::string spacing = "0.02", cost_db;
  std::vector<int> ranks = {1, 2, 4};
  int rounds = 3, load_repeats = 5;
};

struct BuildRow {
  int round = 0, ranks = 0;
  std::string backend;
  double wall_s = 0;
  int simulations = 0;
  double fixed_s = 0;  // the same command on the finished database: MPI start-up, opening, planning
  double throughput() const { return wall_s > 0 ? simulations / wall_s : 0; }
  double simulationThroughput() const { return wall_s > fixed_s ? simulations / (wall_s - fixed_s) : 0; }
};

[[noreturn]] void usage(const std::string& why) {
  std::cerr << "farm_bench: " << why
            << "\nusage: farm_bench --out DIR --drape-db EXE [--mpirun EXE] [--postgres URL] [--ranks 1,2,4] "
               "[--rounds 3] [--textile towel] [--spacing 0.02] [--grid 6x6] [--load-repeats 5]\n";
  std::exit(2);
}

Options parse(int argc, char** argv) {
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) usage("option " + a + " needs a value");
    const std::string v = argv[++i];
    if (a == "--out") o.out = v;
    else if (a == "--drape-db") o.drape_db = v;
    else if (a == "--mpirun") o.mpirun = v;
    else if (a == "--postgres") o.postgres = v;
    else if (a == "--textile") o.textile = v;
    else if (a == "--spacing") o.spacing = v;
    else if (a == "--grid") o.grid = v;
    else if (a == "--cost-db") o.cost_db = v;
    else if (a == "--chart-from") o.chart_from = v;
    else if (a == "--rounds") o.rounds = std::stoi(v);
    else if (a == "--load-repeats") o.load_repeats = std::stoi(v);
    else if (a == "--ranks") {
      o.ranks.clear();
      std::stringstream ss(v);
      for (std::string part; std::getline(ss, part, ',');) o.ranks.push_back(std::stoi(part));
    } else usage("unknown option " + a);
  }
  if (o.out.empty() || (o.drape_db.empty() && o.chart_from.empty())) usage("--out and --drape-db are required");
  if (o.rounds < 1 || o.load_repeats < 1 || o.ranks.empty()) usage("rounds, load repeats and ranks must be >= 1");
  for (int r : o.ranks)
    if (r < 1 || r > 64) usage("ranks must be in 1..64");
  return o;
}

// Runs `argv` with stdout and stderr into `log`; its exit status (-1: signal).
int run(const std::vector<std::string>& argv, const std::string& log) {
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::freopen(log.c_str(), "w", stdout);
    std::freopen(log.c_str(), "a", stderr);
    std::vector<char*> c;
    for (const auto& a : argv) c.push_back(const_cast<char*>(a.c_str()));
    c.push_back(nullptr);
    ::execvp(c[0], c.data());
    ::_exit(127);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// A fresh database of `backend` for one build: the file removed, or the schema dropped and created.
std::string freshDatabase(const Options& o, const std::string& backend, const std::string& name) {
  if (backend == "sqlite") {
    const std::string path = o.out + "/" + name + ".sqlite";
    for (const char* s : {"", "-wal", "-shm"}) std::filesystem::remove(path + s);
    return path;
  }
  db::PgConnection(o.postgres).exec("DROP SCHEMA IF EXISTS " + name + " CASCADE; CREATE SCHEMA " + name);
  return o.postgres + (o.postgres.find('?') == std::string::npos ? "?" : "&") + "options=-csearch_path%3D" + name;
}

// Throughput against ranks, one series per backend and round (its points joined in rank order).
bool writeThroughputChart(const std::string& path, const std::vector<BuildRow>& rows, const std::string& title) {
  std::vector<BuildRow> sorted = rows;
  std::sort(sorted.begin(), sorted.end(), [](const BuildRow& a, const BuildRow& b) {
    return std::tie(a.backend, a.round, a.ranks) < std::tie(b.backend, b.round, b.ranks);
  });
  std::vector<ChartPoint> points;
  for (const BuildRow& r : sorted)
    points.push_back({static_cast<double>(r.ranks), r.throughput(), "", r.backend + " round " + std::to_string(r.round)});
  std::string err;
  if (writeLineChart(path, points, "MPI ranks", "simulations per second (whole build)", title, &err)) return true;
  std::cerr << "farm_bench: chart: " << err << "\n";
  return false;
}

// The build rows of a farm_builds.csv.
std::vector<BuildRow> readBuildRows(const std::string& path) {
  std::ifstream in(path);
  std::vector<BuildRow> rows;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string f[6];
    for (auto& x : f) std::getline(ss, x, ',');
    BuildRow r;
    r.round = std::stoi(f[0]);
    r.backend = f[1];
    r.ranks = std::stoi(f[2]);
    r.wall_s = std::stod(f[3]);
    r.fixed_s = std::stod(f[4]);
    r.simulations = std::stoi(f[5]);
    rows.push_back(r);
  }
  return rows;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n == 0 ? 0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

std::string fmt(double v, int digits = 3) {
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// The planning efficiency: the simulating part's median efficiency at the most ranks, the smaller of
// the backends', at most 1 (a plant's builds run for hours; start-up does not count).
double planningEfficiency(const std::vector<BuildRow>& rows, int cores, int* ranks) {
  *ranks = 0;
  for (const BuildRow& r : rows) *ranks = std::max(*ranks, r.ranks);
  double eff = 1;
  std::map<std::string, std::vector<double>> per_backend;
  for (const BuildRow& r : rows) {
    if (r.ranks != *ranks) continue;
    for (const BuildRow& q : rows)
      if (q.round == r.round && q.backend == r.backend && q.ranks == 1 && q.simulationThroughput() > 0)
        per_backend[r.backend].push_back(r.simulationThroughput() / q.simulationThroughput() / std::min(*ranks, cores));
  }
  for (const auto& [backend, v] : per_backend) eff = std::min(eff, median(v));
  return eff;
}

// DIR/planning.csv: hours for a plant on N machines of 8 cores, from the cost per simulation (--cost-db
// or `measured`) and planningEfficiency().
void writePlanning(const Options& o, const std::vector<BuildRow>& rows, std::vector<double> seconds_per_simulation) {
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::string cost_source = "the 1-rank SQLite builds here";
  if (!o.cost_db.empty()) {
    db::DatabaseOpenOptions ro;
    ro.read_only = true;
    const db::HangingDrapeDatabase cost(o.cost_db, ro);
    seconds_per_simulation.clear();
    for (const auto& s : cost.simulations(0, db::SimulationStatus::kDone))
      if (s.source == db::MirrorKind::kIdentity && s.wall_time_s > 0) seconds_per_simulation.push_back(s.wall_time_s);
    cost_source = o.cost_db + " (" + std::to_string(seconds_per_simulation.size()) + " simulated rows)";
  }
  const double per_sim = median(seconds_per_simulation);
  int ranks = 0;
  const double efficiency = planningEfficiency(rows, cores, &ranks);
  std::ofstream plan(o.out + "/planning.csv");
  plan << "textiles,hold_points,shapes_per_hold_point,simulations,machines,cores_per_machine,efficiency,hours\n";
  for (int textiles : {10, 100, 300})
    for (int holds : {36, 121})
      for (int shapes : {1, 3})
        for (int machines : {1, 4, 16}) {
          const int cores_each = 8;
          const double sims = double(textiles) * holds * shapes;
          const double hours = sims * per_sim / (machines * cores_each * efficiency) / 3600;
          plan << textiles << "," << holds << "," << shapes << "," << sims << "," << machines << "," << cores_each << ","
               << fmt(efficiency, 2) << "," << fmt(hours, 2) << "\n";
        }
  std::printf("\nplanning: %.2f s per simulation (median of %s), efficiency %.2f (simulating part, %d ranks, the "
              "smaller backend's) -> %s/planning.csv\n",
              per_sim, cost_source.c_str(), efficiency, ranks, o.out.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  const Options o = parse(argc, argv);
  std::filesystem::create_directories(o.out);
  const int cores_here = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  if (!o.chart_from.empty()) {
    const std::vector<BuildRow> stored = readBuildRows(o.chart_from);
    if (!o.cost_db.empty()) writePlanning(o, stored, {});
    return writeThroughputChart(o.out + "/farm_throughput.png", stored,
                                "Build farm throughput (" + std::to_string(cores_here) + " cores)")
               ? 0
               : 4;
  }
  std::vector<std::string> backends = {"sqlite"};
  if (!o.postgres.empty()) backends.push_back("postgres");
  const int cores = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));

  // ---- builds, interleaved: round r runs every (backend, ranks) pair, the order rotating per round ----
  std::vector<BuildRow> rows;
  std::map<std::string, std::string> last_one_rank_db;  // backend -> setting
  std::vector<double> seconds_per_simulation;           // 1 rank, SQLite
  for (int round = 1; round <= o.rounds; ++round) {
    std::vector<std::pair<std::string, int>> order;
    for (const auto& b : backends)
      for (int r : o.ranks) order.emplace_back(b, r);
    std::rotate(order.begin(), order.begin() + (round - 1) % order.size(), order.end());
    for (const auto& [backend, ranks] : order) {
      const std::string name = "farm_" + backend + "_r" + std::to_string(ranks) + "_n" + std::to_string(round);
      const std::string setting = freshDatabase(o, backend, name);
      std::vector<std::string> cmd = {o.mpirun, "--oversubscribe", "-np", std::to_string(ranks)};
      if (::geteuid() == 0) cmd.push_back("--allow-run-as-root");
      for (const std::string& a : {o.drape_db, std::string("build"), std::string("--mpi"), std::string("--db"), setting,
                                   std::string("--textile"), o.textile, std::string("--spacing"), o.spacing,
                                   std::string("--grid"), o.grid, std::string("--quiet")})
        cmd.push_back(a);
      const auto t0 = std::chrono::steady_clock::now();
      const int rc = run(cmd, o.out + "/" + name + ".log");
      BuildRow row{round, ranks, backend, secondsSince(t0), 0, 0};
      const auto t1 = std::chrono::steady_clock::now();
      const int rc_again = run(cmd, o.out + "/" + name + "_again.log");
      row.fixed_s = secondsSince(t1);
      if (rc != 0 || rc_again != 0) {
        std::cerr << "farm_bench: build " << name << " failed (exit " << rc << ", " << rc_again << "), see " << o.out
                  << "/" << name << ".log\n";
        return 5;
      }
      db::DatabaseOpenOptions ro;
      ro.read_only = true;
      const db::HangingDrapeDatabase database(setting, ro);
      double sim_seconds = 0;
      for (const auto& s : database.simulations(0, db::SimulationStatus::kDone))
        if (s.source == db::MirrorKind::kIdentity) {
          ++row.simulations;
          sim_seconds += s.wall_time_s;
        }
      if (ranks == 1 && backend == "sqlite" && row.simulations > 0) seconds_per_simulation.push_back(sim_seconds / row.simulations);
      if (ranks == 1) last_one_rank_db[backend] = setting;
      rows.push_back(row);
      std::printf("round %d %-8s %d rank(s): %d simulations in %.1f s (%.3f /s), fixed cost %.2f s\n", round,
                  backend.c_str(), ranks, row.simulations, row.wall_s, row.throughput(), row.fixed_s);
    }
  }

  // ---- ratios within a round, the CSV and the chart ----
  std::ofstream csv(o.out + "/farm_builds.csv");
  if (!csv) return 4;
  csv << "round,backend,ranks,wall_s,fixed_s,simulations,simulations_per_s,speedup_vs_1_rank,efficiency,"
         "simulating_speedup,simulating_efficiency\n";
  std::map<std::pair<std::string, int>, std::vector<double>> speedups, sim_speedups;
  for (const BuildRow& r : rows) {
    double one = 0, one_sim = 0;
    for (const BuildRow& q : rows)
      if (q.round == r.round && q.backend == r.backend && q.ranks == 1) {
        one = q.throughput();
        one_sim = q.simulationThroughput();
      }
    const double s = one > 0 ? r.throughput() / one : 0;
    const double ss = one_sim > 0 ? r.simulationThroughput() / one_sim : 0;
    const double eff = s / std::min(r.ranks, cores);
    speedups[{r.backend, r.ranks}].push_back(s);
    sim_speedups[{r.backend, r.ranks}].push_back(ss);
    csv << r.round << "," << r.backend << "," << r.ranks << "," << fmt(r.wall_s) << "," << fmt(r.fixed_s) << ","
        << r.simulations << "," << fmt(r.throughput(), 4) << "," << fmt(s) << "," << fmt(eff) << "," << fmt(ss) << ","
        << fmt(ss / std::min(r.ranks, cores)) << "\n";
  }
  writeThroughputChart(o.out + "/farm_throughput.png", rows,
                       "Build farm throughput (" + o.textile + ", d = " + o.spacing + " m, " + std::to_string(cores) +
                           " cores)");
  std::printf("\nspeed-up over 1 rank (min / median / max over %d interleaved rounds), efficiency = median / min(ranks, %d cores):\n",
              o.rounds, cores);
  for (const auto& [key, v] : speedups) {
    const double med = median(v);
    const std::vector<double>& w = sim_speedups[key];
    const double sim_med = median(w);
    std::printf("  %-8s %d rank(s): %.2f / %.2f / %.2f, efficiency %.2f; simulating part %.2f / %.2f / %.2f, "
                "efficiency %.2f\n",
                key.first.c_str(), key.second, *std::min_element(v.begin(), v.end()), med,
                *std::max_element(v.begin(), v.end()), med / std::min(key.second, cores),
                *std::min_element(w.begin(), w.end()), sim_med, *std::max_element(w.begin(), w.end()),
                sim_med / std::min(key.second, cores));
  }

  // ---- recognizer start-up and reload, the backends alternating ----
  std::ofstream load(o.out + "/recognizer_load.csv");
  load << "repeat,backend,silhouettes,startup_s,reload_s\n";
  for (int k = 1; k <= o.load_repeats; ++k)
    for (const auto& [backend, setting] : last_one_rank_db) {
      const auto t0 = std::chrono::steady_clock::now();
      recognition::TextileRecognizer rec(setting);
      const double startup = secondsSince(t0);
      const auto t1 = std::chrono::steady_clock::now();
      rec.reload();
      const double reload = secondsSince(t1);
      load << k << "," << backend << "," << rec.silhouetteCount() << "," << fmt(startup, 4) << "," << fmt(reload, 4) << "\n";
      std::printf("recognizer %-8s: %zu silhouettes, start-up %.3f s, reload %.3f s\n", backend.c_str(),
                  rec.silhouetteCount(), startup, reload);
    }

  // ---- planning table ----
  writePlanning(o, rows, seconds_per_simulation);
  return 0;
}
