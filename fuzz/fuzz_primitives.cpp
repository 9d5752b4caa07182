// POST /api/v1/primitives bodies with the server's default options and limits. Expected: an observation or a
// json_codec::CodecError (bad_request, naming the field).
#include <cstddef>
#include <cstdint>

#include "fuzz/fuzz_support.h"
#include "server/json/codec.h"
#include "server/json/codec_error.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  static const world::WorldOptions options;
  static const json_codec::PrimitiveLimits limits;
  try {
    json_codec::parse_primitives(fuzz::as_text(data, size), options, limits);
  } catch (const json_codec::CodecError&) {
  }
  return 0;
}
