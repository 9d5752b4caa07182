// Text messages a Foxglove client sends over GET /foxglove, as a hostile client could: any bytes. Expected: a
// message or a ProtocolError; a Subscribe names as many subscriptions as its text can hold (no amplification).
#include <cstddef>
#include <cstdint>
#include <string_view>
#include <variant>

#include "fuzz/fuzz_support.h"
#include "server/foxglove/protocol.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const auto message = wm::foxglove::parse_client_message(text);
    if (const auto* subscribe = std::get_if<wm::foxglove::Subscribe>(&message)) {
      // Each subscription takes at least `{"id":0,"channelId":0}` minus its quotes' worth of text.
      if (subscribe->subscriptions.size() > size / 8 + 1) wm::fuzz::fail("more subscriptions than the text holds");
    } else if (const auto* unsubscribe = std::get_if<wm::foxglove::Unsubscribe>(&message)) {
      if (unsubscribe->subscription_ids.size() > size / 2 + 1) wm::fuzz::fail("more ids than the text holds");
    }
  } catch (const wm::foxglove::ProtocolError&) {
  }
  return 0;
}
