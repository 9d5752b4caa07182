#include "server/shm/segment_files.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <cstring>
#include <ctime>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "server/shm/shared_map_export.h"
#include "wire/shm/worldmodel_shm.h"

namespace wm::shm {
namespace internal {

std::optional<ProcessStat> process_stat(std::int64_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto close = text.rfind(')');  // the command name may hold spaces and parentheses
  if (close == std::string::npos) return std::nullopt;
  std::istringstream fields(text.substr(close + 1));
  ProcessStat stat;
  std::string field;
  if (!(fields >> stat.state)) return std::nullopt;
  for (int i = 4; i <= 22; ++i)
    if (!(fields >> field)) return std::nullopt;
  try {
    stat.start_ticks = std::stoull(field);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  return stat;
}

std::uint64_t free_shm_bytes() {
  struct statvfs info {};
  if (::statvfs(kShmDir, &info) != 0) return 0;
  return static_cast<std::uint64_t>(info.f_bavail) * info.f_frsize;
}

}  // namespace internal

namespace layout = worldmodel::shm;
using internal::kShmDir;

std::vector<std::string> SharedMapExport::remove_stale_segments() {
  static const std::regex ours("wm-[0-9a-f]{8}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{4}-[0-9a-f]{12}");
  std::vector<std::string> removed;
  DIR* dir = ::opendir(kShmDir);
  if (dir == nullptr) return removed;
  std::vector<std::string> names;
  while (const dirent* entry = ::readdir(dir))
    if (std::regex_match(entry->d_name, ours)) names.emplace_back(entry->d_name);
  ::closedir(dir);
  for (const auto& name : names) {
    // Anyone may put a file of that name here: no blocking open (a FIFO), no symlink, only our own regular files.
    const auto path = std::string(kShmDir) + "/" + name;
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) continue;
    struct stat info {};
    if (::fstat(fd, &info) != 0 || !S_ISREG(info.st_mode) || info.st_uid != ::geteuid()) {
      ::close(fd);
      continue;
    }
    // Its maker holds a shared lock for as long as it runs: the kernel drops it when the process ends, however it
    // ends (kill -9 included), so a lock we can take means no server owns the segment, whatever pid it names.
    if (::flock(fd, LOCK_EX | LOCK_NB) == 0) {
      char magic[5] = {};
      const bool filled = ::pread(fd, magic, sizeof magic, 0) == static_cast<ssize_t>(sizeof magic) &&
                          std::memcmp(magic, layout::kMagic, sizeof magic) == 0;  // "WMSHM": any layout version
      // Without a header, its maker may be between creating the file and taking the lock: wait a minute.
      if ((filled || ::time(nullptr) - info.st_mtime > 60) && ::shm_unlink(("/" + name).c_str()) == 0)
        removed.push_back(name);
    }
    ::close(fd);
  }
  return removed;
}

}  // namespace wm::shm
