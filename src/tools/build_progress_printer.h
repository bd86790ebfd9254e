// Terminal progress of a drape database build, for the command-line tools (drape_db build, drape_db
// bench). The builder itself prints nothing: it reports through DrapeBuildConfig's callbacks, and this
// printer turns them into a header line per pass, a progress bar and a line per failed simulation.
// On a terminal the bar is redrawn in place ("\r"); otherwise about 20 bar lines are written per pass.
#pragma once

#include <chrono>
#include <ostream>
#include <string>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace tools {

/// Text progress bar: "[=====>    ]  12/36 simulations  elapsed 00:42  ETA 01:23", with
/// " (N failed)" after the counts when `failed` > 0. `width` is the bar width in characters. `eta_s` is
/// the builder's estimate (DrapeBuildProgress::eta_s); a negative one prints as "--:--".
std::string formatProgressBar(int done, int total, double elapsed_s, double eta_s, int failed = 0, int width = 30);

/// Prints the progress of builds to one stream. Not thread-safe by itself: the builder calls its
/// callbacks one at a time. Must outlive every build it is attached to.
class BuildProgressPrinter {
 public:
  /// `terminal`: the stream is a terminal (bar redrawn in place) rather than a file or pipe.
  BuildProgressPrinter(std::ostream& out, bool terminal);
  /// A printer on std::cerr, redrawing in place when stderr is a terminal.
  static BuildProgressPrinter forStderr();
  /// A printer of machine-readable records on std::cerr, one line per finished simulation:
  /// "th-build-progress done=D total=T eta_s=E" (DrapeBuildProgress's counts of the pass; what
  /// TextileRegistry reads from an external build, docs/build_farm.md). Failures print as in forStderr().
  static BuildProgressPrinter recordsOnStderr();

  /// Sets config's on_pass_start, on_progress, on_failure and on_pass_end to this printer (replacing
  /// any set before).
  void attach(db::DrapeBuildConfig& config);

  void passStarted(const db::DrapeBuildPass& pass);
  void progress(const db::DrapeBuildProgress& progress);
  void failed(const db::DrapeBuildFailure& failure);
  void passEnded(const db::DrapeBuildPass& pass);

 private:
  void printBar(bool final_line);

  std::ostream& out_;
  bool terminal_;
  bool records_ = false;
  db::DrapeBuildPass pass_;
  std::chrono::steady_clock::time_point started_;
  int done_ = 0;          ///< simulated rows of the pass done or failed, including those done before it
  double eta_s_ = -1;     ///< the builder's last estimate of the remaining time [s]
  int failed_ = 0;        ///< simulations of the pass that failed
  int last_printed_ = -1; ///< simulations completed at the last bar line (not a terminal)
};

}  // namespace tools
}  // namespace textile_handling
