#include "common/diagnostics.h"

#include <chrono>
#include <utility>

namespace wm::common {
namespace {

std::uint64_t& count_of(Diagnostics::Counts& counts, Severity severity) {
  switch (severity) {
    case Severity::info:
      return counts.info;
    case Severity::warning:
      return counts.warnings;
    case Severity::error:
      break;
  }
  return counts.errors;
}

}  // namespace

std::string_view severity_name(Severity severity) {
  switch (severity) {
    case Severity::info:
      return "info";
    case Severity::warning:
      return "warning";
    case Severity::error:
      break;
  }
  return "error";
}

Diagnostics::Diagnostics(std::string echo_prefix, std::ostream* echo, std::size_t recent_kept)
    : echo_prefix_(std::move(echo_prefix)), echo_(echo), recent_kept_(recent_kept) {}

void Diagnostics::report(Severity severity, std::string_view where, std::string message) {
  if (echo_) {
    // One write of the whole line: lines from several threads do not interleave.
    const std::string line = echo_prefix_ + message + "\n";
    std::lock_guard lock(echo_mutex_);
    try {
      echo_->write(line.data(), static_cast<std::streamsize>(line.size()));
      echo_->flush();
    } catch (...) {  // a stream with exceptions enabled: the report is still counted
    }
  }
  if (message.size() > kMaxKeptMessageBytes) {
    message.resize(kMaxKeptMessageBytes);
    message += "...";
  }
  const double now = std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  std::lock_guard lock(mutex_);
  ++count_of(total_, severity);
  auto found = by_where_.find(where);
  if (found == by_where_.end()) found = by_where_.emplace(std::string(where), Counts{}).first;
  ++count_of(found->second, severity);
  if (recent_kept_ == 0) return;
  if (recent_.size() == recent_kept_) recent_.pop_front();
  recent_.push_back(Report{now, severity, std::string(where), std::move(message)});
}

Diagnostics::Summary Diagnostics::summary() const {
  std::lock_guard lock(mutex_);
  return Summary{total_, by_where_, {recent_.begin(), recent_.end()}};
}

}  // namespace wm::common
