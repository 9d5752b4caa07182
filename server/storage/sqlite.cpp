#include "server/storage/sqlite.h"

#include <sqlite3.h>

#include <cstring>

namespace wm::storage {

Connection::Connection(const std::string& path, bool create) {
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

Connection::~Connection() {
  for (auto& [sql, statement] : statements_) sqlite3_finalize(statement.stmt);
  sqlite3_close_v2(db_);
}

sqlite3_stmt* Connection::acquire(const std::string& sql, bool& cached) {
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

void Connection::release(const std::string& sql, sqlite3_stmt* stmt) {
  sqlite3_reset(stmt);  // its result repeats the last step's error, which the owner has seen
  sqlite3_clear_bindings(stmt);
  const auto it = statements_.find(sql);
  if (it != statements_.end() && it->second.stmt == stmt) it->second.in_use = false;
}

void Connection::exec(std::string_view sql) {
  char* error = nullptr;
  const std::string text(sql);
  if (sqlite3_exec(db_, text.c_str(), nullptr, nullptr, &error) != SQLITE_OK) {
    std::string message = error ? error : sqlite3_errmsg(db_);
    sqlite3_free(error);
    throw StorageError("sqlite: " + message + " (in: " + text.substr(0, 80) + ")");
  }
}

Statement::Statement(Connection& connection, std::string_view sql)
    : connection_(connection), db_(connection.handle()), sql_(sql) {
  stmt_ = connection_.acquire(sql_, cached_);
}

Statement::~Statement() {
  if (cached_)
    connection_.release(sql_, stmt_);
  else
    sqlite3_finalize(stmt_);
}

void Statement::check(int rc, const char* what) const {
  if (rc != SQLITE_OK)
    throw StorageError(std::string("sqlite ") + what + ": " + sqlite3_errmsg(db_) + " (in: " + sql_.substr(0, 80) +
                       ")");
}

Statement& Statement::bind(int index, std::int64_t value) {
  check(sqlite3_bind_int64(stmt_, index, value), "bind");
  return *this;
}
Statement& Statement::bind(int index, double value) {
  check(sqlite3_bind_double(stmt_, index, value), "bind");
  return *this;
}
Statement& Statement::bind(int index, std::string_view value) {
  check(sqlite3_bind_text(stmt_, index, value.data(), static_cast<int>(value.size()), SQLITE_TRANSIENT), "bind");
  return *this;
}
Statement& Statement::bind_blob(int index, const void* data, std::size_t bytes) {
  check(sqlite3_bind_blob(stmt_, index, data, static_cast<int>(bytes), SQLITE_TRANSIENT), "bind");
  return *this;
}
Statement& Statement::bind_null(int index) {
  check(sqlite3_bind_null(stmt_, index), "bind");
  return *this;
}
Statement& Statement::bind(int index, const std::optional<std::string>& value) {
  return value ? bind(index, std::string_view(*value)) : bind_null(index);
}
Statement& Statement::bind(int index, const std::optional<double>& value) {
  return value ? bind(index, *value) : bind_null(index);
}
Statement& Statement::bind(int index, const std::optional<std::int64_t>& value) {
  return value ? bind(index, *value) : bind_null(index);
}

bool Statement::step() {
  const int rc = sqlite3_step(stmt_);
  if (rc == SQLITE_ROW) return true;
  if (rc == SQLITE_DONE) return false;
  throw StorageError(std::string("sqlite step: ") + sqlite3_errmsg(db_) + " (in: " + sql_.substr(0, 80) + ")");
}

void Statement::run() {
  step();
  reset();
}

void Statement::reset() {
  sqlite3_reset(stmt_);
  sqlite3_clear_bindings(stmt_);
}

std::int64_t Statement::column_int(int column) const { return sqlite3_column_int64(stmt_, column); }
double Statement::column_double(int column) const { return sqlite3_column_double(stmt_, column); }
std::string Statement::column_text(int column) const {
  const auto* text = sqlite3_column_text(stmt_, column);
  return text ? std::string(reinterpret_cast<const char*>(text),
                            static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column)))
              : std::string();
}
std::optional<std::string> Statement::column_optional_text(int column) const {
  if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return std::nullopt;
  return column_text(column);
}
std::optional<double> Statement::column_optional_double(int column) const {
  if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return std::nullopt;
  return column_double(column);
}
std::optional<std::int64_t> Statement::column_optional_int(int column) const {
  if (sqlite3_column_type(stmt_, column) == SQLITE_NULL) return std::nullopt;
  return column_int(column);
}
std::int64_t Connection::last_insert_rowid() const { return sqlite3_last_insert_rowid(db_); }

const void* Statement::column_blob(int column) const { return sqlite3_column_blob(stmt_, column); }

std::size_t Statement::column_bytes(int column) const {
  return static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column));
}

std::vector<double> Statement::column_doubles(int column) const {
  const auto bytes = static_cast<std::size_t>(sqlite3_column_bytes(stmt_, column));
  std::vector<double> values(bytes / sizeof(double));
  if (!values.empty()) std::memcpy(values.data(), sqlite3_column_blob(stmt_, column), values.size() * sizeof(double));
  return values;
}

Transaction::Transaction(Connection& connection) : connection_(connection) { connection_.exec("BEGIN IMMEDIATE"); }

Transaction::~Transaction() {
  if (!done_) {
    try {
      connection_.exec("ROLLBACK");
    } catch (const StorageError&) {
      // The transaction may already be gone (SQLite rolls back on some errors itself).
    }
  }
}

void Transaction::commit() {
  connection_.exec("COMMIT");
  done_ = true;
}

}  // namespace wm::storage
