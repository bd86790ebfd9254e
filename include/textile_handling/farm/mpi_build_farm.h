// The MPI build farm: one drape database build spread over the ranks of an MPI job
// (`mpirun -np N drape_db build --mpi ...`, several machines with a hostfile). ROS-free; the only part
// of the package that links MPI (Debian's OpenMPI). docs/build_farm.md.
//
//  * SQLite database (a file path): rank 0 opens the file, plans, claims, derives mirror rows and stores;
//    every rank, rank 0 included, simulates. A rank is given its next hold point when it returns the
//    last one (dynamic scheduling); results travel as THSO messages (simulation_outcome_codec.h).
//  * PostgreSQL database (a URL): every rank is a builder of its own on the shared database and the
//    rows are shared out by claims (HangingDrapeDatabase::claimSimulation); each rank stores its own.
// A build that dies (any rank, or the whole job) is resumed by running the same command again: done
// rows stay done, rows a dead builder had claimed are taken over when their lease runs out.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "textile_handling/db/drape_database_builder.h"

namespace textile_handling {
namespace farm {

/// The MPI environment of a process (MPI_Init_thread with MPI_THREAD_SERIALIZED; MPI_Finalize when it
/// ends). One per process. Throws std::runtime_error if MPI cannot give serialized threading.
class MpiSession {
 public:
  MpiSession(int* argc, char*** argv);
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;
  int rank() const { return rank_; }
  int size() const { return size_; }
  /// Rank 0's `text` on every rank (the others' argument is ignored); call it on all ranks. For
  /// input only rank 0's machine has (a build-job file).
  std::string broadcastText(const std::string& text) const;
  /// Ends every rank of the job at once (after a fatal error on one of them).
  [[noreturn]] void abort(int exit_code) const;

 private:
  int rank_ = 0, size_ = 1;
};

/// What a farm build is given: the database setting and one configuration per member build (the same
/// on every rank: every rank parses the same command line).
struct FarmBuildInput {
  std::string database;                        ///< SQLite file path or postgresql:// URL
  std::vector<db::DrapeBuildConfig> members;   ///< one build each, in order
  /// Rank 0 only: called before member k's build starts with the configuration it will use (attach
  /// progress printers here).
  std::function<void(std::size_t member, db::DrapeBuildConfig& config)> on_member_start;
};

/// Every member's report; on rank 0 summed over all ranks (PostgreSQL) or as rank 0's builder saw the
/// whole farm (SQLite); on the other ranks their own part.
struct FarmBuildResult {
  std::vector<db::DrapeBuildReport> reports;
  int ranks = 1;
  bool shared_database = false;  ///< PostgreSQL: every rank wrote
};

/// Runs the build on every rank of `session` (call it on all of them). Throws DrapeDatabaseError,
/// InvalidInputError (on the rank that failed; the caller aborts the job).
FarmBuildResult runFarmBuild(const MpiSession& session, FarmBuildInput input);

}  // namespace farm
}  // namespace textile_handling
