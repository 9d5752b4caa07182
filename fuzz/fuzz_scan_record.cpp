// The scan journal's binary records (a row of a SQLite file someone else may have written or damaged). Expected: a
// scan that encodes back to the same bytes, or a storage::StorageError naming what is wrong.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "fuzz/fuzz_support.h"
#include "server/storage/database.h"
#include "server/storage/scan_record.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  const auto record = fuzz::as_text(data, size);
  try {
    const auto scan = storage::decode_scan(record, "fuzz", 0);
    if (storage::encode_scan(scan) != record) std::abort();  // accepted bytes are kept as they were
  } catch (const storage::StorageError&) {
  }
  return 0;
}
