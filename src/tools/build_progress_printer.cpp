#include "build_progress_printer.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>

#include "textile_handling/db/build_progress_records.h"
#include "textile_handling/sim/timing.h"

namespace textile_handling {
namespace tools {

namespace {

std::string clockText(double s) {
  if (!std::isfinite(s) || s < 0) return "--:--";
  const long t = std::lround(s);
  char buf[32];
  if (t >= 3600)
    std::snprintf(buf, sizeof buf, "%ld:%02ld:%02ld", t / 3600, (t / 60) % 60, t % 60);
  else
    std::snprintf(buf, sizeof buf, "%02ld:%02ld", t / 60, t % 60);
  return buf;
}

}  // namespace

std::string formatProgressBar(int done, int total, double elapsed_s, double eta_s, int failed, int width) {
  const double frac = total > 0 ? std::min(1.0, static_cast<double>(done) / total) : 1.0;
  const int filled = static_cast<int>(std::floor(frac * width));
  std::string bar = "[";
  for (int k = 0; k < width; ++k) bar += k < filled ? '=' : (k == filled ? '>' : ' ');
  if (filled >= width) bar.back() = '=';
  bar += "]";
  char buf[160];
  const double eta = done >= total ? 0.0 : eta_s;
  std::snprintf(buf, sizeof buf, " %d/%d simulations%s  elapsed %s  ETA %s", done, total,
                failed > 0 ? (" (" + std::to_string(failed) + " failed)").c_str() : "", clockText(elapsed_s).c_str(),
                clockText(eta).c_str());
  return bar + buf;
}

BuildProgressPrinter::BuildProgressPrinter(std::ostream& out, bool terminal) : out_(out), terminal_(terminal) {}

BuildProgressPrinter BuildProgressPrinter::forStderr() { return BuildProgressPrinter(std::cerr, isatty(fileno(stderr)) != 0); }

BuildProgressPrinter BuildProgressPrinter::recordsOnStderr() {
  BuildProgressPrinter p(std::cerr, false);
  p.records_ = true;
  return p;
}

void BuildProgressPrinter::attach(db::DrapeBuildConfig& config) {
  config.on_pass_start = [this](const db::DrapeBuildPass& p) { passStarted(p); };
  config.on_progress = [this](const db::DrapeBuildProgress& p) { progress(p); };
  config.on_failure = [this](const db::DrapeBuildFailure& f) { failed(f); };
  config.on_pass_end = [this](const db::DrapeBuildPass& p) { passEnded(p); };
}

void BuildProgressPrinter::passStarted(const db::DrapeBuildPass& p) {
  pass_ = p;
  started_ = std::chrono::steady_clock::now();
  done_ = p.already_done;
  eta_s_ = -1;
  failed_ = 0;
  last_printed_ = -1;
  if (p.to_run == 0 || records_) return;  // nothing to run: no header, no bar
  out_ << "drape_db: " << p.textile
       << (p.bracket_corner >= 0
               ? " (bracket corner " + std::to_string(p.bracket_corner) + " of the hold points' grid cells)"
               : "")
       << ": " << p.planned << " hold points (" << p.to_simulate << " simulated, symmetry " << p.symmetry
       << (p.symmetric_grid ? "" : ", no mirroring") << "), " << p.already_done << " already done, " << p.to_run
       << " to run on " << p.workers << " worker(s) x " << p.threads_per_simulation << " thread(s)\n";
  printBar(false);
}

void BuildProgressPrinter::progress(const db::DrapeBuildProgress& p) {
  done_ = p.done;
  eta_s_ = p.eta_s;
  if (records_) {
    // One write per line, so that no other output (or mpirun's forwarding) splits it.
    out_ << db::progressRecord(p) << std::flush;
    return;
  }
  printBar(false);
}

void BuildProgressPrinter::failed(const db::DrapeBuildFailure& f) {
  ++failed_;
  if (terminal_) out_ << "\n";  // keep the bar line that was being redrawn
  out_ << "drape_db: simulation " << f.simulation_id << " failed: " << f.reason << "\n";
}

void BuildProgressPrinter::passEnded(const db::DrapeBuildPass& p) {
  if (p.to_run > 0 && !records_) printBar(true);
}

void BuildProgressPrinter::printBar(bool final_line) {
  const int completed = done_ - pass_.already_done;
  const int runs = pass_.to_run;
  const std::string bar = formatProgressBar(done_, pass_.to_simulate, secondsSince(started_), eta_s_, failed_, 30);
  if (terminal_) {
    out_ << "\r" << bar << (final_line ? "\n" : "") << std::flush;
  } else if ((final_line && completed != last_printed_) ||
             (!final_line && (runs <= 20 || completed % std::max(1, runs / 20) == 0))) {
    out_ << bar << "\n" << std::flush;
    last_printed_ = completed;
  }
}

}  // namespace tools
}  // namespace textile_handling
