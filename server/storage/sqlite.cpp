#include "server/storage/sqlite.h"

#include <sqlite3.h>

namespace wm::storage {

/// A statement compiled once per connection and SQL text: destroying it gives it back to its connection's cache (a
/// statement still in use, e.g. the same SQL nested in a loop over its own rows, gets a fresh one of its own).
class SqliteStatement final : public detail::StatementBackend {
 public:
  SqliteStatement(SqliteConnection& connection, const std::string& sql)
      : connection_(connection), db_(connection.db_), sql_(sql) {
    stmt_ = connection_.acquire(sql_, cached_);
  }
  ~SqliteStatement() override {
    if (cached_)
      connection_.release(sql_, stmt_);
    else
      sqlite3_finalize(stmt_);
  }
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;

  void bind_int(int index, std::int64_t value) override { check(sqlite3_bind_int64(stmt_, index, value)); }
  void bind_double(int index, double value) override { check(sqlite3_bind_double(stmt_, index, value)); }
  void bind_text(int index, std::string_view value) override {
    check(sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT));
  }
  void bind_blob(int index, const void* data, std::size_t bytes) override {
    check(sqlite3_bind_blob(stmt_, index, data, static_cast<int>(bytes), SQLITE_TRANSIENT));
  }
  void bind_null(int index) override { check(sqlite3_bind_null(stmt_, index)); }

  bool step() override {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    throw StorageError(std::string("sqlite step: ") + sqlite3_errmsg(db_) + " (in: " + sql_.substr(0, 80) + ")");
  }
  void reset() override {
    sqlite3_reset(stmt_);
    sqlite3_clear_bindings(stmt_);
  }

  bool column_is_null(int column) const override { return sqlite3_column_type(stmt_, column) == SQLITE_NULL; }
  std::int64_t column_int(int column) const override { return sqlite3_column_int64(stmt_, column); }
  double column_double(int column) const override { return sqlite3_column_double(stmt_, column); }
  std::string column_text(int column) const override {
    const auto* text = sqlite3_column_text(stmt_, column);
    return text ? std::string(reinterpret_cast<const char*>(text),
                              static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column)))
                : std::string();
  }
  const void* column_blob(int column) const override { return sqlite3_column_blob(stmt_, column); }
  std::size_t column_bytes(int column) const override {
    return static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column));
  }

 private:
  void check(int rc) const {
    if (rc != SQLITE_OK)
      throw StorageError(std::string("sqlite bind: ") + sqlite3_errmsg(db_) + " (in: " + sql_.substr(0, 80) + ")");
  }
  SqliteConnection& connection_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;
  bool cached_ = false;
};

SqliteConnection::SqliteConnection(const std::string& path, bool create) {
  const int flags = SQLITE_OPEN_READWRITE | (create ? SQLITE_OPEN_CREATE : 0) | SQLITE_OPEN_FULLMUTEX;
  const int rc = sqlite3_open_v2(path.c_str(), &db_, flags, nullptr);
  if (rc != SQLITE_OK) {
    std::string message = db_ ? sqlite3_errmsg(db_) : sqlite3_errstr(rc);
    sqlite3_close(db_);
    db_ = nullptr;
    throw StorageError("cannot open database '" + path + "': " + message);
  }
  sqlite3_extended_result_codes(db_, 1);
  // Another process (a backup, the sqlite3 shell) may hold the lock briefly; wait instead of failing.
  sqlite3_busy_timeout(db_, 5000);
}

SqliteConnection::~SqliteConnection() {
  for (auto& [sql, statement] : statements_) sqlite3_finalize(statement.stmt);
  sqlite3_close_v2(db_);
}

std::unique_ptr<detail::StatementBackend> SqliteConnection::prepare(const std::string& sql) {
  return std::make_unique<SqliteStatement>(*this, sql);
}

sqlite3_stmt* SqliteConnection::acquire(const std::string& sql, bool& cached) {
  auto it = statements_.find(sql);
  if (it != statements_.end() && !it->second.in_use) {
    it->second.in_use = true;
    cached = true;
    return it->second.stmt;
  }
  sqlite3_stmt* stmt = nullptr;
  const int rc = sqlite3_prepare_v2(db_, sql.c_str(), static_cast<int>(sql.size()), &stmt, nullptr);
  if (rc != SQLITE_OK) {
    sqlite3_finalize(stmt);
    throw StorageError(std::string("sqlite prepare: ") + sqlite3_errmsg(db_) + " (in: " + sql.substr(0, 80) + ")");
  }
  cached = it == statements_.end();
  if (cached) statements_.emplace(sql, CachedStatement{stmt, true});
  return stmt;
}

void SqliteConnection::release(const std::string& sql, sqlite3_stmt* stmt) {
  sqlite3_reset(stmt);  // its result repeats the last step's error, which the owner has seen
  sqlite3_clear_bindings(stmt);
  const auto it = statements_.find(sql);
  if (it != statements_.end() && it->second.stmt == stmt) it->second.in_use = false;
}

void SqliteConnection::exec(std::string_view sql) {
  char* error = nullptr;
  const std::string text(sql);
  if (sqlite3_exec(db_, text.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    std::string message = error ? error : sqlite3_errmsg(db_);
    sqlite3_free(error);
    throw StorageError("sqlite: " + message + " (in: " + text.substr(0, 80) + ")");
  }
}

int SqliteConnection::schema_version() {
  SqliteStatement s(*this, "PRAGMA user_version");
  s.step();
  return static_cast<int>(s.column_int(0));
}

void SqliteConnection::set_schema_version(int version) { exec("PRAGMA user_version = " + std::to_string(version)); }

}  // namespace wm::storage
