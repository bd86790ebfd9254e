#include "textile_handling/db/build_progress_records.h"

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <sstream>

namespace textile_handling {
namespace db {

namespace {

constexpr const char* kProgress = "th-build-progress ";
constexpr const char* kReport = "th-build-report ";

// The value of "key=" among a record line's words; false if absent or not a finite number.
bool recordValue(const std::string& line, const std::string& key, double* value) {
  const std::string k = " " + key + "=";
  const auto at = line.find(k);
  if (at == std::string::npos) return false;
  char* end = nullptr;
  const char* begin = line.c_str() + at + k.size();
  *value = std::strtod(begin, &end);
  return end != begin && std::isfinite(*value);
}

}  // namespace

std::string progressRecord(const DrapeBuildProgress& p) {
  std::ostringstream o;
  o << kProgress << "done=" << p.done << " total=" << p.total << " eta_s=" << p.eta_s << "\n";
  return o.str();
}

std::string reportRecord(const DrapeBuildReport& r) {
  std::ostringstream o;
  o << kReport << "generation=" << r.generation << " planned=" << r.planned << " to_simulate=" << r.to_simulate
    << " already_done=" << r.already_done << " simulated=" << r.simulated_now << " failed=" << r.failed_now
    << " derived=" << r.derived_now << " done_elsewhere=" << r.done_elsewhere << "\n";
  return o.str();
}

bool parseProgressRecord(const std::string& line, DrapeBuildProgress* p) {
  if (line.rfind(kProgress, 0) != 0) return false;
  double done = 0, total = 0, eta = -1;
  if (!recordValue(line, "done", &done) || !recordValue(line, "total", &total)) return false;
  recordValue(line, "eta_s", &eta);
  p->done = static_cast<int>(done);
  p->total = static_cast<int>(total);
  p->eta_s = eta;
  return true;
}

bool parseReportRecord(const std::string& line, DrapeBuildReport* r) {
  if (line.rfind(kReport, 0) != 0) return false;
  const char* keys[8] = {"generation", "planned", "to_simulate", "already_done", "simulated", "failed", "derived", "done_elsewhere"};
  double v[8];
  for (int k = 0; k < 8; ++k)
    if (!recordValue(line, keys[k], &v[k])) return false;
  r->generation = static_cast<std::int64_t>(v[0]);
  r->planned = static_cast<int>(v[1]);
  r->to_simulate = static_cast<int>(v[2]);
  r->already_done = static_cast<int>(v[3]);
  r->simulated_now = static_cast<int>(v[4]);
  r->failed_now = static_cast<int>(v[5]);
  r->derived_now = static_cast<int>(v[6]);
  r->done_elsewhere = static_cast<int>(v[7]);
  return true;
}

}  // namespace db
}  // namespace textile_handling
