#pragma once

// Where library code reports what it recovered from, instead of writing to stderr where nothing counts it.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace wm::common {

enum class Severity {
  info,     // worth a line, nothing went wrong (the rules were reloaded)
  warning,  // something was skipped or will be retried; nothing is lost (a flush retried at the next one)
  error,    // something was lost or is out of step until a restart (a scan not in the grid)
};

/// "info", "warning", "error".
std::string_view severity_name(Severity severity);

/// The sink for the diagnostics of library code: failures it handled without failing its caller, and events worth a
/// line. Counts every report by where it came from and its severity, and keeps the last few (for GET /api/v1/health).
/// Each report is also written to an echo stream as one line (stderr unless told otherwise), so the terminal shows
/// what it did before. main makes one and passes it to every part that reports; no globals.
/// Thread-safe: report() and summary() from any thread. The echo is written under a lock of its own, so a reader of
/// the counts never waits for a slow terminal.
class Diagnostics {
 public:
  struct Counts {
    std::uint64_t info = 0;
    std::uint64_t warnings = 0;
    std::uint64_t errors = 0;
  };
  struct Report {
    double at_unix_s = 0;  // when it was reported [s since the Unix epoch]
    Severity severity = Severity::info;
    std::string where;
    std::string message;  // the kept copy is cut at kMaxKeptMessageBytes (the echo has it whole)
  };
  /// All of it as of one instant.
  struct Summary {
    Counts total;
    std::map<std::string, Counts, std::less<>> by_where;
    std::vector<Report> recent;  // oldest first, at most recent_kept
  };

  static constexpr std::size_t kRecentKept = 20;
  /// A message kept longer than this is cut, so that the recent list stays small whatever an exception said [bytes].
  static constexpr std::size_t kMaxKeptMessageBytes = 2000;

  /// Echoes each report to `echo` as `echo_prefix` + message + '\n' (nullptr: no echo); keeps the last `recent_kept`.
  explicit Diagnostics(std::string echo_prefix = "", std::ostream* echo = &std::cerr,
                       std::size_t recent_kept = kRecentKept);
  Diagnostics(const Diagnostics&) = delete;
  Diagnostics& operator=(const Diagnostics&) = delete;

  /// `where`: the part of the program that reports, a short fixed name ("grid", "rules", "foxglove"), never data, so
  /// the count table grows with the code and not with the traffic. Never throws for a failing echo stream.
  void report(Severity severity, std::string_view where, std::string message);
  Summary summary() const;

 private:
  const std::string echo_prefix_;
  std::ostream* const echo_;
  const std::size_t recent_kept_;
  std::mutex echo_mutex_;  // one line at a time
  mutable std::mutex mutex_;
  Counts total_;
  std::map<std::string, Counts, std::less<>> by_where_;
  std::deque<Report> recent_;
};

}  // namespace wm::common
