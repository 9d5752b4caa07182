#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

struct sqlite3;
struct sqlite3_stmt;

namespace wm::storage {

/// A failed SQLite call; what() carries the sqlite3_errmsg text and the statement or action.
class StorageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// One open connection (RAII). Not copyable; use from one thread at a time.
class Connection {
 public:
  /// Opens (creating when `create`) the database file. @throw StorageError.
  Connection(const std::string& path, bool create);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  /// Runs one or more statements without results. @throw StorageError.
  void exec(std::string_view sql);
  sqlite3* handle() const { return db_; }
  /// Rowid of the last INSERT on this connection.
  std::int64_t last_insert_rowid() const;

 private:
  friend class Statement;
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

/// A prepared statement (RAII). Bind indices start at 1, column indices at 0. Compiled once per connection and SQL
/// text: destroying it gives the statement back to its connection's cache (a statement still in use, e.g. the same
/// SQL nested in a loop over its own rows, gets a fresh one of its own).
class Statement {
 public:
  /// @throw StorageError when the SQL does not compile.
  Statement(Connection& connection, std::string_view sql);
  ~Statement();
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  Statement& bind(int index, std::int64_t value);
  Statement& bind(int index, double value);
  Statement& bind(int index, std::string_view value);
  Statement& bind_blob(int index, const void* data, std::size_t bytes);
  Statement& bind_null(int index);
  Statement& bind(int index, const std::optional<std::string>& value);
  Statement& bind(int index, const std::optional<double>& value);
  Statement& bind(int index, const std::optional<std::int64_t>& value);

  /// Advances; true while a row is available. @throw StorageError.
  bool step();
  /// Steps a statement that returns no rows, then resets it for reuse.
  void run();
  void reset();

  std::int64_t column_int(int column) const;
  double column_double(int column) const;
  std::string column_text(int column) const;
  std::optional<std::string> column_optional_text(int column) const;
  std::optional<double> column_optional_double(int column) const;
  std::optional<std::int64_t> column_optional_int(int column) const;
  std::vector<double> column_doubles(int column) const;  // a BLOB of native doubles
  const void* column_blob(int column) const;             // valid until the next step
  std::size_t column_bytes(int column) const;

 private:
  void check(int rc, const char* what) const;
  Connection& connection_;
  sqlite3* db_ = nullptr;
  sqlite3_stmt* stmt_ = nullptr;
  std::string sql_;
  bool cached_ = false;
};

/// RAII transaction: BEGIN IMMEDIATE on construction, ROLLBACK unless commit() ran.
class Transaction {
 public:
  explicit Transaction(Connection& connection);
  ~Transaction();
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit();

 private:
  Connection& connection_;
  bool done_ = false;
};

}  // namespace wm::storage
