#pragma once

// The files of /dev/shm and /proc the export reads: what free space the segments may take, who a process is, and
// (in segment_files.cpp, beside these) SharedMapExport::remove_stale_segments.
#include <cstdint>
#include <optional>

namespace wm::shm::internal {

inline constexpr const char* kShmDir = "/dev/shm";

/// A process as /proc/<pid>/stat tells it: its state letter (field 3) and its start time (field 22, clock ticks after
/// boot).
struct ProcessStat {
  char state = '?';
  std::uint64_t start_ticks = 0;
};
/// nullopt when unreadable (gone, or /proc not mounted).
std::optional<ProcessStat> process_stat(std::int64_t pid);

/// What /dev/shm has free for this user [bytes]; 0 when it cannot tell.
std::uint64_t free_shm_bytes();

}  // namespace wm::shm::internal
