// The libpq wrappers (db/postgres_connection.h) against a real PostgreSQL server: the one named by
// TH_TEST_POSTGRES_URL (scripts/test.sh starts one for the whole run), else a throw-away server this
// test starts itself (test_database.h, ThrowawayPostgres). No server is a failure, not a skip: CI installs
// PostgreSQL (scripts/setup.sh). Each test works in a schema of its own, so runs can share a server.
#include <gtest/gtest.h>

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "../test_support.h"
#include "../tools/tool_process.h"
#include "test_database.h"
#include "textile_handling/db/hanging_drape_database.h"
#include "textile_handling/db/postgres_connection.h"

using namespace textile_handling;
using namespace textile_handling::db;

namespace {

/// The throw-away server script's stdout (its URL on start), or its stderr on failure; at most 120 s.
std::string runServerScript(const std::vector<std::string>& args, bool* ok) {
  const tool_process::ToolRun r = tool_process::runTool("/bin/bash", args);
  *ok = r.exit_code == 0;
  std::string text = *ok ? r.out : r.err + r.out;
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  return text;
}

const std::string kScript = std::string(TEXTILE_HANDLING_SOURCE_DIR) + "/scripts/throwaway_postgres.sh";

class PostgresConnectionTest : public ::testing::Test {
 protected:
  void SetUp() override {
    try {
      url_ = test_support::ThrowawayPostgres::url();
    } catch (const std::exception& e) {
      FAIL() << e.what();
    }
    schema_ = "t_" + std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name();
    for (char& c : schema_) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    conn_ = std::make_unique<PgConnection>(url_);
    conn_->exec("DROP SCHEMA IF EXISTS " + schema_ + " CASCADE; CREATE SCHEMA " + schema_ + "; SET search_path TO " +
                schema_);
  }
  void TearDown() override {
    if (!conn_) return;
    try {
      PgConnection c(url_);
      c.exec("DROP SCHEMA IF EXISTS " + schema_ + " CASCADE");
    } catch (const PostgresError&) {
    }
  }
  /// A second connection working in this test's schema.
  PgConnection another() const {
    PgConnection c(url_);
    c.exec("SET search_path TO " + schema_);
    return c;
  }

  std::string url_;
  std::string schema_;
  std::unique_ptr<PgConnection> conn_;
};


}  // namespace

TEST(PostgresUrl, SettingsAndRedaction) {
  EXPECT_TRUE(isPostgresUrl("postgresql://db.plant:5432/drapes"));
  EXPECT_TRUE(isPostgresUrl("postgres://u@h/d"));
  EXPECT_FALSE(isPostgresUrl("/var/lib/drapes.sqlite"));
  EXPECT_FALSE(isPostgresUrl("drapes.sqlite"));
  EXPECT_FALSE(isPostgresUrl("mysql://h/d"));
  EXPECT_EQ(redactedUrl("postgresql://cell:s3cret@db.plant:5432/drapes"), "postgresql://cell:***@db.plant:5432/drapes");
  EXPECT_EQ(redactedUrl("postgresql://cell@db.plant/drapes"), "postgresql://cell@db.plant/drapes");
  EXPECT_EQ(redactedUrl("postgresql://db.plant:5432/drapes"), "postgresql://db.plant:5432/drapes");
}

TEST(PostgresUrl, ADrapeDatabaseUrlConnectsToAServerAndNeverCreatesAFileOfThatName) {
  const std::string cwd = std::filesystem::current_path().string();
  const std::string dir = test_support::freshTempDir("th_pg_url");
  std::filesystem::current_path(dir);
  try {
    HangingDrapeDatabase db("postgresql://cell:s3cret@127.0.0.1:1/drapes");
    ADD_FAILURE() << "opened a database on port 1";
  } catch (const PostgresError& e) {
    EXPECT_TRUE(e.connectionLost()) << e.what();
    EXPECT_NE(std::string(e.what()).find("127.0.0.1:1"), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).find("s3cret"), std::string::npos) << e.what();
  }
  std::filesystem::current_path(cwd);
  EXPECT_TRUE(std::filesystem::is_empty(dir));
  std::filesystem::remove_all(dir);
}

TEST(PostgresUrl, AnUnreachableServerIsAConnectionErrorWithoutThePassword) {
  // Port 1 on the loopback refuses at once.
  try {
    PgConnection c("postgresql://cell:s3cret@127.0.0.1:1/drapes", 2);
    FAIL() << "connected to port 1";
  } catch (const PostgresError& e) {
    const std::string m = e.what();
    EXPECT_TRUE(e.connectionLost());
    EXPECT_NE(m.find("cannot connect"), std::string::npos) << m;
    EXPECT_NE(m.find("127.0.0.1:1"), std::string::npos) << m;
    EXPECT_EQ(m.find("s3cret"), std::string::npos) << m;
  }
  EXPECT_THROW(PgConnection("/tmp/drapes.sqlite"), PostgresError);
}

TEST_F(PostgresConnectionTest, ValuesRoundTripExactly) {
  conn_->exec("CREATE TABLE v (id BIGSERIAL PRIMARY KEY, i BIGINT, r DOUBLE PRECISION, t TEXT, b BYTEA)");
  const std::vector<std::uint8_t> bytes = {0, 1, 2, 0, 255, 92, 39, 0};  // zeros, a backslash, a quote
  const double third = 1.0 / 3.0;
  const std::string text = "hold 'corner' \\ \xc3\xa9t\xc3\xa9";  // quotes, a backslash, UTF-8
  PgResult ins = conn_->query("INSERT INTO v (i, r, t, b) VALUES ($1, $2, $3, $4) RETURNING id",
                              {PgParam(std::int64_t{-9007199254740993}), PgParam(third), PgParam(text), PgParam::bytes(bytes)});
  ASSERT_EQ(ins.rows(), 1);
  const std::int64_t id = ins.getInt(0, 0);
  conn_->query("INSERT INTO v (i, r, t, b) VALUES ($1, $2, $3, $4)",
               {PgParam::null(), PgParam(std::nan("")), PgParam(""), PgParam::bytes({})});
  const PgResult r = conn_->query("SELECT i, r, t, b FROM v WHERE id = $1", {PgParam(id)});
  ASSERT_EQ(r.rows(), 1);
  EXPECT_EQ(r.getInt(0, 0), -9007199254740993);
  EXPECT_EQ(r.getDouble(0, 1), third);  // bit-exact
  EXPECT_EQ(r.getText(0, 2), text);
  EXPECT_EQ(r.getBytes(0, 3), bytes);
  const PgResult n = conn_->query("SELECT i, r, t, b FROM v WHERE id <> $1", {PgParam(id)});
  ASSERT_EQ(n.rows(), 1);
  EXPECT_TRUE(n.isNull(0, 0));
  EXPECT_TRUE(std::isnan(n.getDouble(0, 1)));
  EXPECT_EQ(n.getText(0, 2), "");
  EXPECT_TRUE(n.getBytes(0, 3).empty());
  EXPECT_THROW(n.getInt(0, 0), PostgresError);  // NULL
  EXPECT_THROW(n.getInt(0, 2), PostgresError);  // not an integer
  EXPECT_THROW(n.getText(1, 0), PostgresError);  // no such row
  EXPECT_EQ(conn_->queryInt("SELECT count(*) FROM v"), 2);
  EXPECT_EQ(conn_->queryInt("SELECT i FROM v WHERE false", 7), 7);
}

TEST_F(PostgresConnectionTest, FailedStatementsNameTheirStateAndStatement) {
  conn_->exec("CREATE TABLE u (k TEXT PRIMARY KEY)");
  conn_->query("INSERT INTO u VALUES ($1)", {PgParam("corner")});
  try {
    conn_->query("INSERT INTO u VALUES ($1)", {PgParam("corner")});
    FAIL() << "duplicate key accepted";
  } catch (const PostgresError& e) {
    EXPECT_EQ(e.sqlstate(), "23505");
    EXPECT_FALSE(e.connectionLost());
    EXPECT_NE(std::string(e.what()).find("INSERT INTO u"), std::string::npos) << e.what();
  }
  try {
    conn_->exec("SELEC 1");
    FAIL() << "syntax error accepted";
  } catch (const PostgresError& e) {
    EXPECT_EQ(e.sqlstate(), "42601");
  }
  try {
    conn_->query("SELECT * FROM no_such_table");
    FAIL();
  } catch (const PostgresError& e) {
    EXPECT_EQ(e.sqlstate(), "42P01");
  }
  EXPECT_TRUE(conn_->isOk());  // a failed statement leaves the connection usable
  EXPECT_EQ(conn_->queryInt("SELECT count(*) FROM u"), 1);
}

TEST_F(PostgresConnectionTest, ATransactionRollsBackUnlessCommitted) {
  conn_->exec("CREATE TABLE s (n INT)");
  try {
    PgTransaction tx(*conn_);
    conn_->query("INSERT INTO s VALUES (1)");
    throw std::runtime_error("simulation failed");
  } catch (const std::runtime_error&) {
  }
  EXPECT_FALSE(conn_->inTransaction());
  EXPECT_EQ(conn_->queryInt("SELECT count(*) FROM s"), 0);
  {
    PgTransaction tx(*conn_);
    conn_->query("INSERT INTO s VALUES (2)");
    tx.commit();
  }
  PgConnection other = another();
  EXPECT_EQ(other.queryInt("SELECT count(*) FROM s"), 1);  // committed: visible to another connection
}

TEST_F(PostgresConnectionTest, SkipLockedHandsEachClaimerADifferentJob) {
  // The claim a shared build will use: two builders each lock one pending job; neither waits for the
  // other and no job is taken twice.
  conn_->exec("CREATE TABLE jobs (id INT PRIMARY KEY, state TEXT NOT NULL)");
  conn_->exec("INSERT INTO jobs SELECT g, 'pending' FROM generate_series(1, 3) g");
  const std::string claim =
      "SELECT id FROM jobs WHERE state = 'pending' ORDER BY id LIMIT 1 FOR UPDATE SKIP LOCKED";
  PgConnection b = another();
  {
    PgTransaction ta(*conn_), tb(b);
    const PgResult ra = conn_->query(claim);
    const PgResult rb = b.query(claim);
    ASSERT_EQ(ra.rows(), 1);
    ASSERT_EQ(rb.rows(), 1);
    EXPECT_EQ(ra.getInt(0, 0), 1);
    EXPECT_EQ(rb.getInt(0, 0), 2);
    conn_->query("UPDATE jobs SET state = 'done' WHERE id = $1", {PgParam(ra.getInt(0, 0))});
    ta.commit();
    // b fails before committing: its transaction rolls back and its job is free again.
  }
  EXPECT_EQ(conn_->queryInt("SELECT count(*) FROM jobs WHERE state = 'pending'"), 2);
  PgTransaction tc(b);
  const PgResult rc = b.query(claim);
  ASSERT_EQ(rc.rows(), 1);
  EXPECT_EQ(rc.getInt(0, 0), 2);
}

TEST_F(PostgresConnectionTest, AConnectionKilledByTheServerSaysItWasLost) {
  PgConnection victim = another();
  const std::int64_t pid = victim.queryInt("SELECT pg_backend_pid()");
  conn_->query("SELECT pg_terminate_backend($1)", {PgParam(pid)});
  try {
    victim.query("SELECT 1");
    FAIL() << "a terminated connection answered";
  } catch (const PostgresError& e) {
    EXPECT_TRUE(e.connectionLost()) << e.what();
    EXPECT_NE(std::string(e.what()).find("connection lost"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(victim.isOk());
}

TEST_F(PostgresConnectionTest, ListenersHearCommittedNotificationsOnly) {
  // How a recognizer learns that a builder changed the database.
  PgConnection listener = another();
  const std::string channel = schema_ + "_changed";
  listener.listen(channel);
  EXPECT_FALSE(listener.waitForNotification(0));  // nothing yet, no wait
  {
    PgTransaction tx(*conn_);
    conn_->notify(channel, "textile towel generation 3");
    EXPECT_FALSE(listener.waitForNotification(200));  // not before the commit
    tx.commit();
  }
  const auto n = listener.waitForNotification(5000);
  ASSERT_TRUE(n);
  EXPECT_EQ(n->channel, channel);
  EXPECT_EQ(n->payload, "textile towel generation 3");
  EXPECT_GT(n->sender_pid, 0);
  {
    PgTransaction tx(*conn_);
    conn_->notify(channel, "rolled back");
  }  // rolled back: never delivered
  EXPECT_FALSE(listener.waitForNotification(300));
  // Channel names are checked before any SQL is sent.
  EXPECT_THROW(listener.listen("x; DROP TABLE jobs"), InvalidInputError);
  EXPECT_THROW(conn_->notify("Upper", "p"), InvalidInputError);
  EXPECT_THROW(conn_->notify(channel, std::string(8000, 'p')), InvalidInputError);
}

TEST(PostgresServerLoss, ADrapeDatabaseHandleCarriesOnAfterItsServerRestarts) {
  // A server of this test's own: it is stopped and started again in the middle.
  const std::string dir = test_support::freshTempDir("th_pg_restart");
  bool ok = false;
  const std::string url = runServerScript({kScript, "start", dir}, &ok);
  ASSERT_TRUE(ok) << url;
  const std::size_t colon = url.rfind(':'), slash = url.rfind('/');
  const std::string port = url.substr(colon + 1, slash - colon - 1);
  HangingDrapeDatabase db(url);
  const std::int64_t textile = db.addTextile(presetTextile("towel"), Material::cotton());
  NewSimulation row;
  row.textile_id = textile;
  row.hold = Vec2(0.1, 0.1);
  row.integrator = "semi_implicit";
  row.spacing = 0.04;
  row.parameters = "p: 1\n";
  db.addSimulations({row});

  runServerScript({kScript, "stop", dir}, &ok);
  ASSERT_TRUE(ok);
  // The server is away: a typed error that says the connection is lost; the handle stays usable.
  try {
    db.counts();
    ADD_FAILURE() << "counted rows of a stopped server";
  } catch (const PostgresError& e) {
    EXPECT_TRUE(e.connectionLost()) << e.what();
  }
  EXPECT_THROW(db.counts(), PostgresError);

  const std::string again = runServerScript({kScript, "start", dir, port}, &ok);
  ASSERT_TRUE(ok) << again;
  EXPECT_EQ(again, url);
  // Back: the handle reconnects by itself, nothing stored before is lost, and it writes again.
  EXPECT_EQ(db.counts().simulations, 1);
  row.hold = Vec2(0.2, 0.1);
  EXPECT_EQ(db.addSimulations({row}).size(), 1u);
  EXPECT_EQ(db.counts().simulations, 2);
  EXPECT_EQ(db.textile(textile).outline.name, "towel");
  // A restart while the handle is idle goes unnoticed: the first statement meets the dropped connection
  // and is sent again on a new one.
  runServerScript({kScript, "stop", dir}, &ok);
  ASSERT_TRUE(ok);
  runServerScript({kScript, "start", dir, port}, &ok);
  ASSERT_TRUE(ok);
  EXPECT_EQ(db.counts().simulations, 2);
  runServerScript({kScript, "stop", dir}, &ok);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
}
