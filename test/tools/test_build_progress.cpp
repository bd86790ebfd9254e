// The tools' build progress printer (src/tools/build_progress_printer.h): the bar text and what a pass
// prints to a stream that is not a terminal, driven through the builder's callbacks.
#include <gtest/gtest.h>

#include <algorithm>
#include <sstream>
#include <string>

#include "build_progress_printer.h"

using namespace textile_handling;
using textile_handling::tools::BuildProgressPrinter;
using textile_handling::tools::formatProgressBar;

TEST(BuildProgress, ProgressBar) {
  EXPECT_EQ(formatProgressBar(0, 10, 0.0, -1.0, 0, 10), "[>         ] 0/10 simulations  elapsed 00:00  ETA --:--");
  EXPECT_EQ(formatProgressBar(5, 10, 62.0, 75.4, 0, 10), "[=====>    ] 5/10 simulations  elapsed 01:02  ETA 01:15");
  EXPECT_EQ(formatProgressBar(10, 10, 3725.0, 12.0, 2, 10),
            "[==========] 10/10 simulations (2 failed)  elapsed 1:02:05  ETA 00:00");
}

namespace {
db::DrapeBuildProgress progressOf(int done, int total, double eta_s) {
  db::DrapeBuildProgress p;
  p.done = done;
  p.total = total;
  p.eta_s = eta_s;
  return p;
}

db::DrapeBuildPass pass(int to_run) {
  db::DrapeBuildPass p;
  p.textile = "towel";
  p.planned = 12;
  p.to_simulate = 4;
  p.already_done = 4 - to_run;
  p.to_run = to_run;
  p.workers = 2;
  p.threads_per_simulation = 1;
  p.symmetry = "xy";
  p.symmetric_grid = true;
  return p;
}

// The lines of `text` with the elapsed/ETA clocks cut off (they depend on timing).
std::string withoutClocks(const std::string& text) {
  std::istringstream in(text);
  std::string line, out;
  while (std::getline(in, line)) {
    const auto e = line.find("  elapsed");
    out += (e == std::string::npos ? line : line.substr(0, e)) + "\n";
  }
  return out;
}

}  // namespace

TEST(BuildProgress, TheBarShowsTheBuildersEstimate) {
  std::ostringstream out;
  BuildProgressPrinter printer(out, false);
  db::DrapeBuildConfig c;
  printer.attach(c);
  c.on_pass_start(pass(4));
  c.on_progress(progressOf(1, 4, 3599.6));
  EXPECT_NE(out.str().find("1/4 simulations  elapsed 00:00  ETA 1:00:00\n"), std::string::npos) << out.str();
}

TEST(BuildProgress, PrintsHeaderBarsAndFailuresThroughTheCallbacks) {
  std::ostringstream out;
  BuildProgressPrinter printer(out, false);
  db::DrapeBuildConfig c;
  printer.attach(c);
  const db::DrapeBuildPass p = pass(3);
  c.on_pass_start(p);
  c.on_progress(progressOf(2, 4, 10));
  c.on_failure({17, Vec2(0.1, 0.2), "no rest within max_time 1 s"});
  c.on_progress(progressOf(3, 4, 5));
  c.on_progress(progressOf(4, 4, 0));
  c.on_pass_end(p);
  EXPECT_EQ(withoutClocks(out.str()),
            "drape_db: towel: 12 hold points (4 simulated, symmetry xy), 1 already done, 3 to run on 2 worker(s) x 1 "
            "thread(s)\n"
            "[=======>                      ] 1/4 simulations\n"
            "[===============>              ] 2/4 simulations\n"
            "drape_db: simulation 17 failed: no rest within max_time 1 s\n"
            "[======================>       ] 3/4 simulations (1 failed)\n"
            "[==============================] 4/4 simulations (1 failed)\n");
}

TEST(BuildProgress, APassWithNothingToRunPrintsNothing) {
  std::ostringstream out;
  BuildProgressPrinter printer(out, true);
  db::DrapeBuildConfig c;
  printer.attach(c);
  c.on_pass_start(pass(0));
  c.on_pass_end(pass(0));
  EXPECT_EQ(out.str(), "");
}

TEST(BuildProgress, OnATerminalTheBarIsRedrawnInPlace) {
  std::ostringstream out;
  BuildProgressPrinter printer(out, true);
  db::DrapeBuildConfig c;
  printer.attach(c);
  c.on_pass_start(pass(1));
  c.on_progress(progressOf(4, 4, 0));
  c.on_pass_end(pass(1));
  const std::string s = out.str();
  EXPECT_EQ(std::count(s.begin(), s.end(), '\r'), 3);
  EXPECT_EQ(s.back(), '\n');
}
