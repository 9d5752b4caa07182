#pragma once

// The pieces every wmctl command shares: its parsed arguments, the command table's row type, the errors that
// choose the exit code, and the server-answer helpers.
#include <cstdint>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "clients/wmctl/http_client.h"

namespace wm::wmctl {

using nlohmann::json;

/// Exit codes, the contract scripts rely on.
constexpr int kExitOk = 0;
constexpr int kExitServerError = 1;  // the server answered with an error status (or something else failed)
constexpr int kExitUsage = 2;        // bad command line, or a local file that cannot be read or written
constexpr int kExitUnreachable = 3;  // no server at --server

/// A bad command line or local file: exit 2, with `usage` (one command's, or the whole list when empty).
struct UsageError : std::runtime_error {
  explicit UsageError(const std::string& message, std::string usage_text = {})
      : std::runtime_error(message), usage(std::move(usage_text)) {}
  std::string usage;
};

/// The server answered an error status or something that is not JSON: exit 1.
struct ServerError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// One run of one command: the connection, the global options and the command's own arguments.
struct Invocation {
  const client::HttpClient& client;
  std::string token;  // sent with the requests that change the server
  bool raw_json = false;
  std::vector<std::string> operands;                       // positional arguments, as many as the command names
  std::vector<std::pair<std::string, std::string>> flags;  // "--flag value" pairs in command-line order

  /// The value of the last `name` given, if any.
  std::optional<std::string> flag(std::string_view name) const;

  /// Prints `body` as JSON with --json, else through `readable`; returns kExitOk.
  template <typename Readable>
  int emit(const json& body, Readable&& readable) const {
    if (raw_json)
      std::cout << body.dump(2) << "\n";
    else
      readable(body);
    return kExitOk;
  }
};

/// A "--flag VALUE" a command accepts; `value` names the value in the usage text (empty: a switch, "--flag" alone).
struct Flag {
  std::string_view name;
  std::string_view value;
  bool required = false;  // shown without brackets; parse_arguments() refuses a command line without it
};

/// A row of the command table: dispatch, `wmctl help` and every usage message come from these.
struct Command {
  std::string_view name;                   // the words that select it, e.g. "rules dry-run"
  std::vector<std::string_view> operands;  // positional arguments, all required, before any flag; a last one
                                           // named "X..." takes one or more words
  std::vector<Flag> flags;
  std::string_view summary;  // one or more lines, without the leading indent
  int (*run)(const Invocation&);
};

/// "replay LOG [--limit N] ...": the command's usage line.
std::string usage_line(const Command& command);

/// Splits a command's words (after its name) into operands and flags.
/// @throw UsageError for a missing operand or required flag, a flag without its value or one the command does not take.
void parse_arguments(const Command& command, const std::vector<std::string>& words, Invocation& into);

/// The body of a successful answer as JSON.
/// @throw ServerError for a status >= 400 (with the server's error and detail) or a body that is not JSON.
json parse_answer(const client::HttpResult& answer);

/// @throw UsageError when the file cannot be read or written.
std::string read_file(const std::string& path);
void write_file(const std::string& path, const std::string& data);

/// A whole number > 0. @throw UsageError otherwise.
std::int64_t parse_count(const std::string& text);

/// `v` with `digits` decimals.
std::string fixed(double v, int digits = 3);

/// One decision of the log: seq, action, rule, element, object and the explanation.
void print_decision(const json& decision);

}  // namespace wm::wmctl
