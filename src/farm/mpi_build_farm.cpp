// The MPI build farm (mpi_build_farm.h): rank 0 as the SQLite store's only writer with every rank
// simulating, or every rank a claiming builder of a shared PostgreSQL database.
#include "textile_handling/farm/mpi_build_farm.h"

#include <mpi.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstdint>
#include <map>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "textile_handling/db/postgres_connection.h"
#include "textile_handling/db/simulation_outcome_codec.h"

namespace textile_handling {
namespace farm {

namespace {

// Message tags between rank 0 and the simulating ranks.
constexpr int kTagJob = 1;     // rank 0 -> worker: int64[4] = member, corner, plan index, simulation id
constexpr int kTagResult = 2;  // worker -> rank 0: THSO bytes
constexpr int kTagStop = 3;    // rank 0 -> worker: no more jobs (empty)

// Rank 0's side of the SQLite farm: slot 0 simulates here, slot k on rank k. Every MPI call is made under
// one mutex (MPI_THREAD_SERIALIZED); a slot's thread polls for its answer, sleeping between polls, so the
// other slots' threads are never held up by a long wait.
class MpiRemoteSimulator final : public db::RemoteSimulator {
 public:
  MpiRemoteSimulator(int ranks, std::size_t member) : ranks_(ranks), member_(member) {}
  void setLocal(const db::DrapeDatabaseBuilder* builder) { local_ = builder; }
  int slots() const override { return ranks_; }

  db::SimulationOutcome simulate(int slot, int corner, std::size_t plan_index, std::int64_t id) override {
    if (slot == 0) return local_->simulateHoldPoint(corner, plan_index, id);
    const std::int64_t job[4] = {static_cast<std::int64_t>(member_), corner, static_cast<std::int64_t>(plan_index), id};
    {
      std::lock_guard<std::mutex> lock(mpi_);
      MPI_Send(job, 4, MPI_INT64_T, slot, kTagJob, MPI_COMM_WORLD);
    }
    for (;;) {
      {
        std::lock_guard<std::mutex> lock(mpi_);
        int ready = 0;
        MPI_Status st;
        MPI_Iprobe(slot, kTagResult, MPI_COMM_WORLD, &ready, &st);
        if (ready) {
          int bytes = 0;
          MPI_Get_count(&st, MPI_BYTE, &bytes);
          std::vector<std::uint8_t> msg(static_cast<std::size_t>(std::max(bytes, 0)));
          MPI_Recv(msg.data(), bytes, MPI_BYTE, slot, kTagResult, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
          return db::decodeSimulationOutcome(msg.data(), msg.size(), "rank " + std::to_string(slot));
        }
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
  }

 private:
  int ranks_;
  std::size_t member_;
  const db::DrapeDatabaseBuilder* local_ = nullptr;
  static std::mutex mpi_;
};

std::mutex MpiRemoteSimulator::mpi_;

// A simulating rank of the SQLite farm: answers rank 0's jobs until told to stop.
void serveJobs(const std::vector<db::DrapeBuildConfig>& members, int rank) {
  // One simulation per rank at a time: its OpenMP threads as configured, else one (several ranks usually
  // share a machine's cores).
  omp_set_num_threads(std::max(1, members.front().threads_per_simulation));
  std::map<std::size_t, std::unique_ptr<db::DrapeDatabaseBuilder>> builders;  // made on first use
  for (;;) {
    MPI_Status st;
    MPI_Probe(0, MPI_ANY_TAG, MPI_COMM_WORLD, &st);
    if (st.MPI_TAG == kTagStop) {
      MPI_Recv(nullptr, 0, MPI_BYTE, 0, kTagStop, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
      return;
    }
    std::int64_t job[4] = {0, 0, 0, 0};
    MPI_Recv(job, 4, MPI_INT64_T, 0, kTagJob, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    db::SimulationOutcome out;
    std::vector<std::uint8_t> msg;
    try {
      const auto member = static_cast<std::size_t>(job[0]);
      if (job[0] < 0 || member >= members.size()) throw db::InvalidInputError("job of unknown member " + std::to_string(job[0]));
      auto& b = builders[member];
      if (!b) b = std::make_unique<db::DrapeDatabaseBuilder>(members[member]);
      out = b->simulateHoldPoint(static_cast<int>(job[1]), static_cast<std::size_t>(job[2]), job[3]);
      msg = db::encodeSimulationOutcome(out);
    } catch (const std::exception& e) {
      // A job this rank cannot run (or a result the codec refuses) fails that row, not the farm.
      db::SimulationOutcome failed;
      failed.result.simulation_id = job[3];
      failed.failure = "rank " + std::to_string(rank) + ": " + e.what();
      msg = db::encodeSimulationOutcome(failed);
    }
    MPI_Send(msg.data(), static_cast<int>(msg.size()), MPI_BYTE, 0, kTagResult, MPI_COMM_WORLD);
  }
}

// Rank 0 of the SQLite farm: the builder of every member, its simulations spread over all ranks.
std::vector<db::DrapeBuildReport> leadSqliteFarm(const MpiSession& session, FarmBuildInput& input) {
  db::HangingDrapeDatabase database(input.database);
  std::vector<db::DrapeBuildReport> reports;
  for (std::size_t k = 0; k < input.members.size(); ++k) {
    db::DrapeBuildConfig c = input.members[k];
    auto remote = std::make_shared<MpiRemoteSimulator>(session.size(), k);
    c.remote = remote;
    if (input.on_member_start) input.on_member_start(k, c);
    db::DrapeDatabaseBuilder builder(database, c);
    remote->setLocal(&builder);
    reports.push_back(builder.build());
  }
  for (int r = 1; r < session.size(); ++r) MPI_Send(nullptr, 0, MPI_BYTE, r, kTagStop, MPI_COMM_WORLD);
  return reports;
}

// Every rank of the PostgreSQL farm: a builder of its own; rank 0's reports become the sums.
std::vector<db::DrapeBuildReport> buildOnSharedDatabase(const MpiSession& session, FarmBuildInput& input) {
  db::HangingDrapeDatabase database(input.database);
  std::vector<db::DrapeBuildReport> reports;
  for (std::size_t k = 0; k < input.members.size(); ++k) {
    db::DrapeBuildConfig c = input.members[k];
    if (session.rank() == 0 && input.on_member_start) input.on_member_start(k, c);
    db::DrapeBuildReport r = db::DrapeDatabaseBuilder(database, c).build();
    // What each rank ran, summed on rank 0 (the plan counts are the same on every rank).
    const double mine[5] = {double(r.simulated_now), double(r.failed_now), double(r.derived_now),
                            r.simulation_seconds, double(r.failures.size())};
    double sum[5] = {0, 0, 0, 0, 0};
    MPI_Reduce(mine, sum, 5, MPI_DOUBLE, MPI_SUM, 0, MPI_COMM_WORLD);
    // Failure texts of the other ranks, so rank 0 can print them.
    for (int from = 1; from < session.size(); ++from) {
      if (session.rank() == from) {
        std::string text;
        for (const auto& f : r.failures) text += f + '\n';
        MPI_Send(text.data(), static_cast<int>(text.size()), MPI_CHAR, 0, kTagResult, MPI_COMM_WORLD);
      } else if (session.rank() == 0) {
        MPI_Status st;
        MPI_Probe(from, kTagResult, MPI_COMM_WORLD, &st);
        int n = 0;
        MPI_Get_count(&st, MPI_CHAR, &n);
        std::string text(static_cast<std::size_t>(n), '\0');
        MPI_Recv(text.data(), n, MPI_CHAR, from, kTagResult, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        for (std::size_t a = 0, b; (b = text.find('\n', a)) != std::string::npos; a = b + 1)
          r.failures.push_back(text.substr(a, b - a));
      }
    }
    if (session.rank() == 0) {
      r.simulated_now = static_cast<int>(sum[0]);
      r.failed_now = static_cast<int>(sum[1]);
      r.derived_now = static_cast<int>(sum[2]);
      r.simulation_seconds = sum[3];
      r.done_elsewhere = 0;  // every rank's work is in the sums
    }
    reports.push_back(std::move(r));
  }
  return reports;
}

}  // namespace

MpiSession::MpiSession(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_SERIALIZED, &provided);
  if (provided < MPI_THREAD_SERIALIZED) {
    MPI_Finalize();
    throw std::runtime_error("this MPI library gives no MPI_THREAD_SERIALIZED threading");
  }
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
}

MpiSession::~MpiSession() { MPI_Finalize(); }

std::string MpiSession::broadcastText(const std::string& text) const {
  std::uint64_t size = rank_ == 0 ? text.size() : 0;
  MPI_Bcast(&size, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
  if (size > (std::uint64_t{1} << 30)) throw std::runtime_error("broadcastText: more than 1 GiB");
  std::string out = rank_ == 0 ? text : std::string(size, '\0');
  if (size > 0) MPI_Bcast(out.data(), static_cast<int>(size), MPI_CHAR, 0, MPI_COMM_WORLD);
  return out;
}

void MpiSession::abort(int exit_code) const {
  MPI_Abort(MPI_COMM_WORLD, exit_code);
  std::_Exit(exit_code);  // MPI_Abort does not return; in case an implementation does
}

FarmBuildResult runFarmBuild(const MpiSession& session, FarmBuildInput input) {
  if (input.members.empty()) throw db::InvalidInputError("farm build: no member builds");
  FarmBuildResult out;
  out.ranks = session.size();
  out.shared_database = db::isPostgresUrl(input.database);
  if (out.shared_database) {
    out.reports = buildOnSharedDatabase(session, input);
  } else if (session.rank() == 0) {
    out.reports = leadSqliteFarm(session, input);
  } else {
    serveJobs(input.members, session.rank());
  }
  return out;
}

}  // namespace farm
}  // namespace textile_handling
