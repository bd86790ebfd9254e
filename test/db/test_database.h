// The database a database test works on, on the backend under test: an SQLite file (default) or, with
// TH_TEST_DATABASE_BACKEND=postgres, a schema of its own on a PostgreSQL server. The server is the one
// named by TH_TEST_POSTGRES_URL (scripts/test.sh starts one for the whole run), else a throw-away server
// this process starts once with scripts/throwaway_postgres.sh and stops at exit. No server is a failure,
// not a skip: CI installs PostgreSQL (scripts/setup.sh).
#pragma once

#include <gtest/gtest.h>

#include <cctype>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "../test_support.h"
#include "../tools/tool_process.h"
#include "textile_handling/db/postgres_connection.h"

namespace textile_handling {
namespace test_support {

/// True when this run tests the PostgreSQL backend (TH_TEST_DATABASE_BACKEND=postgres).
inline bool testingPostgres() {
  const char* b = std::getenv("TH_TEST_DATABASE_BACKEND");
  return b && std::string(b) == "postgres";
}

/// Skips a test that is about SQLite files (WAL, damaged files, file migrations) in a PostgreSQL run.
#define TH_SQLITE_FILES_ONLY()                                                                      \
  do {                                                                                              \
    if (::textile_handling::test_support::testingPostgres()) GTEST_SKIP() << "tests SQLite files";  \
  } while (0)

/// A throw-away PostgreSQL server, started on first use and stopped when the process ends.
class ThrowawayPostgres {
 public:
  static const std::string& url() {
    static ThrowawayPostgres server;
    if (server.url_.empty()) throw std::runtime_error(server.error_);
    return server.url_;
  }

 private:
  ThrowawayPostgres() {
    if (const char* env = std::getenv("TH_TEST_POSTGRES_URL"); env && *env) {
      url_ = env;
      return;
    }
    dir_ = freshTempDir("th_pg_server");
    const tool_process::ToolRun r = tool_process::runTool("/bin/bash", {script(), "start", dir_});
    std::string out = r.out;
    while (!out.empty() && (out.back() == '\n' || out.back() == ' ')) out.pop_back();
    if (r.exit_code == 0)
      url_ = out;
    else
      error_ = "throwaway_postgres.sh start failed: " + r.err + r.out;
  }
  ~ThrowawayPostgres() {
    if (dir_.empty()) return;
    if (!url_.empty()) tool_process::runTool("/bin/bash", {script(), "stop", dir_});
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  static std::string script() { return std::string(TEXTILE_HANDLING_SOURCE_DIR) + "/scripts/throwaway_postgres.sh"; }

  std::string url_, dir_, error_;
};

/// The URL of schema `schema` on the server of `server_url` (libpq's `options=-csearch_path=`).
inline std::string schemaUrl(const std::string& server_url, const std::string& schema) {
  return server_url + (server_url.find('?') == std::string::npos ? "?" : "&") + "options=-csearch_path%3D" + schema;
}

/// The database setting (file path or URL) of one test's database, empty and removed again afterwards.
class TestDatabase {
 public:
  explicit TestDatabase(const std::string& name) : file_(name) {
    if (!testingPostgres()) return;
    schema_ = "t" + std::to_string(::getpid()) + "_" + name;
    for (char& c : schema_) {
      c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9'))) c = '_';
    }
    server_ = ThrowawayPostgres::url();
    db::PgConnection(server_).exec("DROP SCHEMA IF EXISTS " + schema_ + " CASCADE; CREATE SCHEMA " + schema_);
    url_ = schemaUrl(server_, schema_);
  }
  ~TestDatabase() {
    if (schema_.empty()) return;
    try {
      db::PgConnection(server_).exec("DROP SCHEMA IF EXISTS " + schema_ + " CASCADE");
    } catch (const std::exception&) {
      // The server went away; its schemas go with it.
    }
  }
  TestDatabase(const TestDatabase&) = delete;
  TestDatabase& operator=(const TestDatabase&) = delete;

  /// What HangingDrapeDatabase is given: the SQLite file's path or the PostgreSQL URL.
  const std::string& path() const { return schema_.empty() ? file_.path() : url_; }
  bool isPostgres() const { return !schema_.empty(); }

 private:
  TempDatabase file_;  // unused (never created) in a PostgreSQL run
  std::string schema_, server_, url_;
};

}  // namespace test_support
}  // namespace textile_handling
