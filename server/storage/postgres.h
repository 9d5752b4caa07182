#pragma once

// PostgreSQL, the store's engine beyond one machine (libpq, the PostgreSQL project's own client library). Each map
// lives in a schema of its own in one database; a connection's search_path names it (and `public`, where PostGIS is).
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "server/storage/database.h"
#include "server/storage/leases.h"

struct pg_conn;

namespace wm::storage {

/// Whether `path` names a PostgreSQL database (a postgresql:// or postgres:// connection URI) rather than a file.
bool is_postgres_uri(std::string_view path);

/// A schema name the store accepts: 1-63 of [a-z0-9_-], starting with a letter or '_'.
bool is_valid_schema_name(std::string_view name);
/// `name` as a quoted SQL identifier. @throw StorageError when is_valid_schema_name refuses it.
std::string quoted_schema(const std::string& name);

/// One open PostgreSQL connection (RAII), with `schema` first on its search_path.
class PostgresConnection final : public Connection {
 public:
  /// Connects, and when `create` makes the schema (and the PostGIS extension in `public`) if missing.
  /// @throw StorageError (a message without the password).
  PostgresConnection(const std::string& uri, const std::string& schema, bool create);
  ~PostgresConnection() override;

  Dialect dialect() const override { return Dialect::postgresql; }
  void exec(std::string_view sql) override;
  std::unique_ptr<detail::StatementBackend> prepare(const std::string& sql) override;
  /// Begins a write transaction in libpq's pipeline mode: its writes (Statement::run) are sent without waiting for
  /// their answers, which the commit collects, one round trip for the whole transaction instead of one per write.
  void begin() override;
  int schema_version() override;  // the row of table schema_version, 0 when there is none
  /// From now on every write transaction begins by checking, in it, that `fence` still holds its map's lease
  /// (wm_cluster.fence); one that does not commits nothing and throws FencedError.
  void set_fence(const Fence& fence);
  void set_schema_version(int version) override;

 private:
  /// A fenced connection: named after its lease (fence_session_name), by which a node taking it over ends it should it
  /// stall inside a transaction; and the database ends a transaction idle on this client for half the lease.
  void limit_stalls();
  friend class PostgresStatement;
  /// The name of the server-side prepared statement for `sql`, prepared on first use. @throw StorageError.
  std::string prepared(const std::string& sql);
  bool pipelining() const { return pipelining_; }
  /// Sends a prepared statement's run in the pipeline.
  void send(const std::string& name, const std::vector<const char*>& values, const std::vector<int>& lengths,
            const std::vector<int>& formats, const std::string& sql);
  /// Ends the pipeline: waits for every answer sent, leaves pipeline mode. @throw StorageError with the first error.
  void finish_pipeline();
  /// When the connection was lost (the server restarted), connects again before the next statement or transaction.
  /// @throw StorageError when the server does not answer.
  void reconnect_if_lost();

  pg_conn* conn_ = nullptr;
  std::string schema_;
  std::unordered_map<std::string, std::string> prepared_;  // SQL text -> statement name
  std::int64_t statements_made_ = 0;
  bool pipelining_ = false;
  bool in_transaction_ = false;
  std::optional<Fence> fence_;
  std::vector<std::string> prepared_in_pipeline_;  // SQL texts
  std::string first_sent_sql_;  // a pipelined statement, for the message of an error the commit meets
};

}  // namespace wm::storage
