#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

// The Servosila Engineer's remote-control protocol over UDP (clients/robot/PROTOCOL.md has the byte tables and
// where each fact comes from). Both packets are packed (no padding) and every multi-byte field is little-endian:
// the vendor's and the authors' software send the raw memory of packed C structs, and both ends are x86.
// Encoding and decoding go field by field through explicit shifts, never through memcpy of a struct, so the
// layout does not depend on this compiler's padding or byte order.

namespace wm::robot {

/// The first byte of every packet. The paper names the field without values; these are the authors' library's.
enum class FrameType : std::uint8_t {
  control = 1,      // operator → robot, 57 bytes
  telemetry = 2,    // robot → operator, 275 bytes
  video_frame = 4,  // robot → operator, a camera frame (not decoded here; a receiver skips it)
};

inline constexpr std::size_t kControlPacketSize = 57;
inline constexpr std::size_t kTelemetryPacketSize = 275;
inline constexpr std::size_t kMotorRecordSize = 24;
inline constexpr std::size_t kAxisCount = 16;
inline constexpr std::size_t kButtonCount = 16;
/// Motor records in a telemetry packet: always 10 slots on the wire, of which `motor count` are valid.
inline constexpr std::size_t kMaxMotors = 10;
/// Telemetry offsets: frame type (1) + tick (8) + motor count (1), then the records, then 25 unused bytes.
inline constexpr std::size_t kMotorRecordsOffset = 10;
inline constexpr std::size_t kTelemetryUnusedBytes = 25;

/// A packet that cannot be decoded. reason() says which check failed; what() adds the numbers.
class ProtocolError : public std::runtime_error {
 public:
  enum class Reason {
    wrong_size,          // datagram length is not the packet's size
    unknown_frame_type,  // first byte is not a FrameType
    wrong_frame_type,    // a known frame type, but not the one this decoder reads
    too_many_motors,     // telemetry motor count > kMaxMotors
    non_finite,          // the control packet's video bit rate is NaN or infinite
  };
  ProtocolError(Reason reason, const std::string& detail);
  Reason reason() const { return reason_; }

 private:
  Reason reason_;
};

/// The remote-control packet (the operator's game controller, sent five times a second).
/// Wire layout, 57 bytes: [0] frame type = 1 (uint8); [1..32] axes 0..15 (int16 LE each);
/// [33..48] buttons 0..15 (uint8 each); [49..56] video bit rate (IEEE 754 binary64 LE).
struct ControlPacket {
  std::array<std::int16_t, kAxisCount> axes{};       // stick positions, −32768..32767
  std::array<std::uint8_t, kButtonCount> buttons{};  // 0 = released
  double video_bit_rate = 0.0;                       // "video bit rate telemetry"; this library sends 0

  bool operator==(const ControlPacket&) const = default;
};

/// One motor's record in a telemetry packet. Wire layout, 24 bytes, little-endian:
/// [0] device id (uint8); [1] device state (uint8); [2] operation mode (uint8); [3..6] position (uint32);
/// [7..8] speed (int16); [9..10] amps (int16); [11..12] status bits (int16); [13..16] position command (uint32);
/// [17..18] speed command (int16); [19..20] amps command (int16); [21] fault detected (uint8);
/// [22..23] faults counter (uint16). Units are the controller's own (the protocol states none). The paper's
/// record table lists only the first ten fields (21 bytes) of its 24-byte record; the last two are the authors'
/// library's, and the paper's text names both (an error flag and an error counter).
struct MotorRecord {
  std::uint8_t device_id = 0;
  std::uint8_t device_state = 0;
  std::uint8_t operation_mode = 0;
  std::uint32_t position = 0;  // encoder count; wraps around at 2^32
  std::int16_t speed = 0;
  std::int16_t amps = 0;
  std::int16_t status_bits = 0;
  std::uint32_t position_command = 0;
  std::int16_t speed_command = 0;
  std::int16_t amps_command = 0;
  std::uint8_t fault_detected = 0;
  std::uint16_t faults_counter = 0;

  bool operator==(const MotorRecord&) const = default;
};

/// The telemetry packet (robot → operator; once a second on the real robot). Wire layout, 275 bytes:
/// [0] frame type = 2 (uint8); [1..8] tick number (uint64 LE); [9] motor count (uint8, ≤ 10);
/// [10..249] 10 motor records of 24 bytes (only the first `motor count` are meaningful); [250..274] unused.
struct TelemetryPacket {
  std::uint64_t tick = 0;
  std::vector<MotorRecord> motors;  // size() is the motor count, ≤ kMaxMotors

  bool operator==(const TelemetryPacket&) const = default;
};

/// The frame type of a datagram, from its first byte, to route it before decoding.
/// @throw ProtocolError (wrong_size) for an empty datagram, (unknown_frame_type) for a byte that is not a FrameType.
FrameType frame_type(std::span<const std::uint8_t> datagram);

/// The 57 wire bytes of a control packet.
/// @throw std::invalid_argument when video_bit_rate is not finite (the robot would read garbage).
std::array<std::uint8_t, kControlPacketSize> encode_control(const ControlPacket& packet);

/// @throw ProtocolError: wrong_size (not 57 bytes), unknown_frame_type, wrong_frame_type (not 1),
///        non_finite (video bit rate NaN or ±∞).
ControlPacket decode_control(std::span<const std::uint8_t> datagram);

/// The 275 wire bytes of a telemetry packet; unused record slots and the trailing 25 bytes are zero.
/// @throw std::invalid_argument when packet.motors has more than kMaxMotors records.
std::array<std::uint8_t, kTelemetryPacketSize> encode_telemetry(const TelemetryPacket& packet);

/// Reads the first `motor count` records; the unused slots and trailing bytes are ignored, whatever they hold.
/// @throw ProtocolError: wrong_size (not 275 bytes), unknown_frame_type, wrong_frame_type (not 2),
///        too_many_motors (motor count > 10).
TelemetryPacket decode_telemetry(std::span<const std::uint8_t> datagram);

/// A short stable name for a reason ("wrong_size", ...), for counters and logs.
const char* to_string(ProtocolError::Reason reason);

}  // namespace wm::robot
