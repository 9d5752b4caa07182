#include "server/storage/postgres.h"

#include <libpq-fe.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <vector>

namespace wm::storage {
namespace {

// The bytea type's OID (pg_type.h): its columns come as hex text.
constexpr Oid kBytea = 17;

// The store's SQL numbers its parameters ?1, ?2, … (SQLite); PostgreSQL's are $1, $2, …. Quoted text is left alone.
std::string dollar_parameters(const std::string& sql) {
  std::string out;
  out.reserve(sql.size());
  char quote = 0;
  for (const char c : sql) {
    if (quote) {
      if (c == quote) quote = 0;
    } else if (c == '\'' || c == '"') {
      quote = c;
    } else if (c == '?') {
      out += '$';
      continue;
    }
    out += c;
  }
  return out;
}

std::string error_text(const PGresult* result, pg_conn* conn) {
  std::string message = result ? PQresultErrorMessage(result) : PQerrorMessage(conn);
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  return message;
}

void ignore_notice(void*, const char*) {}

}  // namespace

bool is_postgres_uri(std::string_view path) {
  return path.starts_with("postgresql://") || path.starts_with("postgres://");
}

bool is_valid_schema_name(std::string_view name) {
  if (name.empty() || name.size() > 63 || !((name[0] >= 'a' && name[0] <= 'z') || name[0] == '_')) return false;
  for (const char c : name)
    if (!((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-')) return false;
  return true;
}

std::string quoted_schema(const std::string& name) {
  if (!is_valid_schema_name(name))
    throw StorageError("postgresql: '" + name + "' is not a schema name the store uses (1-63 of [a-z0-9_-])");
  return '"' + name + '"';
}

/// A statement run as a server-side prepared statement (parsed once per connection; the server infers each
/// parameter's type from where it stands), its parameters sent as numbers in text or as bytes (text and bytea), its
/// rows read as text (bytea as hex, decoded on demand).
class PostgresStatement final : public detail::StatementBackend {
 public:
  PostgresStatement(PostgresConnection& connection, std::string sql)
      : connection_(connection), sql_(std::move(sql)), name_(connection.prepared(sql_)) {}
  ~PostgresStatement() override { PQclear(result_); }
  PostgresStatement(const PostgresStatement&) = delete;
  PostgresStatement& operator=(const PostgresStatement&) = delete;

  void bind_int(int index, std::int64_t value) override { set(index, std::to_string(value), 0); }
  void bind_double(int index, double value) override {
    if (std::isnan(value)) return set(index, "NaN", 0);
    if (std::isinf(value)) return set(index, value > 0 ? "Infinity" : "-Infinity", 0);
    char text[32];
    const auto end = std::to_chars(text, text + sizeof text, value).ptr;  // the shortest text that reads back exact
    set(index, std::string(text, end), 0);
  }
  // Text and bytes go as they are, with their length: a NUL in text is refused by the server, not cut short.
  void bind_text(int index, std::string_view value) override { set(index, std::string(value), 1); }
  void bind_blob(int index, const void* data, std::size_t bytes) override {
    set(index, std::string(static_cast<const char*>(data), bytes), 1);
  }
  void bind_null(int index) override {
    slot(index);
    params_[static_cast<std::size_t>(index - 1)].reset();
  }

  void run() override {
    if (!connection_.pipelining()) {
      step();
      reset();
      return;
    }
    std::vector<const char*> values(params_.size());
    std::vector<int> lengths(params_.size());
    for (std::size_t i = 0; i < params_.size(); ++i) {
      values[i] = params_[i] ? params_[i]->data() : nullptr;
      lengths[i] = params_[i] ? static_cast<int>(params_[i]->size()) : 0;
    }
    connection_.send(name_, values, lengths, formats_, sql_);
    reset();
  }

  bool step() override {
    if (connection_.pipelining()) connection_.finish_pipeline();  // a read needs its answer now
    if (!result_) execute();
    ++row_;
    decoded_.assign(static_cast<std::size_t>(PQnfields(result_)), std::nullopt);
    return row_ < PQntuples(result_);
  }
  void reset() override {
    PQclear(result_);
    result_ = nullptr;
    row_ = -1;
    params_.clear();
    formats_.clear();
  }

  bool column_is_null(int column) const override { return PQgetisnull(result_, row_, column) != 0; }
  std::int64_t column_int(int column) const override {
    if (column_is_null(column)) return 0;
    const char* text = PQgetvalue(result_, row_, column);
    std::int64_t value = 0;
    std::from_chars(text, text + PQgetlength(result_, row_, column), value);
    return value;
  }
  double column_double(int column) const override {
    if (column_is_null(column)) return 0;
    const char* text = PQgetvalue(result_, row_, column);
    const int length = PQgetlength(result_, row_, column);
    const std::string_view value(text, static_cast<std::size_t>(length));
    if (value == "Infinity") return HUGE_VAL;
    if (value == "-Infinity") return -HUGE_VAL;
    double number = 0;
    std::from_chars(text, text + length, number);  // "NaN" reads as NaN
    return number;
  }
  std::string column_text(int column) const override {
    return std::string(PQgetvalue(result_, row_, column), static_cast<std::size_t>(PQgetlength(result_, row_, column)));
  }
  const void* column_blob(int column) const override {
    const auto& bytes = blob(column);
    return bytes.empty() ? nullptr : bytes.data();
  }
  std::size_t column_bytes(int column) const override {
    // Text columns (a JSON payload) are read through column_bytes too: their length is the text's.
    if (PQftype(result_, column) != kBytea) return static_cast<std::size_t>(PQgetlength(result_, row_, column));
    return blob(column).size();
  }

 private:
  void slot(int index) {
    if (index < 1) throw StorageError("postgresql bind: parameter index " + std::to_string(index));
    const auto n = static_cast<std::size_t>(index);
    if (params_.size() < n) {
      params_.resize(n);
      formats_.resize(n, 0);
    }
  }
  void set(int index, std::string value, int format) {
    slot(index);
    const auto i = static_cast<std::size_t>(index - 1);
    params_[i] = std::move(value);
    formats_[i] = format;
  }

  void execute() {
    std::vector<const char*> values(params_.size());
    std::vector<int> lengths(params_.size());
    for (std::size_t i = 0; i < params_.size(); ++i) {
      values[i] = params_[i] ? params_[i]->data() : nullptr;
      lengths[i] = params_[i] ? static_cast<int>(params_[i]->size()) : 0;
    }
    result_ = PQexecPrepared(connection_.conn_, name_.c_str(), static_cast<int>(values.size()), values.data(),
                             lengths.data(), formats_.data(), 0);
    if (PQresultStatus(result_) == PGRES_FATAL_ERROR && PQstatus(connection_.conn_) != CONNECTION_OK &&
        !connection_.in_transaction_) {
      // The connection was gone (the server restarted). Outside a transaction a statement ran whole or not at all,
      // and those run there may run twice (the store's reads; a lease taken twice has the later epoch): once more,
      // on a new connection.
      PQclear(result_);
      connection_.reconnect_if_lost();
      name_ = connection_.prepared(sql_);
      result_ = PQexecPrepared(connection_.conn_, name_.c_str(), static_cast<int>(values.size()), values.data(),
                               lengths.data(), formats_.data(), 0);
    }
    const auto status = PQresultStatus(result_);
    if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) {
      const std::string message = error_text(result_, connection_.conn_);
      PQclear(result_);
      result_ = nullptr;
      throw StorageError("postgresql: " + message + " (in: " + sql_.substr(0, 80) + ")");
    }
    row_ = -1;
  }

  // A bytea column's bytes (hex text "\x0a1b…" on the wire), decoded once per row.
  const std::string& blob(int column) const {
    auto& cached = decoded_[static_cast<std::size_t>(column)];
    if (!cached) {
      cached.emplace();
      const char* text = PQgetvalue(result_, row_, column);
      const auto length = static_cast<std::size_t>(PQgetlength(result_, row_, column));
      if (PQftype(result_, column) != kBytea) {
        cached->assign(text, length);
      } else if (length >= 2 && text[0] == '\\' && text[1] == 'x') {
        const auto nibble = [](char c) -> int { return c <= '9' ? c - '0' : (c | 0x20) - 'a' + 10; };
        cached->resize((length - 2) / 2);
        for (std::size_t i = 0; i < cached->size(); ++i)
          (*cached)[i] = static_cast<char>(nibble(text[2 + 2 * i]) << 4 | nibble(text[3 + 2 * i]));
      } else if (length > 0) {
        throw StorageError("postgresql: bytea not in hex output format (bytea_output = 'escape'?)");
      }
    }
    return *cached;
  }

  PostgresConnection& connection_;
  std::string sql_;
  std::string name_;
  std::vector<std::optional<std::string>> params_;
  std::vector<int> formats_;
  PGresult* result_ = nullptr;
  int row_ = -1;
  mutable std::vector<std::optional<std::string>> decoded_;
};

PostgresConnection::PostgresConnection(const std::string& uri, const std::string& schema, bool create)
    : schema_(schema) {
  const std::string quoted = quoted_schema(schema);
  conn_ = PQconnectdb(uri.c_str());
  if (PQstatus(conn_) != CONNECTION_OK) {
    const std::string message = error_text(nullptr, conn_);
    PQfinish(conn_);
    conn_ = nullptr;
    throw StorageError("cannot connect to postgresql: " + message);
  }
  PQsetNoticeProcessor(conn_, ignore_notice, nullptr);
  try {
    if (create) {
      // PostGIS in `public`, once per database; two stores creating it at once race, and the loser finds it made.
      for (int attempt = 0;; ++attempt) {
        try {
          exec("CREATE EXTENSION IF NOT EXISTS postgis WITH SCHEMA public");
          break;
        } catch (const StorageError&) {
          if (attempt > 0) throw;
        }
      }
      exec("CREATE SCHEMA IF NOT EXISTS " + quoted);
    }
    exec("SET search_path TO " + quoted + ", public");
  } catch (...) {
    PQfinish(conn_);
    throw;
  }
}

PostgresConnection::~PostgresConnection() { PQfinish(conn_); }

void PostgresConnection::reconnect_if_lost() {
  if (PQstatus(conn_) == CONNECTION_OK) return;
  // Inside a transaction its writes went with the connection: it fails whole, never goes on in autocommit.
  if (in_transaction_) throw StorageError("lost the connection to postgresql during a transaction");
  // The server went away (a restart, a failover) and the operation that found out failed; this one starts afresh on a
  // new connection: its prepared statements are gone with the old one.
  PQreset(conn_);
  if (PQstatus(conn_) != CONNECTION_OK)
    throw StorageError("lost the connection to postgresql: " + error_text(nullptr, conn_));
  PQsetNoticeProcessor(conn_, ignore_notice, nullptr);
  prepared_.clear();
  prepared_in_pipeline_.clear();
  pipelining_ = false;
  exec("SET search_path TO " + quoted_schema(schema_) + ", public");
  limit_stalls();
}

void PostgresConnection::begin() {
  reconnect_if_lost();
  in_transaction_ = true;
  if (PQenterPipelineMode(conn_) != 1) throw StorageError("postgresql: " + error_text(nullptr, conn_));
  pipelining_ = true;
  first_sent_sql_ = "BEGIN";
  // BEGIN goes in the pipeline too: the whole transaction is one round trip, the fence's check included.
  bool sent = PQsendQueryParams(conn_, "BEGIN", 0, nullptr, nullptr, nullptr, nullptr, 0) == 1;
  if (sent && fence_) {
    const std::string epoch = std::to_string(fence_->epoch);
    const char* values[] = {fence_->map.c_str(), fence_->node.c_str(), epoch.c_str()};
    sent = PQsendQueryParams(conn_, "SELECT wm_cluster.fence($1, $2, $3::bigint)", 3, nullptr, values, nullptr, nullptr,
                             0) == 1;
  }
  if (!sent) {
    const std::string message = error_text(nullptr, conn_);
    pipelining_ = false;
    PQexitPipelineMode(conn_);
    throw StorageError("postgresql: " + message + " (in: BEGIN)");
  }
}

void PostgresConnection::set_fence(const Fence& fence) {
  ensure_lease_schema(*this);
  fence_ = fence;
  limit_stalls();
}

void PostgresConnection::limit_stalls() {
  if (!fence_) return;
  // The name a node taking the lease over ends this session by, should it stall inside a transaction.
  exec("SET application_name = '" + fence_session_name(fence_->map, fence_->epoch) + "'");
  if (fence_->ttl_ms <= 0) return;
  exec("SET idle_in_transaction_session_timeout = " + std::to_string(std::max<std::int64_t>(fence_->ttl_ms / 2, 100)));
}

void PostgresConnection::send(const std::string& name, const std::vector<const char*>& values,
                              const std::vector<int>& lengths, const std::vector<int>& formats,
                              const std::string& sql) {
  if (PQsendQueryPrepared(conn_, name.c_str(), static_cast<int>(values.size()), values.data(), lengths.data(),
                          formats.data(), 0) != 1)
    throw StorageError("postgresql: " + error_text(nullptr, conn_) + " (in: " + sql.substr(0, 80) + ")");
  if (first_sent_sql_ == "BEGIN") first_sent_sql_ = sql;
}

void PostgresConnection::finish_pipeline() {
  pipelining_ = false;
  std::string error;
  bool fenced = false;
  if (PQpipelineSync(conn_) != 1) error = error_text(nullptr, conn_);
  // Each statement's results end with a null; the sync point's result ends the pipeline.
  while (error.empty() || PQstatus(conn_) == CONNECTION_OK) {
    PGresult* result = PQgetResult(conn_);
    if (!result) {
      if (PQstatus(conn_) != CONNECTION_OK) break;
      continue;
    }
    const auto status = PQresultStatus(result);
    if (status == PGRES_FATAL_ERROR && error.empty()) {
      error = error_text(result, conn_);
      const char* state = PQresultErrorField(result, PG_DIAG_SQLSTATE);
      fenced = state && std::string_view(state) == "WM001";
    }
    PQclear(result);
    if (status == PGRES_PIPELINE_SYNC) break;
  }
  if (PQstatus(conn_) != CONNECTION_OK && error.empty()) error = error_text(nullptr, conn_);
  PQexitPipelineMode(conn_);
  // Which statement failed is not known here: those prepared in this pipeline are prepared again (new names) on use.
  if (!error.empty())
    for (const auto& sql : prepared_in_pipeline_) prepared_.erase(sql);
  prepared_in_pipeline_.clear();
  if (fenced) throw FencedError("postgresql: " + error);
  if (!error.empty())
    throw StorageError("postgresql: " + error + " (in a transaction from: " + first_sent_sql_.substr(0, 80) + ")");
}

void PostgresConnection::exec(std::string_view sql) {
  // COMMIT ends the pipeline with it, in the same round trip; anything else waits for the pipeline's answers first.
  if (sql == "COMMIT" || sql == "ROLLBACK") in_transaction_ = false;  // ended, committed or not
  if (pipelining_) {
    if (sql == "COMMIT") {
      if (PQsendQueryParams(conn_, "COMMIT", 0, nullptr, nullptr, nullptr, nullptr, 0) != 1) {
        pipelining_ = false;
        PQexitPipelineMode(conn_);
        throw StorageError("postgresql: " + error_text(nullptr, conn_) + " (in: COMMIT)");
      }
      finish_pipeline();  // throws the first error: a failed write, or the commit's
      return;
    }
    if (sql == "ROLLBACK") {
      try {
        finish_pipeline();
      } catch (const StorageError&) {
        // The write that failed is why the transaction rolls back.
      }
    } else {
      finish_pipeline();
    }
  }
  if (sql == "ROLLBACK" && PQstatus(conn_) != CONNECTION_OK) return;  // gone with the connection
  if (sql != "COMMIT" && sql != "ROLLBACK") reconnect_if_lost();
  const std::string text(sql);
  PGresult* result = PQexec(conn_, text.c_str());
  const auto status = PQresultStatus(result);
  if (status != PGRES_COMMAND_OK && status != PGRES_TUPLES_OK) {
    const std::string message = error_text(result, conn_);
    PQclear(result);
    throw StorageError("postgresql: " + message + " (in: " + text.substr(0, 80) + ")");
  }
  PQclear(result);
}

std::unique_ptr<detail::StatementBackend> PostgresConnection::prepare(const std::string& sql) {
  return std::make_unique<PostgresStatement>(*this, sql);
}

std::string PostgresConnection::prepared(const std::string& sql) {
  if (!pipelining_) reconnect_if_lost();
  const auto found = prepared_.find(sql);
  if (found != prepared_.end()) return found->second;
  const std::string name = "wm" + std::to_string(++statements_made_);
  if (pipelining_) {
    // Prepared in the pipeline too; its answer comes with the others (a failure forgets it, see finish_pipeline).
    if (PQsendPrepare(conn_, name.c_str(), dollar_parameters(sql).c_str(), 0, nullptr) != 1)
      throw StorageError("postgresql prepare: " + error_text(nullptr, conn_) + " (in: " + sql.substr(0, 80) + ")");
    prepared_in_pipeline_.push_back(sql);
    return prepared_.emplace(sql, name).first->second;
  }
  PGresult* result = PQprepare(conn_, name.c_str(), dollar_parameters(sql).c_str(), 0, nullptr);
  if (PQresultStatus(result) != PGRES_COMMAND_OK && PQstatus(conn_) != CONNECTION_OK && !in_transaction_) {
    PQclear(result);  // the connection was gone: once more on a new one (a prepare changes nothing)
    reconnect_if_lost();
    result = PQprepare(conn_, name.c_str(), dollar_parameters(sql).c_str(), 0, nullptr);
  }
  if (PQresultStatus(result) != PGRES_COMMAND_OK) {
    const std::string message = error_text(result, conn_);
    PQclear(result);
    throw StorageError("postgresql prepare: " + message + " (in: " + sql.substr(0, 80) + ")");
  }
  PQclear(result);
  return prepared_.emplace(sql, name).first->second;
}

int PostgresConnection::schema_version() {
  PostgresStatement s(*this, "SELECT to_regclass('schema_version') IS NOT NULL");
  s.step();
  if (s.column_text(0) != "t") return 0;
  PostgresStatement v(*this, "SELECT MAX(version) FROM schema_version");
  v.step();
  return static_cast<int>(v.column_int(0));
}

void PostgresConnection::set_schema_version(int version) {
  exec("DELETE FROM schema_version; INSERT INTO schema_version(version) VALUES (" + std::to_string(version) + ")");
}

}  // namespace wm::storage
