// The texts that drive a robot: a "v w" command datagram to the bridge (--command-udp), a driver's message on
// GET /api/v1/robots/{id}/drive, and a robot's pose report with its telemetry (PUT /api/v1/robots/{id}/pose). The
// first byte picks the parser, the rest is the text. Expected: a value that keeps the parser's promises (finite
// numbers where it says so, within its bounds) or its documented refusal; anything else is a finding.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "clients/robot/command_input.h"
#include "fuzz/fuzz_support.h"
#include "server/api/drive_relay.h"
#include "server/json/codec_error.h"
#include "server/json/robots_json.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const auto text = wm::fuzz::as_text(data + 1, size - 1);
  switch (data[0] % 3) {
    case 0: {
      const auto line = wm::robot::parse_velocity_line(text);
      if (line && text.size() > wm::robot::kMaxCommandBytes) wm::fuzz::fail("a command over the size limit parsed");
      break;
    }
    case 1: {
      std::string error;
      const auto command = wm::api::parse_drive_command(text, error);
      if (command) {
        if (!std::isfinite(command->linear_mps) || !std::isfinite(command->angular_radps) ||
            std::abs(command->linear_mps) > 1e3 || std::abs(command->angular_radps) > 1e3)
          wm::fuzz::fail("a drive command outside its bounds parsed");
      } else if (error.empty()) {
        wm::fuzz::fail("a drive command was refused without a reason");
      }
      break;
    }
    default:
      try {
        const auto report = wm::json_codec::parse_reported_pose(text);
        if (!std::isfinite(report.pose.x) || !std::isfinite(report.pose.y) || !std::isfinite(report.pose.theta))
          wm::fuzz::fail("a pose report with a non-finite pose parsed");
      } catch (const wm::json_codec::CodecError&) {
      }
  }
  return 0;
}
