#include "clients/robot/servosila_protocol.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <random>
#include <vector>

namespace wm::robot {
namespace {

using Bytes = std::vector<std::uint8_t>;

std::optional<ProtocolError::Reason> reason_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ProtocolError& e) {
    return e.reason();
  }
  return std::nullopt;
}

// A control packet written out byte by byte from the layout table (57 bytes, packed, little-endian):
// frame type, 16 int16 axes, 16 uint8 buttons, the video bit rate as an IEEE 754 double.
const Bytes kControlBytes = {
    0x01,                                            // [0] frame type 1: remote control
    0x40, 0xA2,                                      // [1..2] axis 0 = -24000 (0xA240)
    0xAB, 0xB9,                                      // [3..4] axis 1 = -18005 (0xB9AB)
    0x02, 0x01,                                      // [5..6] axis 2 = 258 (0x0102)
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // [7..14] axes 3..6 = 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // [15..22] axes 7..10 = 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00,              // [23..28] axes 11..13 = 0
    0x00, 0x80,                                      // [29..30] axis 14 = -32768 (0x8000)
    0xFF, 0x7F,                                      // [31..32] axis 15 = 32767 (0x7FFF)
    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // [33..40] button 0 = 1, buttons 1..7 = 0
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xFF,  // [41..48] buttons 8..14 = 0, button 15 = 255
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x3F,  // [49..56] video bit rate 1.5 (0x3FF8000000000000)
};

ControlPacket expected_control() {
  ControlPacket p;
  p.axes[0] = -24000;
  p.axes[1] = -18005;
  p.axes[2] = 258;
  p.axes[14] = -32768;
  p.axes[15] = 32767;
  p.buttons[0] = 1;
  p.buttons[15] = 255;
  p.video_bit_rate = 1.5;
  return p;
}

// The first 58 bytes of a telemetry packet written out from the layout tables: frame type, uint64 tick,
// motor count, then two 24-byte motor records (id, state, mode, uint32 position, int16 speed, int16 amps,
// int16 status bits, uint32 position command, int16 speed command, int16 amps command, uint8 fault detected,
// uint16 faults counter). The remaining 8 record slots and the 25 unused bytes are zero (kTelemetryBytes()).
const Bytes kTelemetryPrefix = {
    0x02,                                            // [0] frame type 2: telemetry
    0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // [1..8] tick 0x0102030405060708
    0x02,                                            // [9] motor count 2
    // record 0, bytes [10..33]
    0x07,                    // device id 7
    0x02,                    // device state 2
    0x03,                    // operation mode 3
    0xEF, 0xCD, 0xAB, 0x89,  // position 0x89ABCDEF
    0xFE, 0xFF,              // speed -2
    0x02, 0x01,              // amps 258
    0x01, 0x80,              // status bits 0x8001 (-32767)
    0x00, 0x00, 0x01, 0x00,  // position command 65536
    0x2C, 0x01,              // speed command 300
    0xD4, 0xFE,              // amps command -300
    0x01,                    // fault detected 1
    0xEF, 0xBE,              // faults counter 0xBEEF
    // record 1, bytes [34..57]
    0x08,                    // device id 8
    0x01,                    // device state 1
    0x00,                    // operation mode 0
    0xFF, 0xFF, 0xFF, 0xFF,  // position 4294967295
    0x00, 0x80,              // speed -32768
    0xFF, 0x7F,              // amps 32767
    0x00, 0x00,              // status bits 0
    0x00, 0x00, 0x00, 0x00,  // position command 0
    0x00, 0x00,              // speed command 0
    0x00, 0x00,              // amps command 0
    0x00,                    // fault detected 0
    0x00, 0x00,              // faults counter 0
};

Bytes telemetry_bytes() {
  Bytes bytes(275, 0x00);
  std::copy(kTelemetryPrefix.begin(), kTelemetryPrefix.end(), bytes.begin());
  return bytes;
}

TelemetryPacket expected_telemetry() {
  TelemetryPacket p;
  p.tick = 0x0102030405060708ULL;
  MotorRecord a;
  a.device_id = 7;
  a.device_state = 2;
  a.operation_mode = 3;
  a.position = 0x89ABCDEFU;
  a.speed = -2;
  a.amps = 258;
  a.status_bits = -32767;
  a.position_command = 65536;
  a.speed_command = 300;
  a.amps_command = -300;
  a.fault_detected = 1;
  a.faults_counter = 0xBEEF;
  MotorRecord b;
  b.device_id = 8;
  b.device_state = 1;
  b.position = 4294967295U;
  b.speed = -32768;
  b.amps = 32767;
  p.motors = {a, b};
  return p;
}

TEST(ServosilaProtocolTest, LayoutSizesAreTheStatedOnes) {
  EXPECT_EQ(kControlBytes.size(), kControlPacketSize);
  EXPECT_EQ(kControlPacketSize, 57u);
  EXPECT_EQ(kTelemetryPacketSize, 275u);
  EXPECT_EQ(kMotorRecordSize, 24u);
  EXPECT_EQ(kTelemetryPrefix.size(), 10u + 2 * 24u);
}

TEST(ServosilaProtocolTest, DecodesHandWrittenControlPacket) {
  EXPECT_EQ(decode_control(kControlBytes), expected_control());
}

TEST(ServosilaProtocolTest, EncodesControlPacketToHandWrittenBytes) {
  const auto bytes = encode_control(expected_control());
  EXPECT_EQ(Bytes(bytes.begin(), bytes.end()), kControlBytes);
}

TEST(ServosilaProtocolTest, EncodesAllZeroControlPacketAsFrameTypeAndZeros) {
  const auto bytes = encode_control(ControlPacket{});
  Bytes expected(57, 0x00);
  expected[0] = 0x01;
  EXPECT_EQ(Bytes(bytes.begin(), bytes.end()), expected);
}

TEST(ServosilaProtocolTest, DecodesHandWrittenTelemetryPacket) {
  EXPECT_EQ(decode_telemetry(telemetry_bytes()), expected_telemetry());
}

TEST(ServosilaProtocolTest, EncodesTelemetryPacketToHandWrittenBytes) {
  const auto bytes = encode_telemetry(expected_telemetry());
  EXPECT_EQ(Bytes(bytes.begin(), bytes.end()), telemetry_bytes());
}

TEST(ServosilaProtocolTest, IgnoresUnusedRecordSlotsAndTrailingBytes) {
  Bytes bytes = telemetry_bytes();
  bytes[58] = 0xAA;   // first byte of record slot 2, beyond the motor count
  bytes[249] = 0xAB;  // last byte of record slot 9
  bytes[250] = 0x11;  // first of the 25 unused bytes
  bytes[274] = 0x55;  // last byte of the packet
  EXPECT_EQ(decode_telemetry(bytes), expected_telemetry());
}

TEST(ServosilaProtocolTest, ReadsRecordsAtTheirOffsets) {
  // Ten records, each with its slot number as device id and a position of 0x01000000·slot: the tenth record
  // starts at byte 10 + 9·24 = 226, its position at 229.
  Bytes bytes(275, 0x00);
  bytes[0] = 0x02;
  bytes[9] = 10;
  for (int slot = 0; slot < 10; ++slot) {
    bytes[10 + 24 * slot] = static_cast<std::uint8_t>(slot);
    bytes[10 + 24 * slot + 6] = static_cast<std::uint8_t>(slot);  // the position's most significant byte
  }
  const TelemetryPacket p = decode_telemetry(bytes);
  ASSERT_EQ(p.motors.size(), 10u);
  for (std::uint32_t slot = 0; slot < 10; ++slot) {
    EXPECT_EQ(p.motors[slot].device_id, slot);
    EXPECT_EQ(p.motors[slot].position, slot << 24);
  }
  EXPECT_EQ(bytes[229 + 3], 9);
}

TEST(ServosilaProtocolTest, RoundTripsControlPackets) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> axis(-32768, 32767);
  std::uniform_int_distribution<int> button(0, 255);
  std::uniform_real_distribution<double> rate(-1e9, 1e9);
  for (int i = 0; i < 200; ++i) {
    ControlPacket p;
    for (auto& a : p.axes) a = static_cast<std::int16_t>(axis(rng));
    for (auto& b : p.buttons) b = static_cast<std::uint8_t>(button(rng));
    p.video_bit_rate = i == 0 ? std::numeric_limits<double>::max() : rate(rng);
    EXPECT_EQ(decode_control(encode_control(p)), p);
  }
}

TEST(ServosilaProtocolTest, RoundTripsTelemetryPackets) {
  std::mt19937_64 rng(11);
  for (std::size_t count = 0; count <= kMaxMotors; ++count) {
    TelemetryPacket p;
    p.tick = rng();
    for (std::size_t i = 0; i < count; ++i) {
      MotorRecord m;
      m.device_id = static_cast<std::uint8_t>(rng());
      m.device_state = static_cast<std::uint8_t>(rng());
      m.operation_mode = static_cast<std::uint8_t>(rng());
      m.position = static_cast<std::uint32_t>(rng());
      m.speed = static_cast<std::int16_t>(rng());
      m.amps = static_cast<std::int16_t>(rng());
      m.status_bits = static_cast<std::int16_t>(rng());
      m.position_command = static_cast<std::uint32_t>(rng());
      m.speed_command = static_cast<std::int16_t>(rng());
      m.amps_command = static_cast<std::int16_t>(rng());
      m.fault_detected = static_cast<std::uint8_t>(rng());
      m.faults_counter = static_cast<std::uint16_t>(rng());
      p.motors.push_back(m);
    }
    EXPECT_EQ(decode_telemetry(encode_telemetry(p)), p);
  }
}

TEST(ServosilaProtocolTest, FrameTypeRoutesByFirstByte) {
  EXPECT_EQ(frame_type(Bytes{0x01}), FrameType::control);
  EXPECT_EQ(frame_type(Bytes{0x02, 0x00}), FrameType::telemetry);
  EXPECT_EQ(frame_type(Bytes{0x04, 0xFF, 0xD8}), FrameType::video_frame);
  EXPECT_EQ(reason_of([] { frame_type(Bytes{}); }), ProtocolError::Reason::wrong_size);
  EXPECT_EQ(reason_of([] { frame_type(Bytes{0x03}); }), ProtocolError::Reason::unknown_frame_type);
  EXPECT_EQ(reason_of([] { frame_type(Bytes{0x00}); }), ProtocolError::Reason::unknown_frame_type);
}

TEST(ServosilaProtocolTest, RejectsControlPacketOfWrongSize) {
  for (const std::size_t size : {0u, 1u, 56u, 58u, 275u}) {
    Bytes bytes(size, 0x00);
    if (size > 0) bytes[0] = 0x01;
    EXPECT_EQ(reason_of([&] { decode_control(bytes); }), ProtocolError::Reason::wrong_size) << size;
  }
}

TEST(ServosilaProtocolTest, RejectsControlPacketWithUnknownOrOtherFrameType) {
  Bytes bytes = kControlBytes;
  bytes[0] = 0x03;
  EXPECT_EQ(reason_of([&] { decode_control(bytes); }), ProtocolError::Reason::unknown_frame_type);
  bytes[0] = 0x02;
  EXPECT_EQ(reason_of([&] { decode_control(bytes); }), ProtocolError::Reason::wrong_frame_type);
  bytes[0] = 0x04;
  EXPECT_EQ(reason_of([&] { decode_control(bytes); }), ProtocolError::Reason::wrong_frame_type);
}

TEST(ServosilaProtocolTest, RejectsControlPacketWithNonFiniteBitRate) {
  const Bytes nan = {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x7F};         // quiet NaN 0x7FF8000000000000
  const Bytes plus_inf = {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0x7F};    // +inf 0x7FF0000000000000
  const Bytes minus_inf = {0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0xFF};   // -inf 0xFFF0000000000000
  const Bytes signalling = {0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF0, 0x7F};  // NaN 0x7FF0000000000001
  for (const Bytes& rate : {nan, plus_inf, minus_inf, signalling}) {
    Bytes bytes = kControlBytes;
    std::copy(rate.begin(), rate.end(), bytes.begin() + 49);
    EXPECT_EQ(reason_of([&] { decode_control(bytes); }), ProtocolError::Reason::non_finite);
  }
}

TEST(ServosilaProtocolTest, RejectsTelemetryPacketOfWrongSize) {
  for (const std::size_t size : {0u, 10u, 57u, 274u, 276u}) {
    Bytes bytes(size, 0x00);
    if (size > 0) bytes[0] = 0x02;
    EXPECT_EQ(reason_of([&] { decode_telemetry(bytes); }), ProtocolError::Reason::wrong_size) << size;
  }
}

TEST(ServosilaProtocolTest, RejectsTelemetryPacketWithUnknownOrOtherFrameType) {
  Bytes bytes = telemetry_bytes();
  bytes[0] = 0x00;
  EXPECT_EQ(reason_of([&] { decode_telemetry(bytes); }), ProtocolError::Reason::unknown_frame_type);
  bytes[0] = 0x01;
  EXPECT_EQ(reason_of([&] { decode_telemetry(bytes); }), ProtocolError::Reason::wrong_frame_type);
}

TEST(ServosilaProtocolTest, RejectsTelemetryPacketWithMoreThanTenMotors) {
  Bytes bytes = telemetry_bytes();
  bytes[9] = 10;
  EXPECT_EQ(decode_telemetry(bytes).motors.size(), 10u);
  bytes[9] = 11;
  EXPECT_EQ(reason_of([&] { decode_telemetry(bytes); }), ProtocolError::Reason::too_many_motors);
  bytes[9] = 255;
  EXPECT_EQ(reason_of([&] { decode_telemetry(bytes); }), ProtocolError::Reason::too_many_motors);
}

TEST(ServosilaProtocolTest, ErrorMessageNamesTheReasonAndNumbers) {
  try {
    decode_telemetry(Bytes(274, 0x02));
    FAIL() << "no ProtocolError";
  } catch (const ProtocolError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("wrong_size"), std::string::npos) << what;
    EXPECT_NE(what.find("274"), std::string::npos) << what;
    EXPECT_NE(what.find("275"), std::string::npos) << what;
  }
}

TEST(ServosilaProtocolTest, EncodersRefuseWhatTheWireCannotCarry) {
  ControlPacket control;
  control.video_bit_rate = std::nan("");
  EXPECT_THROW(encode_control(control), std::invalid_argument);
  control.video_bit_rate = std::numeric_limits<double>::infinity();
  EXPECT_THROW(encode_control(control), std::invalid_argument);
  TelemetryPacket telemetry;
  telemetry.motors.resize(11);
  EXPECT_THROW(encode_telemetry(telemetry), std::invalid_argument);
}

}  // namespace
}  // namespace wm::robot
