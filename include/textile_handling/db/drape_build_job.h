// A database build as a file (a "build job"): how TextileRegistry hands one of its builds to an external
// builder, `drape_db build --job FILE` (alone or as every rank of `mpirun ... drape_db build --mpi --job
// FILE`; docs/build_farm.md, "The drape simulator node on a farm"). The file carries the whole
// DrapeBuildConfig that decides what is stored (textile, material, hold points, simulation, model, views,
// target generation) and the database members, so the external build writes exactly the rows the
// registry's own worker would; callbacks, the claim owner and the remote simulator stay behind.
//
// Format: YAML, `format: textile_handling_build_job 1` first; docs/build_farm.md lists the keys.
#pragma once

#include <cstddef>
#include <string>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace db {

/// Largest build-job file [bytes]: a textile of kMaxOutlineVertices vertices and a material fit easily.
constexpr std::size_t kMaxBuildJobBytes = std::size_t{4} << 20;

struct DrapeBuildJob {
  DrapeBuildConfig config;
  /// The database members to build, as drapeMembersByName() reads them ("base", "base,tilted", ...).
  std::string members = "base";
};

/// The job as file text. Throws InvalidInputError if the text would not give back the same build (the
/// writer reads its own output and compares every parameter text and every execution setting), naming
/// what differs, or if `members` is not a valid member list.
std::string drapeBuildJobText(const DrapeBuildJob& job);

/// Reads drapeBuildJobText() output. Missing keys keep DrapeBuildConfig's defaults. Throws
/// InvalidInputError naming the key at fault for malformed YAML, an unknown key or format, a value of the
/// wrong type, a non-finite number, an invalid outline, material or model, or a text over
/// kMaxBuildJobBytes.
DrapeBuildJob parseDrapeBuildJob(const std::string& text);

/// parseDrapeBuildJob() of a file; the error names the file. Refuses files over kMaxBuildJobBytes (and
/// non-regular files) before reading them.
DrapeBuildJob loadDrapeBuildJob(const std::string& path);

/// Writes drapeBuildJobText(job) to `path` through a temporary file and a rename, so a reader never sees
/// half a job. Throws InvalidInputError (as drapeBuildJobText) or OutputError if it cannot be written.
void saveDrapeBuildJob(const DrapeBuildJob& job, const std::string& path);

}  // namespace db
}  // namespace textile_handling
