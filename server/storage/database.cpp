#include "server/storage/database.h"

#include <cstring>

namespace wm::storage {

Statement::Statement(Connection& connection, std::string_view sql) : backend_(connection.prepare(std::string(sql))) {}

Statement& Statement::bind(int index, std::int64_t value) {
  backend_->bind_int(index, value);
  return *this;
}
Statement& Statement::bind(int index, double value) {
  backend_->bind_double(index, value);
  return *this;
}
Statement& Statement::bind(int index, std::string_view value) {
  backend_->bind_text(index, value);
  return *this;
}
Statement& Statement::bind_blob(int index, const void* data, std::size_t bytes) {
  backend_->bind_blob(index, data, bytes);
  return *this;
}
Statement& Statement::bind_null(int index) {
  backend_->bind_null(index);
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

bool Statement::step() { return backend_->step(); }

void Statement::run() { backend_->run(); }

void Statement::reset() { backend_->reset(); }

std::int64_t Statement::column_int(int column) const { return backend_->column_int(column); }
double Statement::column_double(int column) const { return backend_->column_double(column); }
std::string Statement::column_text(int column) const { return backend_->column_text(column); }
std::optional<std::string> Statement::column_optional_text(int column) const {
  if (backend_->column_is_null(column)) return std::nullopt;
  return column_text(column);
}
std::optional<double> Statement::column_optional_double(int column) const {
  if (backend_->column_is_null(column)) return std::nullopt;
  return column_double(column);
}
std::optional<std::int64_t> Statement::column_optional_int(int column) const {
  if (backend_->column_is_null(column)) return std::nullopt;
  return column_int(column);
}
const void* Statement::column_blob(int column) const { return backend_->column_blob(column); }
std::size_t Statement::column_bytes(int column) const { return backend_->column_bytes(column); }

std::vector<double> Statement::column_doubles(int column) const {
  const auto bytes = backend_->column_bytes(column);
  std::vector<double> values(bytes / sizeof(double));
  if (!values.empty()) std::memcpy(values.data(), backend_->column_blob(column), values.size() * sizeof(double));
  return values;
}

Transaction::Transaction(Connection& connection) : connection_(connection) { connection_.begin(); }

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
