// Servosila datagrams as a bridge or the simulator receives them from the network: any bytes. Expected: a packet
// or a ProtocolError; a decoded packet encodes to the same bytes (control) or decodes again to itself (telemetry,
// whose unused slots and trailing bytes are not kept).
#include <cstddef>
#include <cstdint>
#include <span>

#include "clients/robot/servosila_protocol.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm::robot;
  const std::span<const std::uint8_t> datagram(data, size);
  try {
    const auto type = frame_type(datagram);
    if (type == FrameType::control) {
      const auto packet = decode_control(datagram);
      const auto bytes = encode_control(packet);
      if (!std::equal(bytes.begin(), bytes.end(), datagram.begin(), datagram.end()))
        wm::fuzz::fail("a decoded control packet does not encode to its bytes");
    } else if (type == FrameType::telemetry) {
      const auto packet = decode_telemetry(datagram);
      const auto bytes = encode_telemetry(packet);
      if (!(decode_telemetry(bytes) == packet)) wm::fuzz::fail("a decoded telemetry packet changes when re-encoded");
    }
  } catch (const ProtocolError&) {
  }
  return 0;
}
