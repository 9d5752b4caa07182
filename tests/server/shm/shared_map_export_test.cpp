// The shared-memory export with the real segment in /dev/shm and the real header-only reader, fed by a port whose
// tiles the test controls.
#include "server/shm/shared_map_export.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <boost/uuid/uuid_generators.hpp>
#include <boost/uuid/uuid_io.hpp>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <map>
#include <mutex>
#include <thread>

#include "tests/server/api/fake_world_port.h"
#include "tests/support/lab_plan.h"
#include "wire/shm/worldmodel_shm.h"

namespace wm::testing {
namespace {

namespace reader = worldmodel::shm;
using namespace std::chrono_literals;

/// Tiles of T² cells whose every value tells the tile's revision and the layer: cell value = 4·revision + layer, so
/// a copy mixing two revisions (or two layers) shows at once. Thread-safe, like the real service.
class CountingGridPort : public FakeMap, public FakeGrid {  // the two ports the export reads
 public:
  static constexpr std::int64_t kTile = 16;

  void bump(std::int64_t tx, std::int64_t ty) {
    std::lock_guard lock(mutex_);
    ++revisions_[{tx, ty}];
    ++grid_revision_;
  }
  service::GridTiles grid_tiles() const override {
    std::lock_guard lock(mutex_);
    service::GridTiles tiles{kTile, 0.05, grid_revision_, {}};
    for (const auto& [key, revision] : revisions_) tiles.tiles.push_back({key.first, key.second, revision});
    return tiles;
  }
  std::optional<service::GridTileValues> grid_tile_layers(std::int64_t tx, std::int64_t ty) const override {
    std::lock_guard lock(mutex_);
    const auto it = revisions_.find({tx, ty});
    if (it == revisions_.end()) return std::nullopt;
    service::GridTileValues values{std::vector<float>(4 * kTile * kTile), it->second};
    for (std::size_t i = 0; i < values.values.size(); ++i)
      values.values[i] = static_cast<float>(4 * it->second + i / (kTile * kTile));
    return values;
  }

 private:
  mutable std::mutex mutex_;
  std::map<std::pair<std::int64_t, std::int64_t>, std::uint64_t> revisions_;
  std::int64_t grid_revision_ = 0;
};

bool segment_exists(const std::string& name) { return std::filesystem::exists("/dev/shm/" + name); }

shm::ShmOptions fast(std::uint64_t max_bytes = std::uint64_t{1} << 30) {
  shm::ShmOptions options;
  options.period = 1ms;
  options.max_bytes = max_bytes;
  return options;
}

TEST(SharedMapExportTest, ReadersNeverSeeATornTileWhileTheWriterHammersTheSlots) {
  CountingGridPort port;
  for (int i = 0; i < 8; ++i) port.bump(i, -i);
  common::Diagnostics diagnostics("", nullptr);
  shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
  const auto name = exporter.status().name;

  std::atomic<bool> done{false};
  std::thread writer([&] {  // as fast as it can: bump a tile, copy it in
    for (std::uint64_t n = 0; !done; ++n) {
      port.bump(static_cast<std::int64_t>(n % 8), -static_cast<std::int64_t>(n % 8));
      exporter.sync();
    }
  });
  std::atomic<std::uint64_t> reads{0}, torn{0}, backwards{0};
  std::vector<std::thread> readers;
  for (int r = 0; r < 2; ++r) {
    readers.emplace_back([&] {
      reader::Reader segment(name);  // its own mapping, as another process has
      std::vector<float> cells(4 * CountingGridPort::kTile * CountingGridPort::kTile);
      std::vector<std::uint64_t> last(8, 0);
      const auto until = std::chrono::steady_clock::now() + 1500ms;
      while (std::chrono::steady_clock::now() < until) {
        for (std::size_t slot = 0; slot < segment.tile_count(); ++slot) {
          const auto revision = segment.read_tile_layers(slot, cells.data());
          for (std::size_t i = 0; i < cells.size(); ++i) {
            if (cells[i] != static_cast<float>(4 * revision + i / (cells.size() / 4))) {
              ++torn;
              break;
            }
          }
          if (revision < last[slot]) ++backwards;
          last[slot] = revision;
          ++reads;
        }
      }
    });
  }
  for (auto& t : readers) t.join();
  done = true;
  writer.join();
  EXPECT_GT(reads.load(), 10'000u);
  EXPECT_EQ(torn.load(), 0u);
  EXPECT_EQ(backwards.load(), 0u);
}

// With the event hub the export looks only when told (an idle server costs nothing), and at once when it is.
TEST(SharedMapExportTest, WithTheEventHubAPassRunsAfterAnEventNotOnAClock) {
  CountingGridPort port;
  port.bump(0, 0);
  common::Diagnostics diagnostics("", nullptr);
  events::EventHub hub;
  auto options = fast();
  options.idle_period = 2s;
  shm::SharedMapExport exporter(shm::ExportSource{port, port}, options, "test-run", diagnostics, &hub);
  EXPECT_EQ(hub.subscriber_count(), 1u);
  EXPECT_EQ(hub.json_subscriber_count(), 0u) << "the export needs no JSON: none is made for it";
  const auto wait_for_revision = [&](std::uint64_t revision, std::chrono::milliseconds limit) {
    const auto until = std::chrono::steady_clock::now() + limit;
    while (exporter.status().grid_revision < revision && std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(1ms);
    return exporter.status().grid_revision >= revision;
  };
  ASSERT_TRUE(wait_for_revision(1, 2s));
  port.bump(1, 1);  // the grid changed, but nobody said so: no pass for now (period 1 ms)
  EXPECT_FALSE(wait_for_revision(2, 300ms));
  hub.publish(events::EventKind::scan, "{}");
  EXPECT_TRUE(wait_for_revision(2, 200ms));
  port.bump(2, 2);  // an event that is never published: the idle pass still finds it
  EXPECT_TRUE(wait_for_revision(3, 5s));
}

TEST(SharedMapExportTest, GrowsIntoALargerSegmentAndTheOldOneNamesIt) {
  CountingGridPort port;
  port.bump(0, 0);
  common::Diagnostics diagnostics("", nullptr);
  shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
  const auto first = exporter.status();
  ASSERT_TRUE(first.available) << first.error;
  reader::Reader old_segment(first.name);
  const auto capacity = first.tile_capacity;
  for (std::int64_t i = 0; i < static_cast<std::int64_t>(capacity) + 10; ++i) port.bump(i, 7);
  exporter.sync();

  const auto second = exporter.status();
  EXPECT_NE(second.name, first.name);
  EXPECT_EQ(second.generation, first.generation + 1);
  EXPECT_GE(second.tile_capacity, capacity + 11);
  EXPECT_EQ(old_segment.state(), reader::SegmentState::retired);
  ASSERT_EQ(old_segment.successor(), second.name);
  EXPECT_FALSE(segment_exists(first.name)) << "the retired name is unlinked";
  reader::Reader next(*old_segment.successor());
  EXPECT_EQ(next.tile_count(), capacity + 11);  // (0, 0) and the new ones, each once
  std::vector<float> cells(4 * 16 * 16);
  for (std::size_t slot = 0; slot < next.tile_count(); ++slot) {
    const auto key = next.tile_key(slot);
    const auto revision = next.read_tile_layers(slot, cells.data());
    EXPECT_EQ(revision, 1u) << key.tx << "," << key.ty;
    EXPECT_EQ(cells[0], 4.f * static_cast<float>(revision));
  }
  EXPECT_EQ(next.grid_revision(), capacity + 11);
}

TEST(SharedMapExportTest, ASizeCapLeavesTilesOutAndSaysSo) {
  CountingGridPort port;
  common::Diagnostics diagnostics("", nullptr);
  shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(std::uint64_t{1} << 20), "test-run",
                                diagnostics);  // 1 MB: about 180 slots of 16²
  for (std::int64_t i = 0; i < 1000; ++i) port.bump(i, 0);
  exporter.sync();
  const auto status = exporter.status();
  ASSERT_TRUE(status.available) << status.error;
  EXPECT_LE(status.bytes, std::uint64_t{1} << 20);
  EXPECT_FALSE(status.tiles_complete);
  EXPECT_GT(status.tile_count, 100u);
  EXPECT_LT(status.tile_count, 1000u);
  EXPECT_EQ(status.tile_count, status.tile_capacity);
  EXPECT_NE(status.error.find("cap"), std::string::npos) << status.error;
  reader::Reader segment(status.name);
  EXPECT_EQ(segment.header().truncated.load() & reader::kTilesTruncated, reader::kTilesTruncated);
  EXPECT_EQ(segment.tile_count(), status.tile_count);
}

TEST(SharedMapExportTest, AStopMarksTheSegmentStoppedAndRemovesItsName) {
  CountingGridPort port;
  port.bump(1, 1);
  common::Diagnostics diagnostics("", nullptr);
  std::optional<shm::SharedMapExport> exporter(std::in_place, shm::ExportSource{port, port}, fast(), "test-run",
                                               diagnostics);
  const auto name = exporter->status().name;
  ASSERT_TRUE(segment_exists(name));
  reader::Reader segment(name);
  exporter.reset();
  EXPECT_FALSE(segment_exists(name));
  EXPECT_EQ(segment.state(), reader::SegmentState::stopped);
  std::vector<float> cells(4 * 16 * 16);
  EXPECT_EQ(segment.read_tile_layers(0, cells.data()), 1u) << "a mapped reader keeps the last state";
}

TEST(SharedMapExportTest, TheMapRecordsAreThePlanAsPlacedAndTheElements) {
  CountingGridPort port;
  port.load_plan(lab_plan());
  world::Element e;
  e.number = 12;
  e.segment = fusion::LineSegment::from_points({1, 2}, {4, 2}, Eigen::Matrix2d::Identity() * 1e-4);
  e.support = 3;
  e.origin = "scan";
  e.updated_version = 5;
  port.state().elements.put(e);
  port.state().version = 5;
  common::Diagnostics diagnostics("", nullptr);
  shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
  reader::Reader segment(exporter.status().name);
  const auto map = segment.read_map();
  EXPECT_EQ(map.version, 5);
  EXPECT_EQ(segment.map_version(), 5);
  ASSERT_EQ(map.elements.size(), 1u);
  EXPECT_EQ(map.elements[0].number, 12);
  EXPECT_EQ(map.elements[0].support, 3);
  EXPECT_EQ(map.elements[0].origin, 1u);
  EXPECT_DOUBLE_EQ(std::min(map.elements[0].x1, map.elements[0].x2), 1.0);
  EXPECT_DOUBLE_EQ(std::max(map.elements[0].x1, map.elements[0].x2), 4.0);
  ASSERT_EQ(map.objects.size(), 2u);
  EXPECT_EQ(std::string(map.objects[0].id, map.objects[0].id_length), "wall-n");
  EXPECT_EQ(map.objects[0].flags, reader::kObjectSolid);
  EXPECT_STREQ(map.objects[1].kind, "table");
  EXPECT_EQ(map.objects[1].flags, reader::kObjectNotDeformable);
  EXPECT_NEAR(map.objects[1].theta, 0.3, 1e-12);
  ASSERT_EQ(map.edges.size(), 5u);  // the wall, the table's four sides
  EXPECT_EQ(map.objects[1].first_edge, 1u);
  EXPECT_EQ(map.objects[1].edge_count, 4u);
  for (std::size_t k = 1; k < 5; ++k) {  // the table's corners lie 0.721 m from its centre (5, 5)
    EXPECT_EQ(map.edges[k].object_index, 1u);
    EXPECT_NEAR(std::hypot(map.edges[k].x1 - 5, map.edges[k].y1 - 5), std::hypot(0.6, 0.4), 1e-9);
  }
  EXPECT_NEAR(map.edges[0].y1, 10.0, 1e-12);
}

// A segment file as a server leaves it (header with `pid`); its descriptor, which holds the owner's shared lock when
// `locked` (as a running server does), else closed.
struct LeftSegment {
  std::string name;
  int fd = -1;
  ~LeftSegment() {
    if (fd >= 0) ::close(fd);
    ::shm_unlink(("/" + name).c_str());
  }
};
std::unique_ptr<LeftSegment> leave_segment(std::int64_t pid, bool locked, bool with_header = true) {
  auto left = std::make_unique<LeftSegment>();
  left->name = std::string(reader::kNamePrefix) + boost::uuids::to_string(boost::uuids::random_generator()());
  const int fd = ::shm_open(("/" + left->name).c_str(), O_CREAT | O_EXCL | O_RDWR, 0600);
  EXPECT_GE(fd, 0);
  if (locked) {
    EXPECT_EQ(::flock(fd, LOCK_SH), 0);
  }
  if (with_header) {
    reader::SegmentHeader header{};
    std::memcpy(header.magic, reader::kMagic, sizeof header.magic);
    header.owner_pid = pid;
    EXPECT_EQ(::ftruncate(fd, reader::kHeaderBytes), 0);
    EXPECT_EQ(::pwrite(fd, &header, sizeof header, 0), static_cast<ssize_t>(sizeof header));
  }
  if (locked) {
    left->fd = fd;
  } else {
    ::close(fd);
  }
  return left;
}

TEST(SharedMapExportTest, SegmentsNoServerHoldsGoAndOthersStay) {
  // (Other test processes clean /dev/shm too, so what must go is checked by its absence, not by who removed it.)
  const auto left_before_start = leave_segment(12345, /*locked=*/false);
  CountingGridPort port;
  common::Diagnostics diagnostics("", nullptr);
  std::optional<shm::SharedMapExport> alive(std::in_place, shm::ExportSource{port, port}, fast(), "test-run",
                                            diagnostics);
  EXPECT_FALSE(segment_exists(left_before_start->name)) << "a starting exporter removes what dead servers left";
  const auto own = alive->status().name;
  const auto unlocked = leave_segment(::getpid(), false);  // names a live pid, but no process holds its lock
  const auto held = leave_segment(1, true);                // names another pid, but its lock is held: a live server
  const auto unfilled = leave_segment(0, false, false);    // made a moment ago, header not written yet
  const auto foreign = std::string("wm-not-ours-") + std::to_string(::getpid());
  const int fd = ::shm_open(("/" + foreign).c_str(), O_CREAT | O_RDWR, 0600);
  ASSERT_GE(fd, 0);
  ::close(fd);
  const auto fifo = std::string(reader::kNamePrefix) + boost::uuids::to_string(boost::uuids::random_generator()());
  ASSERT_EQ(::mkfifo(("/dev/shm/" + fifo).c_str(), 0600), 0);  // opening it for reading would block

  shm::SharedMapExport::remove_stale_segments();
  EXPECT_FALSE(segment_exists(unlocked->name));
  EXPECT_TRUE(segment_exists(held->name));
  EXPECT_TRUE(segment_exists(own));
  EXPECT_TRUE(segment_exists(unfilled->name)) << "younger than a minute: its maker may be writing the header now";
  EXPECT_TRUE(segment_exists(foreign)) << "not a name wmd makes";
  EXPECT_TRUE(std::filesystem::exists("/dev/shm/" + fifo)) << "not a regular file: skipped, without blocking";
  ::shm_unlink(("/" + foreign).c_str());
  ::unlink(("/dev/shm/" + fifo).c_str());
  alive.reset();
  EXPECT_FALSE(segment_exists(own));
}

TEST(SharedMapExportTest, TheReaderRefusesFilesThatAreNotSegments) {
  const auto empty_geometry = leave_segment(::getpid(), true);  // a header with zero sizes: no tile size, no map
  EXPECT_THROW(reader::Reader{empty_geometry->name}, reader::Error);
  EXPECT_THROW(reader::Reader{"wm-does-not-exist"}, reader::Error);
}

// The death tests below run in a fresh process (threadsafe style): a forked child of this binary would inherit the
// Prolog runtime of earlier tests, its threads and its allocations (LeakSanitizer's report turns exit 0 into 1).
TEST(SharedMapExportTest, TheReaderRefusesAFifoWithoutWaitingOnIt) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        ::alarm(10);  // opening a FIFO for reading blocks until a writer comes: a hang becomes a failure
        const auto fifo =
            std::string(reader::kNamePrefix) + boost::uuids::to_string(boost::uuids::random_generator()());
        if (::mkfifo(("/dev/shm/" + fifo).c_str(), 0600) != 0) std::exit(3);
        int status = 2;
        try {
          reader::Reader segment(fifo);
        } catch (const reader::Error& e) {
          std::cerr << e.what() << "\n";
          status = std::string(e.what()).find("is not a regular file") != std::string::npos ? 0 : 1;
        }
        ::unlink(("/dev/shm/" + fifo).c_str());
        std::exit(status);
      },
      ::testing::ExitedWithCode(0), "is not a regular file");
}

/// Another process of the server's user, which may map the segment read-write like any file of its own.
class SameUser {
 public:
  explicit SameUser(const std::string& name) {
    fd_ = ::shm_open(("/" + name).c_str(), O_RDWR, 0);
    struct stat info {};
    if (fd_ < 0 || ::fstat(fd_, &info) != 0) std::abort();
    size_ = static_cast<std::size_t>(info.st_size);
    void* mapped = ::mmap(nullptr, size_, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, 0);
    if (mapped == MAP_FAILED) std::abort();
    base_ = static_cast<unsigned char*>(mapped);
  }
  ~SameUser() {
    ::munmap(base_, size_);
    ::close(fd_);
  }
  reader::SegmentHeader& header() { return *reinterpret_cast<reader::SegmentHeader*>(base_); }
  void truncate(std::size_t bytes) { (void)!::ftruncate(fd_, static_cast<off_t>(bytes)); }

 private:
  int fd_ = -1;
  unsigned char* base_ = nullptr;
  std::size_t size_ = 0;
};

// Reads the exporter's current segment as a new reader would and checks every tile: `tiles` tiles (i, 0), each at
// the port's revision. Prints what differs.
bool segment_holds(const shm::SharedMapExport& exporter, CountingGridPort& port, std::size_t tiles) {
  const auto status = exporter.status();
  try {
    reader::Reader segment(status.name);
    if (segment.tile_count() != tiles || segment.state() != reader::SegmentState::live) {
      std::cerr << status.name << ": " << segment.tile_count() << " tiles\n";
      return false;
    }
    const auto grid = port.grid_tiles();
    std::vector<float> cells(4 * CountingGridPort::kTile * CountingGridPort::kTile);
    for (std::size_t slot = 0; slot < tiles; ++slot) {
      const auto key = segment.tile_key(slot);
      const auto revision = segment.read_tile_layers(slot, cells.data());
      const auto expected = std::find_if(grid.tiles.begin(), grid.tiles.end(),
                                         [&](const auto& t) { return t.tx == key.tx && t.ty == key.ty; });
      if (expected == grid.tiles.end() || revision != expected->revision || cells[0] != 4.f * revision) {
        std::cerr << "slot " << slot << " (" << key.tx << ", " << key.ty << ") revision " << revision << "\n";
        return false;
      }
    }
  } catch (const std::exception& e) {
    std::cerr << status.name << ": " << e.what() << "\n";
    return false;
  }
  return true;
}

// Each attack below used to crash the exporter (SIGSEGV or SIGBUS); it runs in a child so that a crash fails the
// test, and the child's stderr shows what differed.
TEST(SharedMapExportTest, ALayoutRewrittenInTheHeaderIsNeitherUsedNorLeftForReaders) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        const bool ok = [] {
          CountingGridPort port;
          for (int i = 0; i < 4; ++i) port.bump(i, 0);
          common::Diagnostics diagnostics("", nullptr);
          shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
          const auto before = exporter.status();
          {
            SameUser other(before.name);
            other.header().slot_bytes = std::uint64_t{1} << 40;
            other.header().tiles_offset = std::uint64_t{1} << 41;
            other.header().tile_capacity = std::uint64_t{1} << 50;
            other.header().map_offset = std::uint64_t{1} << 42;
            other.header().map_capacity_bytes = std::uint64_t{1} << 43;
          }
          for (int pass = 0; pass < 9; ++pass) {
            port.bump(pass % 4, 0);
            exporter.sync();
          }
          const auto after = exporter.status();
          if (after.name == before.name || segment_exists(before.name)) {
            std::cerr << "the rewritten segment was kept\n";
            return false;
          }
          if (after.slot_bytes != before.slot_bytes || after.tiles_offset != before.tiles_offset) {
            std::cerr << "status() took the layout from the mapping\n";
            return false;
          }
          return segment_holds(exporter, port, 4);
        }();
        std::exit(ok ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SharedMapExportTest, ATruncatedSegmentIsReplacedAndTheExporterLivesOn) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(
      {
        const bool ok = [] {
          CountingGridPort port;
          for (int i = 0; i < 4; ++i) port.bump(i, 0);
          common::Diagnostics diagnostics("", nullptr);
          shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
          for (const std::size_t keep : {std::size_t{0}, std::size_t{4096}, std::size_t{8192}}) {
            const auto before = exporter.status().name;
            SameUser(before).truncate(keep);
            for (int pass = 0; pass < 9; ++pass) {
              port.bump(pass % 4, 0);
              exporter.sync();
            }
            if (exporter.status().name == before) {
              std::cerr << "the segment cut to " << keep << " bytes was kept\n";
              return false;
            }
            if (!segment_holds(exporter, port, 4)) return false;
          }
          // Each replacement was reported, not only written to a terminal.
          const auto summary = diagnostics.summary();
          const auto shm = summary.by_where.find("shm");
          if (shm == summary.by_where.end() || shm->second.warnings < 3) {
            std::cerr << "the three replacements were not counted as warnings of \"shm\"\n";
            return false;
          }
          return true;
        }();
        std::exit(ok ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");
}

TEST(SharedMapExportTest, TruncationsRacingTheCopiesNeverKillTheExporter) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  // No check of the size before a write can close this: the file shrinks between the check and the copy.
  EXPECT_EXIT(
      {
        const bool ok = [] {
          CountingGridPort port;
          for (int i = 0; i < 64; ++i) port.bump(i, 0);
          common::Diagnostics diagnostics("", nullptr);
          shm::SharedMapExport exporter(shm::ExportSource{port, port}, fast(), "test-run", diagnostics);
          std::atomic<bool> done{false};
          std::atomic<int> cuts{0};
          std::thread other([&] {
            while (!done) {
              const auto name = exporter.status().name;
              for (int i = 0; i < 200 && !done; ++i) {
                const int fd = ::shm_open(("/" + name).c_str(), O_RDWR, 0);
                if (fd < 0) break;  // replaced: take the new name
                (void)!::ftruncate(fd, i % 2 == 0 ? 0 : 8192);
                ::close(fd);
                ++cuts;
                std::this_thread::sleep_for(50us);
              }
            }
          });
          // At least 1.5 s and 150 truncations (a loaded machine, or a sanitizer build, cuts more slowly), at most 30
          // s.
          const auto start = std::chrono::steady_clock::now();
          const auto racing = [&] {
            const auto now = std::chrono::steady_clock::now();
            return now < start + 30s && (now < start + 1500ms || cuts.load() < 150);
          };
          for (std::uint64_t n = 0; racing(); ++n) {
            for (int i = 0; i < 64; ++i) port.bump(i, 0);
            exporter.sync();
          }
          done = true;
          other.join();
          std::cerr << cuts.load() << " truncations\n";
          for (int pass = 0; pass < 3; ++pass) exporter.sync();
          return cuts.load() > 100 && segment_holds(exporter, port, 64);
        }();
        std::exit(ok ? 0 : 1);
      },
      ::testing::ExitedWithCode(0), "");
}

}  // namespace
}  // namespace wm::testing
