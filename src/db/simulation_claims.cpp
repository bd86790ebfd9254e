// Claims of pending simulations by concurrent builders (HangingDrapeDatabase, "claims"): a builder takes
// a row before it simulates it, renews its claims while it runs, and the row's claim ends when its result
// or failure is stored. A builder that dies stops renewing; once its lease has run out, another builder
// takes the row over. Every claim is a write under the writers' lock, so two builders never hold one row.
// docs/database.md, "Concurrent builders".
#include <cmath>
#include <string>

#include "database_sql.h"
#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace db {

namespace {

void checkOwner(const std::string& owner) {
  if (owner.empty() || owner.size() > 200) throw InvalidInputError("claim owner must be 1 to 200 characters");
}

void checkLease(double lease_s) {
  if (!(lease_s > 0 && lease_s <= 1e6)) throw InvalidInputError("claim lease must be in (0, 1e6] s");
}

}  // namespace

bool HangingDrapeDatabase::claimSimulation(std::int64_t id, const std::string& owner, double lease_s,
                                           const std::string& dead_owner) {
  requireWritable("claimSimulation");
  checkOwner(owner);
  checkLease(lease_s);
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  {
    SqlStatement exists = conn_->prepare("SELECT 1 FROM simulations WHERE id = ?");
    exists.bind(1, id);
    if (!exists.step()) throw NotFoundError("no simulation with id " + std::to_string(id));
  }
  const std::string now = internal::epochNow(*conn_);
  SqlStatement st = conn_->prepare(
      "UPDATE simulations SET claims = claims + (CASE WHEN claimed_by = ?1 THEN 0 ELSE 1 END), claimed_by = ?1, "
      "claim_expires_at = " + now + " + ?2 WHERE id = ?3 AND status = 'pending' AND "
      "(claimed_by IS NULL OR claimed_by = ?1 OR claim_expires_at < " + now + " OR claimed_by = ?4)");
  st.bind(1, owner).bind(2, lease_s).bind(3, id).bind(4, dead_owner.empty() ? owner : dead_owner);
  st.run();
  const bool claimed = conn_->changes() == 1;
  tx.commit();
  return claimed;
}

int HangingDrapeDatabase::renewClaims(const std::string& owner, double lease_s) {
  requireWritable("renewClaims");
  checkOwner(owner);
  checkLease(lease_s);
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement st = conn_->prepare("UPDATE simulations SET claim_expires_at = " + internal::epochNow(*conn_) +
                                   " + ?1 WHERE claimed_by = ?2 AND status = 'pending'");
  st.bind(1, lease_s).bind(2, owner);
  st.run();
  const int n = conn_->changes();
  tx.commit();
  return n;
}

int HangingDrapeDatabase::releaseClaims(const std::string& owner) {
  requireWritable("releaseClaims");
  checkOwner(owner);
  std::lock_guard<std::mutex> lock(mutex_);
  SqlTransaction tx(*conn_);
  SqlStatement st = conn_->prepare(
      "UPDATE simulations SET claimed_by = NULL, claim_expires_at = NULL WHERE claimed_by = ? AND status = 'pending'");
  st.bind(1, owner);
  st.run();
  const int n = conn_->changes();
  tx.commit();
  return n;
}

HangingDrapeDatabase::ClaimState HangingDrapeDatabase::claimState(std::int64_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  SqlStatement st = conn_->prepare(
      "SELECT status, claimed_by, CASE WHEN claim_expires_at < " + internal::epochNow(*conn_) +
      " THEN 1 ELSE 0 END, claims FROM simulations WHERE id = ?");
  st.bind(1, id);
  if (!st.step()) throw NotFoundError("no simulation with id " + std::to_string(id));
  ClaimState c;
  c.status = simulationStatusFromString(st.getText(0));
  c.claimed_by = st.isNull(1) ? "" : st.getText(1);
  c.expired = st.getInt(2) != 0;
  c.claims = st.getInt(3);
  return c;
}

}  // namespace db
}  // namespace textile_handling
