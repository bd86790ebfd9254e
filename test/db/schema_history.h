// The layouts of older schema versions, derived from today's DDL, for the migration tests.
#pragma once

#include <stdexcept>
#include <string>

#include "textile_handling/db/hanging_drape_database.h"

namespace textile_handling {
namespace db {
namespace schema_history {

inline void replaceOnce(std::string* text, const std::string& what, const std::string& with) {
  const auto pos = text->find(what);
  if (pos == std::string::npos) throw std::logic_error("schema text has no '" + what + "'");
  text->replace(pos, what.size(), with);
}

/// Version 2: today's layout without grasp_points.ordinal (grasp points were read in rowid order).
inline std::string schemaV2Sql() {
  std::string s = schemaSql();
  replaceOnce(&s, "  ordinal     INTEGER NOT NULL DEFAULT 0,\n", "");
  replaceOnce(&s, "  claimed_by            TEXT,\n  claim_expires_at      REAL,\n  claims                INTEGER NOT NULL DEFAULT 0,\n", "");
  return s;
}

/// Version 1: version 2 without generations (textiles.generation, simulations.generation in the
/// UNIQUE constraint and the index, staged_generations).
inline std::string schemaV1Sql() {
  std::string s = schemaV2Sql();
  replaceOnce(&s, "  created_at     TEXT NOT NULL,\n  generation     INTEGER NOT NULL DEFAULT 0\n",
              "  created_at     TEXT NOT NULL\n");
  replaceOnce(&s, "  generation            INTEGER NOT NULL DEFAULT 0,\n", "");
  replaceOnce(&s, "UNIQUE (textile_id, generation, parameters, hold_key)", "UNIQUE (textile_id, parameters, hold_key)");
  replaceOnce(&s, "(textile_id, generation, status)", "(textile_id, status)");
  s.erase(s.find("\nCREATE TABLE staged_generations"));
  return s;
}

/// Version 0, the prototype: version 1 without views.area.
inline std::string schemaV0Sql() {
  std::string s = schemaV1Sql();
  replaceOnce(&s, "  area              INTEGER NOT NULL,\n", "");
  return s;
}

}  // namespace schema_history
}  // namespace db
}  // namespace textile_handling
