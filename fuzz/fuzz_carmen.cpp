// CARMEN logs (wmctl replay): FLASER, ROBOTLASER1 and PARAM lines, plain or gzipped. The reader takes a path,
// so each input is written to one temporary file first. Expected: scans until the end, or a LogError.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

#include "fuzz/fuzz_support.h"
#include "logs/carmen_log_reader.h"

namespace {

// One file per process, made once (mkstemp), removed at exit; in memory (/dev/shm) where there is one, which
// makes each execution about a quarter faster.
struct InputFile {
  std::string path;
  InputFile() {
    std::error_code ec;
    const auto dir = std::filesystem::is_directory("/dev/shm", ec) ? std::filesystem::path("/dev/shm")
                                                                   : std::filesystem::temp_directory_path();
    std::string pattern = (dir / "wm-fuzz-carmen-XXXXXX").string();
    const int fd = ::mkstemp(pattern.data());
    if (fd < 0) wm::fuzz::fail("cannot create a temporary file");
    ::close(fd);
    path = pattern;
  }
  ~InputFile() { std::remove(path.c_str()); }
  void write(const std::uint8_t* data, std::size_t size) const {
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (f == nullptr || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0)
      wm::fuzz::fail("cannot write " + path);
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const InputFile file;
  file.write(data, size);
  try {
    wm::logs::CarmenLogReader reader(file.path);
    while (reader.next()) {
    }
    if (reader.progress() < 0.0 || reader.progress() > 1.0) wm::fuzz::fail("progress() outside [0, 1]");
  } catch (const wm::logs::LogError&) {
  }
  return 0;
}
