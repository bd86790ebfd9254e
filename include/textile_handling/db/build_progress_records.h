// Machine-readable lines of a build's progress (`drape_db build --progress-records`), written by drape_db
// and read by TextileRegistry from an external build (docs/build_farm.md). One place for the format:
//   th-build-progress done=D total=T eta_s=E
//   th-build-report generation=G planned=P to_simulate=T already_done=A simulated=S failed=F derived=X done_elsewhere=E
#pragma once

#include <string>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace db {

/// The progress line of `p` (newline included).
std::string progressRecord(const DrapeBuildProgress& p);
/// The report line of one member build `r` (newline included; no textile id, failures or times).
std::string reportRecord(const DrapeBuildReport& r);
/// Reads a progressRecord() line into *p; false (and *p unchanged) for any other line.
bool parseProgressRecord(const std::string& line, DrapeBuildProgress* p);
/// Reads a reportRecord() line into *r (its counts and generation; the other fields as they are); false
/// (and *r unchanged) for any other line.
bool parseReportRecord(const std::string& line, DrapeBuildReport* r);

}  // namespace db
}  // namespace textile_handling
