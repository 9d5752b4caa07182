#pragma once

// Statement helpers the store's source files share (store.cpp, store_world.cpp, store_journal.cpp,
// store_plan.cpp, store_grid.cpp); nothing else includes it.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <vector>

#include "server/storage/database.h"

namespace wm::storage::internal {

inline double now_unix_s() {
  return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
}

// Binds `values` to ?1, ?2, ... in order (std::int64_t, double, std::string_view or their optionals).
template <typename... Values>
Statement& bind_all(Statement& s, const Values&... values) {
  int index = 0;
  (s.bind(++index, values), ...);
  return s;
}

// Runs one statement that returns no rows, with its parameters. @throw StorageError.
template <typename... Values>
void run(Connection& db, std::string_view sql, const Values&... values) {
  Statement s(db, sql);
  bind_all(s, values...).run();
}

// The first column of the first row of a query that returns one (COUNT, MAX, PRAGMA). @throw StorageError.
inline std::int64_t query_int(Connection& db, std::string_view sql) {
  Statement s(db, sql);
  s.step();
  return s.column_int(0);
}

template <typename Matrix>
void bind_matrix(Statement& s, int index, const Matrix& m) {
  s.bind_blob(index, m.data(), sizeof(double) * static_cast<std::size_t>(m.size()));
}

inline void bind_doubles(Statement& s, int index, const std::vector<double>& values) {
  if (values.empty()) {
    s.bind_null(index);
  } else {
    s.bind_blob(index, values.data(), sizeof(double) * values.size());
  }
}

template <typename Matrix>
Matrix read_matrix(const Statement& s, int column) {
  const auto values = s.column_doubles(column);
  Matrix m;
  if (values.size() != static_cast<std::size_t>(m.size())) throw StorageError("corrupt matrix in database");
  for (Eigen::Index i = 0; i < m.size(); ++i) m.data()[i] = values[static_cast<std::size_t>(i)];
  return m;
}

}  // namespace wm::storage::internal
