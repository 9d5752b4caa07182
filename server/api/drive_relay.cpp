#include "server/api/drive_relay.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "server/api/request.h"
#include "server/api/response.h"
#include "server/json/robots_json.h"

namespace wm::api {
namespace {

using Clock = std::chrono::steady_clock;
using nlohmann::json;

std::string_view target_of(const Request& request) {
  const auto target = request.target();
  return {target.data(), target.size()};
}

constexpr std::string_view kDrivePrefix = "/api/v1/robots/";
constexpr std::string_view kDriveSuffix = "/drive";

double unix_now() { return std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count(); }

/// The robot id of a drive path, nullopt for another path.
std::optional<std::string> drive_robot(std::string_view path) {
  if (!path.starts_with(kDrivePrefix) || !path.ends_with(kDriveSuffix) ||
      path.size() <= kDrivePrefix.size() + kDriveSuffix.size())
    return std::nullopt;
  return std::string(path.substr(kDrivePrefix.size(), path.size() - kDrivePrefix.size() - kDriveSuffix.size()));
}

std::string error_message(std::string_view error, std::string_view detail) {
  return json{{"type", "error"}, {"error", error}, {"detail", detail}}.dump(-1, ' ', false,
                                                                            json::error_handler_t::replace);
}

std::string command_message(double v, double w) { return json{{"v", v}, {"w", w}}.dump(); }

class DriveEndpoint;

}  // namespace

std::optional<DriveCommand> parse_drive_command(std::string_view text, std::string& error) {
  json body;
  try {
    body = json::parse(text.begin(), text.end());
  } catch (const std::exception&) {
    error = "not JSON: send {\"v\": m/s, \"w\": rad/s}";
    return std::nullopt;
  }
  if (!body.is_object()) {
    error = "expected an object {\"v\": m/s, \"w\": rad/s}";
    return std::nullopt;
  }
  for (const auto& [key, value] : body.items()) {
    if (key != "v" && key != "w") {
      error = "unknown field '" + key.substr(0, 64) + "' (v, w)";
      return std::nullopt;
    }
  }
  DriveCommand command;
  for (const char* key : {"v", "w"}) {
    if (!body.contains(key) || !body[key].is_number()) {
      error = std::string(key) + ": expected a number";
      return std::nullopt;
    }
    const double value = body[key].get<double>();
    if (!std::isfinite(value) || std::abs(value) > 1e3) {
      error = std::string(key) + ": expected a finite number (|x| ≤ 1000)";
      return std::nullopt;
    }
    (key[0] == 'v' ? command.linear_mps : command.angular_radps) = value;
  }
  return command;
}

// ---- the relay ----

namespace {

/// One side of a robot's drive connection. Its outbox is taken by the transport; the relay fills it.
class DriveEndpoint : public http::WebSocketEndpoint, public std::enable_shared_from_this<DriveEndpoint> {
 public:
  DriveEndpoint(std::shared_ptr<DriveRelay::Impl> relay, std::string robot, bool driver, std::size_t max_queued)
      : relay_(std::move(relay)), robot_(std::move(robot)), driver_(driver), max_queued_(max_queued) {}

  std::string_view subprotocol() const override { return {}; }
  void open(std::function<void()> wake) override;
  void receive(std::string_view message, bool binary) override;
  std::vector<http::WebSocketFrame> take() override {
    const std::lock_guard lock(mutex_);
    std::vector<http::WebSocketFrame> frames(std::make_move_iterator(outbox_.begin()),
                                             std::make_move_iterator(outbox_.end()));
    outbox_.clear();
    if (command_) {
      frames.emplace_back().head = std::move(*command_);
      command_.reset();
    }
    return frames;
  }

  /// Queues a command for the robot side, replacing one not yet sent: the robot needs only the latest, and a
  /// driver's flood never backs up behind a robot on a slow link.
  void send_command(std::string text) {
    std::function<void()> wake;
    {
      const std::lock_guard lock(mutex_);
      if (closed_) return;
      command_ = std::move(text);
      wake = wake_;
    }
    if (wake) wake();
  }
  void close() override;

  /// Queues a text message (and wakes the transport); `last`: the connection closes after it.
  void send(std::string text, bool last = false) {
    std::function<void()> wake;
    {
      const std::lock_guard lock(mutex_);
      if (closed_) return;
      if (outbox_.size() >= max_queued_) {  // a peer that stopped reading: say so, then close
        last = true;
        text = error_message("queue_full", "messages were not read; closing");
      }
      http::WebSocketFrame frame;
      frame.head = std::move(text);
      frame.close_after = last;
      outbox_.push_back(std::move(frame));
      if (last) closed_ = true;
      wake = wake_;
    }
    if (wake) wake();
  }

  const std::string& robot() const { return robot_; }
  bool is_driver() const { return driver_; }

 private:
  std::shared_ptr<DriveRelay::Impl> relay_;
  std::string robot_;
  bool driver_;
  std::size_t max_queued_;
  std::mutex mutex_;
  std::deque<http::WebSocketFrame> outbox_;
  std::optional<std::string> command_;  // the robot side's latest command, sent after the outbox
  std::function<void()> wake_;
  bool closed_ = false;  // a last message is queued: nothing more
};

}  // namespace

struct DriveRelay::Impl : std::enable_shared_from_this<DriveRelay::Impl> {
  struct Slot {
    std::weak_ptr<DriveEndpoint> robot;
    std::weak_ptr<DriveEndpoint> driver;
    DriveCommand command;  // what the robot was last told
    Clock::time_point last_driver_command;
    std::optional<json> telemetry;
    double telemetry_at = 0.0;
    std::uint64_t commands = 0, refused = 0, lease_stops = 0;
  };

  explicit Impl(const DriveOptions& o) : options(o) {}

  json state_locked(const std::string& id, const Slot& slot) const {
    return {{"type", "state"},
            {"robot", id},
            {"robot_connected", !slot.robot.expired()},
            {"command", {{"v", slot.command.linear_mps}, {"w", slot.command.angular_radps}}},
            {"max_v", options.max_linear_mps},
            {"max_w", options.max_angular_radps},
            {"hold_ms", options.hold_ms},
            {"telemetry", slot.telemetry ? *slot.telemetry : json(nullptr)},
            {"telemetry_at", slot.telemetry ? json(slot.telemetry_at) : json(nullptr)}};
  }

  /// Tells the robot side a command (and the driver the state); with the lock held. The endpoints' send() takes
  /// only their own lock.
  void command_locked(Slot& slot, DriveCommand command) {
    slot.command = command;
    if (auto robot = slot.robot.lock()) robot->send_command(command_message(command.linear_mps, command.angular_radps));
  }

  void tell_driver_locked(const std::string& id, Slot& slot) {
    if (auto driver = slot.driver.lock()) driver->send(state_locked(id, slot).dump());
  }

  void stop_locked(const std::string& id, Slot& slot) {
    const bool was_moving = slot.command.linear_mps != 0.0 || slot.command.angular_radps != 0.0;
    command_locked(slot, DriveCommand{});
    if (was_moving) tell_driver_locked(id, slot);
  }

  void open(const std::shared_ptr<DriveEndpoint>& endpoint) {
    const std::lock_guard lock(mutex);
    Slot& slot = slots[endpoint->robot()];
    if (endpoint->is_driver()) {
      const auto idle = std::chrono::duration<double>(Clock::now() - slot.last_driver_command).count();
      if (auto old = slot.driver.lock(); old && idle > options.driver_takeover_s) {
        stop_locked(endpoint->robot(), slot);
        old->send(error_message("replaced", "another driver took over after " + std::to_string(idle) + " s idle"),
                  true);
        slot.driver.reset();
      }
      if (!slot.driver.expired()) {
        endpoint->send(
            error_message("driver_busy", "robot '" + endpoint->robot() + "' has a driver already: one at a time"),
            true);
        return;
      }
      slot.driver = endpoint;
      slot.last_driver_command = Clock::now();
      endpoint->send(state_locked(endpoint->robot(), slot).dump());
    } else {
      // A robot that reconnects (its old connection half-open) replaces the old one, which is closed.
      if (auto old = slot.robot.lock()) old->send(error_message("replaced", "another robot connection"), true);
      slot.robot = endpoint;
      endpoint->send_command(command_message(0.0, 0.0));
      slot.command = DriveCommand{};
      tell_driver_locked(endpoint->robot(), slot);
    }
  }

  void receive(const std::shared_ptr<DriveEndpoint>& endpoint, std::string_view message, bool binary) {
    const std::lock_guard lock(mutex);
    const auto it = slots.find(endpoint->robot());
    if (it == slots.end()) return;
    Slot& slot = it->second;
    if (!endpoint->is_driver()) return;          // the robot side only listens (telemetry comes with its pose reports)
    if (slot.driver.lock() != endpoint) return;  // a refused second driver
    std::string error;
    std::optional<DriveCommand> command;
    if (binary) {
      error = "binary message: send JSON text {\"v\", \"w\"}";
    } else if (message.size() > options.max_message_bytes) {
      error = "message of " + std::to_string(message.size()) + " bytes (at most " +
              std::to_string(options.max_message_bytes) + ")";
    } else {
      command = parse_drive_command(message, error);
    }
    if (!command) {  // whatever the driver meant, the safe reading is a stop
      ++slot.refused;
      stop_locked(endpoint->robot(), slot);
      endpoint->send(error_message("bad_command", error));
      return;
    }
    ++slot.commands;
    slot.last_driver_command = Clock::now();
    const DriveCommand clamped{
        std::clamp(command->linear_mps, -options.max_linear_mps, options.max_linear_mps),
        std::clamp(command->angular_radps, -options.max_angular_radps, options.max_angular_radps)};
    const bool changed =
        clamped.linear_mps != slot.command.linear_mps || clamped.angular_radps != slot.command.angular_radps;
    command_locked(slot, clamped);  // every command, so that the robot side's lease renews
    if (changed) tell_driver_locked(endpoint->robot(), slot);
  }

  void close(const std::shared_ptr<DriveEndpoint>& endpoint) {
    const std::lock_guard lock(mutex);
    const auto it = slots.find(endpoint->robot());
    if (it == slots.end()) return;
    Slot& slot = it->second;
    if (endpoint->is_driver()) {
      if (slot.driver.lock() == endpoint || slot.driver.expired()) {
        slot.driver.reset();
        stop_locked(endpoint->robot(), slot);  // the driver left: stop at once
      }
    } else if (slot.robot.lock() == endpoint || slot.robot.expired()) {
      slot.robot.reset();
      slot.command = DriveCommand{};
      tell_driver_locked(endpoint->robot(), slot);
    }
  }

  void lease_loop() {
    const auto hold = std::chrono::milliseconds(options.hold_ms);
    std::unique_lock lock(mutex);
    while (!quit) {
      wake.wait_for(lock, std::chrono::milliseconds(10));
      const auto now = Clock::now();
      for (auto& [id, slot] : slots) {
        const bool moving = slot.command.linear_mps != 0.0 || slot.command.angular_radps != 0.0;
        if (moving && now - slot.last_driver_command > hold) {
          ++slot.lease_stops;
          stop_locked(id, slot);
        }
      }
    }
  }

  DriveOptions options;
  mutable std::mutex mutex;
  std::condition_variable wake;
  bool quit = false;
  std::map<std::string, Slot> slots;
  std::thread lease_thread;
};

namespace {

void DriveEndpoint::open(std::function<void()> wake) {
  {
    const std::lock_guard lock(mutex_);
    wake_ = std::move(wake);
  }
  relay_->open(shared_from_this());
}

void DriveEndpoint::receive(std::string_view message, bool binary) {
  relay_->receive(shared_from_this(), message, binary);
}

void DriveEndpoint::close() {
  {
    const std::lock_guard lock(mutex_);
    closed_ = true;
    wake_ = nullptr;
  }
  relay_->close(shared_from_this());
}

}  // namespace

DriveRelay::DriveRelay(const DriveOptions& options) : impl_(std::make_shared<Impl>(options)) {
  impl_->lease_thread = std::thread([impl = impl_.get()] { impl->lease_loop(); });
}

DriveRelay::~DriveRelay() {
  {
    const std::lock_guard lock(impl_->mutex);
    impl_->quit = true;
  }
  impl_->wake.notify_all();
  impl_->lease_thread.join();
}

const DriveOptions& DriveRelay::options() const { return impl_->options; }

std::shared_ptr<http::WebSocketEndpoint> DriveRelay::connect(const Request& request) {
  const auto target = parse_target(target_of(request));
  const auto robot = drive_robot(target.path);
  if (!robot || !json_codec::valid_robot_id(*robot)) return nullptr;
  const bool driver = target.param("role").value_or("driver") != "robot";
  return std::make_shared<DriveEndpoint>(impl_, *robot, driver, impl_->options.max_queued_messages);
}

void DriveRelay::put_telemetry(const std::string& robot_id, json telemetry) {
  const std::lock_guard lock(impl_->mutex);
  auto& slot = impl_->slots[robot_id];
  slot.telemetry = std::move(telemetry);
  slot.telemetry_at = unix_now();
  impl_->tell_driver_locked(robot_id, slot);
}

json DriveRelay::robot_live(const std::string& robot_id, bool& fault) const {
  const std::lock_guard lock(impl_->mutex);
  fault = false;
  const auto it = impl_->slots.find(robot_id);
  if (it == impl_->slots.end()) {
    return {{"telemetry", nullptr},
            {"telemetry_at", nullptr},
            {"drive",
             {{"robot_connected", false},
              {"driver_connected", false},
              {"command", {{"v", 0.0}, {"w", 0.0}}},
              {"max_v", impl_->options.max_linear_mps},
              {"max_w", impl_->options.max_angular_radps},
              {"hold_ms", impl_->options.hold_ms}}}};
  }
  const auto& slot = it->second;
  fault = slot.telemetry && slot.telemetry->value("fault", false);
  return {{"telemetry", slot.telemetry ? *slot.telemetry : json(nullptr)},
          {"telemetry_at", slot.telemetry ? json(slot.telemetry_at) : json(nullptr)},
          {"drive",
           {{"robot_connected", !slot.robot.expired()},
            {"driver_connected", !slot.driver.expired()},
            {"command", {{"v", slot.command.linear_mps}, {"w", slot.command.angular_radps}}},
            {"max_v", impl_->options.max_linear_mps},
            {"max_w", impl_->options.max_angular_radps},
            {"hold_ms", impl_->options.hold_ms}}}};
}

std::optional<Response> authorize_drive(const Request& request) {
  try {
    const auto target = parse_target(target_of(request));
    const auto robot = drive_robot(target.path);
    if (!robot) return std::nullopt;
    if (!json_codec::valid_robot_id(*robot))
      return error_response(request.version(), false, 400, "bad_request",
                            "id: a robot id is 1 to 128 of A-Z a-z 0-9 . _ : -");
    const auto role = target.param("role").value_or("driver");
    if (role != "driver" && role != "robot")
      return error_response(request.version(), false, 400, "bad_request", "role: expected driver or robot");
  } catch (...) {
    return error_response(request.version(), false, 400, "bad_request", "malformed target");
  }
  return std::nullopt;
}

}  // namespace wm::api
