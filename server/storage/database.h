#pragma once

// The store's view of a SQL database, the same for each engine it runs on (SQLite, the embedded default, and
// PostgreSQL): a connection runs statements with parameters ?1, ?2, … bound by index, reads their rows by column,
// and brackets writes in transactions. The store's SQL is written once against it; where the engines differ
// (schema, column types, the schema version's home, how a write transaction starts) the connection says so.
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace wm::storage {

/// A failed database call; what() carries the engine's message and the statement or action.
class StorageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Dialect { sqlite, postgresql };

namespace detail {

/// One engine's prepared statement: what Statement forwards to.
class StatementBackend {
 public:
  virtual ~StatementBackend() = default;
  virtual void bind_int(int index, std::int64_t value) = 0;
  virtual void bind_double(int index, double value) = 0;
  virtual void bind_text(int index, std::string_view value) = 0;
  virtual void bind_blob(int index, const void* data, std::size_t bytes) = 0;
  virtual void bind_null(int index) = 0;
  virtual bool step() = 0;
  /// Runs a statement whose rows nobody reads (an INSERT, UPDATE, DELETE), then resets it. An engine may send it
  /// without waiting for its answer (PostgreSQL, inside a write transaction): its error then comes at the commit.
  virtual void run() {
    step();
    reset();
  }
  virtual void reset() = 0;
  virtual bool column_is_null(int column) const = 0;
  virtual std::int64_t column_int(int column) const = 0;
  virtual double column_double(int column) const = 0;
  virtual std::string column_text(int column) const = 0;
  virtual const void* column_blob(int column) const = 0;
  virtual std::size_t column_bytes(int column) const = 0;
};

}  // namespace detail

/// One open connection. Not copyable; use from one thread at a time.
class Connection {
 public:
  virtual ~Connection() = default;
  Connection() = default;
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  virtual Dialect dialect() const = 0;
  /// Runs one or more statements without results or parameters. @throw StorageError.
  virtual void exec(std::string_view sql) = 0;
  /// A statement for `sql` (parameters ?1, ?2, …). @throw StorageError when it does not compile.
  virtual std::unique_ptr<detail::StatementBackend> prepare(const std::string& sql) = 0;
  /// Starts a write transaction (SQLite: BEGIN IMMEDIATE, so that it waits for the write lock up front).
  virtual void begin() = 0;
  /// The schema version stored with the data (0 for a new database).
  virtual int schema_version() = 0;
  /// Records the schema version; inside the migration's transaction.
  virtual void set_schema_version(int version) = 0;
};

/// A statement with its parameters and rows. Bind indices start at 1, column indices at 0.
class Statement {
 public:
  /// @throw StorageError when the SQL does not compile.
  Statement(Connection& connection, std::string_view sql);

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
  /// Runs a statement that returns no rows, then resets it for reuse. Inside a write transaction on PostgreSQL it
  /// is sent without waiting: an error it meets is thrown by the commit (which then commits nothing).
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
  std::unique_ptr<detail::StatementBackend> backend_;
};

/// RAII write transaction: begins on construction, rolls back unless commit() ran.
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
