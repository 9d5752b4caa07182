// The guard against a file shrunk under a shared mapping, with a real /dev/shm file truncated under the writer.
#include "server/shm/sigbus_guard.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

namespace wm::testing {
namespace {

constexpr std::size_t kBytes = 1 << 20;

/// A /dev/shm file of kBytes mapped shared and read-write; the name is unlinked at once.
struct SharedFile {
  int fd = -1;
  unsigned char* base = nullptr;
  SharedFile() {
    const auto name = "/wm-sigbus-test-" + std::to_string(::getpid());
    fd = ::shm_open(name.c_str(), O_CREAT | O_EXCL | O_RDWR, 0600);
    ::shm_unlink(name.c_str());
    if (fd < 0 || ::ftruncate(fd, kBytes) != 0) std::abort();
    void* mapped = ::mmap(nullptr, kBytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    if (mapped == MAP_FAILED) std::abort();
    base = static_cast<unsigned char*>(mapped);
  }
  ~SharedFile() {
    ::munmap(base, kBytes);
    ::close(fd);
  }
};

// Death by SIGBUS, or under AddressSanitizer (which takes SIGBUS itself) its report and a failing exit status.
TEST(SigbusGuardTest, WritingPastAShrunkFileEndKillsWithoutAGuard) {
  // A fresh process: a library of the same test binary (SWI-Prolog) may have put its own SIGBUS handler in place.
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // What the guard is for: the default outcome.
  EXPECT_DEATH(
      {
        SharedFile file;
        if (::ftruncate(file.fd, 0) != 0) std::exit(0);  // survived: fails the test
        std::memset(file.base, 1, kBytes);
        std::exit(0);
      },
      "");
}

TEST(SigbusGuardTest, AGuardedWriteToAShrunkFileGoesOnAndMarksTheRangeLost) {
  SharedFile file;
  std::atomic<bool> lost{false};
  {
    const shm::SigbusGuard guard(file.base, kBytes, lost);
    std::memset(file.base, 1, kBytes);
    EXPECT_FALSE(lost.load());
    ASSERT_EQ(::ftruncate(file.fd, kBytes / 2), 0);
    std::memset(file.base, 2, kBytes);  // the second half is past the end now
    EXPECT_TRUE(lost.load());
    EXPECT_EQ(file.base[kBytes - 1], 2) << "the write went on, into private memory";
    file.base[0] = 3;
  }
  unsigned char first = 0;
  ASSERT_EQ(::pread(file.fd, &first, 1, 0), 1);
  EXPECT_EQ(first, 2) << "written before the fault: in the file; after it: not";
}

TEST(SigbusGuardTest, GuardsNestAndEachMarksOnlyItsOwnRange) {
  SharedFile outer_file, inner_file;
  std::atomic<bool> outer_lost{false}, inner_lost{false};
  const shm::SigbusGuard outer(outer_file.base, kBytes, outer_lost);
  {
    const shm::SigbusGuard inner(inner_file.base, kBytes, inner_lost);
    ASSERT_EQ(::ftruncate(outer_file.fd, 0), 0);
    outer_file.base[10] = 7;
    inner_file.base[10] = 7;
  }
  EXPECT_TRUE(outer_lost.load());
  EXPECT_FALSE(inner_lost.load());
}

TEST(SigbusGuardTest, AFaultOutsideEveryGuardedRangeStillKills) {
  // A fresh process: a library of the same test binary (SWI-Prolog) may have put its own SIGBUS handler in place.
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(
      {
        SharedFile guarded;
        SharedFile other;
        std::atomic<bool> lost{false};
        const shm::SigbusGuard guard(guarded.base, kBytes, lost);
        if (::ftruncate(other.fd, 0) != 0) std::exit(0);
        other.base[0] = 1;
        std::exit(0);
      },
      "");
}

}  // namespace
}  // namespace wm::testing
