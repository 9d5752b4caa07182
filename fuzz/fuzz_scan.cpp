// POST /api/v1/scans bodies (laser and sonar) with the server's default limits. Expected: a scan request or a
// json_codec::CodecError (bad_request, naming the field).
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_support.h"
#include "server/json/codec.h"
#include "server/json/codec_error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  static const json_codec::ScanLimits limits;
  try {
    json_codec::parse_scan(fuzz::as_text(data, size), limits);
  } catch (const json_codec::CodecError&) {
  }
  return 0;
}
