#include "clients/robot/servosila_protocol.h"

#include <bit>
#include <cmath>
#include <limits>

namespace wm::robot {

// The double travels as its IEEE 754 bit pattern; a platform with another double format would need a conversion.
static_assert(std::numeric_limits<double>::is_iec559, "the video bit rate is an IEEE 754 binary64 on the wire");
// The field tables add up to the sizes the protocol states (57, 24 and 275 bytes).
static_assert(1 + 2 * kAxisCount + kButtonCount + 8 == kControlPacketSize);
static_assert(3 * 1 + 4 + 3 * 2 + 4 + 2 * 2 + 1 + 2 == kMotorRecordSize);
static_assert(kMotorRecordsOffset == 1 + 8 + 1);
static_assert(kMotorRecordsOffset + kMaxMotors * kMotorRecordSize + kTelemetryUnusedBytes == kTelemetryPacketSize);

namespace {

/// Appends little-endian fields to a fixed buffer; the caller's layout tables decide the order.
class Writer {
 public:
  explicit Writer(std::span<std::uint8_t> out) : out_(out) {}
  void u8(std::uint8_t v) { out_[pos_++] = v; }
  void u16(std::uint16_t v) { unsigned_le(v, 2); }
  void u32(std::uint32_t v) { unsigned_le(v, 4); }
  void u64(std::uint64_t v) { unsigned_le(v, 8); }
  // Two's complement, as the robot's x86 stores it.
  void i16(std::int16_t v) { u16(static_cast<std::uint16_t>(v)); }
  void f64(double v) { u64(std::bit_cast<std::uint64_t>(v)); }

 private:
  void unsigned_le(std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) out_[pos_++] = static_cast<std::uint8_t>(v >> (8 * i));
  }
  std::span<std::uint8_t> out_;
  std::size_t pos_ = 0;
};

/// Reads little-endian fields; sizes are checked by the caller before the first read.
class Reader {
 public:
  explicit Reader(std::span<const std::uint8_t> in) : in_(in) {}
  std::uint8_t u8() { return in_[pos_++]; }
  std::uint16_t u16() { return static_cast<std::uint16_t>(unsigned_le(2)); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(unsigned_le(4)); }
  std::uint64_t u64() { return unsigned_le(8); }
  std::int16_t i16() { return static_cast<std::int16_t>(u16()); }
  double f64() { return std::bit_cast<double>(u64()); }
  void skip(std::size_t n) { pos_ += n; }

 private:
  std::uint64_t unsigned_le(int bytes) {
    std::uint64_t v = 0;
    for (int i = 0; i < bytes; ++i) v |= static_cast<std::uint64_t>(in_[pos_++]) << (8 * i);
    return v;
  }
  std::span<const std::uint8_t> in_;
  std::size_t pos_ = 0;
};

void check_packet(std::span<const std::uint8_t> datagram, std::size_t size, FrameType expected, const char* what) {
  if (datagram.size() != size) {
    throw ProtocolError(ProtocolError::Reason::wrong_size, std::string(what) + ": " + std::to_string(datagram.size()) +
                                                               " bytes, expected " + std::to_string(size));
  }
  const FrameType type = frame_type(datagram);
  if (type != expected) {
    throw ProtocolError(ProtocolError::Reason::wrong_frame_type,
                        std::string(what) + ": frame type " + std::to_string(static_cast<int>(type)) + ", expected " +
                            std::to_string(static_cast<int>(expected)));
  }
}

void write_motor(Writer& w, const MotorRecord& m) {
  w.u8(m.device_id);
  w.u8(m.device_state);
  w.u8(m.operation_mode);
  w.u32(m.position);
  w.i16(m.speed);
  w.i16(m.amps);
  w.i16(m.status_bits);
  w.u32(m.position_command);
  w.i16(m.speed_command);
  w.i16(m.amps_command);
  w.u8(m.fault_detected);
  w.u16(m.faults_counter);
}

MotorRecord read_motor(Reader& r) {
  MotorRecord m;
  m.device_id = r.u8();
  m.device_state = r.u8();
  m.operation_mode = r.u8();
  m.position = r.u32();
  m.speed = r.i16();
  m.amps = r.i16();
  m.status_bits = r.i16();
  m.position_command = r.u32();
  m.speed_command = r.i16();
  m.amps_command = r.i16();
  m.fault_detected = r.u8();
  m.faults_counter = r.u16();
  return m;
}

}  // namespace

ProtocolError::ProtocolError(Reason reason, const std::string& detail)
    : std::runtime_error(std::string("servosila protocol: ") + to_string(reason) + ": " + detail), reason_(reason) {}

const char* to_string(ProtocolError::Reason reason) {
  switch (reason) {
    case ProtocolError::Reason::wrong_size:
      return "wrong_size";
    case ProtocolError::Reason::unknown_frame_type:
      return "unknown_frame_type";
    case ProtocolError::Reason::wrong_frame_type:
      return "wrong_frame_type";
    case ProtocolError::Reason::too_many_motors:
      return "too_many_motors";
    case ProtocolError::Reason::non_finite:
      return "non_finite";
  }
  return "unknown";
}

FrameType frame_type(std::span<const std::uint8_t> datagram) {
  if (datagram.empty()) throw ProtocolError(ProtocolError::Reason::wrong_size, "empty datagram");
  const std::uint8_t first = datagram[0];
  switch (first) {
    case static_cast<std::uint8_t>(FrameType::control):
    case static_cast<std::uint8_t>(FrameType::telemetry):
    case static_cast<std::uint8_t>(FrameType::video_frame):
      return static_cast<FrameType>(first);
    default:
      throw ProtocolError(ProtocolError::Reason::unknown_frame_type, "frame type " + std::to_string(first));
  }
}

std::array<std::uint8_t, kControlPacketSize> encode_control(const ControlPacket& packet) {
  if (!std::isfinite(packet.video_bit_rate)) {
    throw std::invalid_argument("encode_control: video_bit_rate is not finite");
  }
  std::array<std::uint8_t, kControlPacketSize> out{};
  Writer w(out);
  w.u8(static_cast<std::uint8_t>(FrameType::control));
  for (const std::int16_t axis : packet.axes) w.i16(axis);
  for (const std::uint8_t button : packet.buttons) w.u8(button);
  w.f64(packet.video_bit_rate);
  return out;
}

ControlPacket decode_control(std::span<const std::uint8_t> datagram) {
  check_packet(datagram, kControlPacketSize, FrameType::control, "control packet");
  Reader r(datagram);
  r.skip(1);
  ControlPacket packet;
  for (std::int16_t& axis : packet.axes) axis = r.i16();
  for (std::uint8_t& button : packet.buttons) button = r.u8();
  packet.video_bit_rate = r.f64();
  if (!std::isfinite(packet.video_bit_rate)) {
    throw ProtocolError(ProtocolError::Reason::non_finite, "control packet: video bit rate is not finite");
  }
  return packet;
}

std::array<std::uint8_t, kTelemetryPacketSize> encode_telemetry(const TelemetryPacket& packet) {
  if (packet.motors.size() > kMaxMotors) {
    throw std::invalid_argument("encode_telemetry: " + std::to_string(packet.motors.size()) + " motors, at most " +
                                std::to_string(kMaxMotors));
  }
  std::array<std::uint8_t, kTelemetryPacketSize> out{};
  Writer w(out);
  w.u8(static_cast<std::uint8_t>(FrameType::telemetry));
  w.u64(packet.tick);
  w.u8(static_cast<std::uint8_t>(packet.motors.size()));
  for (const MotorRecord& motor : packet.motors) write_motor(w, motor);
  // Unused record slots and the 25 trailing bytes stay zero.
  return out;
}

TelemetryPacket decode_telemetry(std::span<const std::uint8_t> datagram) {
  check_packet(datagram, kTelemetryPacketSize, FrameType::telemetry, "telemetry packet");
  Reader r(datagram);
  r.skip(1);
  TelemetryPacket packet;
  packet.tick = r.u64();
  const std::uint8_t count = r.u8();
  if (count > kMaxMotors) {
    throw ProtocolError(
        ProtocolError::Reason::too_many_motors,
        "telemetry packet: motor count " + std::to_string(count) + ", at most " + std::to_string(kMaxMotors));
  }
  packet.motors.reserve(count);
  for (std::uint8_t i = 0; i < count; ++i) packet.motors.push_back(read_motor(r));
  return packet;
}

}  // namespace wm::robot
