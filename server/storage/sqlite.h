#pragma once

// SQLite, the store's embedded engine: one file, WAL, every statement compiled once per connection.
#include <string>
#include <unordered_map>

#include "server/storage/database.h"

struct sqlite3;
struct sqlite3_stmt;

namespace wm::storage {

/// One open SQLite connection (RAII).
class SqliteConnection final : public Connection {
 public:
  /// Opens (creating when `create`) the database file. @throw StorageError.
  SqliteConnection(const std::string& path, bool create);
  ~SqliteConnection() override;

  Dialect dialect() const override { return Dialect::sqlite; }
  void exec(std::string_view sql) override;
  std::unique_ptr<detail::StatementBackend> prepare(const std::string& sql) override;
  void begin() override { exec("BEGIN IMMEDIATE"); }
  int schema_version() override;  // PRAGMA user_version
  void set_schema_version(int version) override;

 private:
  friend class SqliteStatement;
  /// A compiled statement for `sql`: the cached one when it is free, else a new one (`cached` says which). Compiling
  /// costs more than running a small INSERT, and the store runs the same few statements for every request.
  sqlite3_stmt* acquire(const std::string& sql, bool& cached);
  /// Gives a cached statement back, reset and with its bindings cleared.
  void release(const std::string& sql, sqlite3_stmt* stmt);

  struct CachedStatement {
    sqlite3_stmt* stmt = nullptr;
    bool in_use = false;
  };
  sqlite3* db_ = nullptr;
  std::unordered_map<std::string, CachedStatement> statements_;
};

}  // namespace wm::storage
