// POST /api/v1/scans bodies sent as application/cbor: one scan or a batch {"scans": [...]}, ranges as arrays or
// float32 typed arrays (tag 85), with the server's default limits. Expected: the scans, or a json_codec::CodecError
// (bad_request). A document the CBOR reader accepts must also dump as JSON (its text is UTF-8): a scan's observer and
// an error's field name are written into answers and the journal.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz/fuzz_support.h"
#include "server/json/codec.h"
#include "server/json/codec_error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  static const json_codec::ScanLimits limits;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  try {
    (void)json_codec::parse_cbor(bytes, 100000).dump();
  } catch (const json_codec::CodecError&) {
  }
  try {
    json_codec::parse_scan_body(bytes, json_codec::BodyFormat::cbor, limits);
  } catch (const json_codec::CodecError& e) {
    (void)nlohmann::json({{"detail", e.what()}}).dump();  // the error answer, as the server writes it
  }
  return 0;
}
