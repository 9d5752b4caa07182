// Requests to the maps and to one map's routes (/api/v1/maps, /api/v1/maps/{map}/...), through the api's router
// onto real maps: a MapRegistry in a temporary directory with two maps on the shipped rules, one of them standing
// in as the default map, with their shared-memory exports. The first byte picks the method, the rest is the target.
// Expected: every request answered (handle_request never throws) with a status other than 500, and a JSON error body
// for every refusal. Writes need a token the inputs do not have, so the maps stay as made and each input meets the
// same server. A GET target is also tried as a Foxglove WebSocket upgrade: authorize_events and foxglove_map never
// throw, and an upgrade allowed with a map named in its query names a map the server has.
#include <unistd.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "common/diagnostics.h"
#include "fuzz/fuzz_support.h"
#include "server/api/router.h"
#include "server/service/map_registry.h"

namespace {

using namespace wm;

class MapsFixture {
 public:
  MapsFixture() : diagnostics_("fuzz_map_routes: ") {
    dir_ = std::filesystem::temp_directory_path() / ("wm-fuzz-maps-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    service::MapRegistryOptions options;
    options.data_dir = dir_;
    options.store.synchronous_full = false;
    options.rules.rules_dir = WM_RULES_PROLOG_DIR;
    registry_ = std::make_unique<service::MapRegistry>(options, diagnostics_);
    home_ = registry_->create("home");
    registry_->create("a");
    api::ApiOptions api_options;
    api_options.token = "fuzz-token-not-in-any-input";
    services_ = std::make_unique<api::Services>(api::Services{api_options, home_->world});
    services_->maps = registry_.get();
    exports_ = std::make_unique<api::MapExports>(shm::ShmOptions{}, diagnostics_);
    services_->map_exports = exports_.get();
  }
  ~MapsFixture() {
    services_.reset();
    exports_.reset();
    home_.reset();
    registry_.reset();
    std::error_code ignored;
    std::filesystem::remove_all(dir_, ignored);
  }
  api::Services& services() { return *services_; }

 private:
  std::filesystem::path dir_;
  common::Diagnostics diagnostics_;
  std::unique_ptr<service::MapRegistry> registry_;
  std::shared_ptr<service::MapInstance> home_;
  std::unique_ptr<api::MapExports> exports_;
  std::unique_ptr<api::Services> services_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace http = boost::beast::http;
  static MapsFixture fixture;
  if (size == 0) return 0;
  constexpr std::array methods{http::verb::get, http::verb::head, http::verb::post, http::verb::put,
                               http::verb::delete_};
  const auto text = fuzz::as_text(data + 1, size - 1);
  const auto newline = text.find('\n');  // target, then an optional body
  const std::string target(text.substr(0, newline));
  if (target.empty() || target.front() != '/') return 0;
  api::Request request{methods[data[0] % methods.size()], target, 11};
  request.set(http::field::host, "127.0.0.1:8080");
  if (newline != std::string_view::npos) {
    request.set(http::field::content_type, "application/json");
    request.body() = std::string(text.substr(newline + 1));
  }
  request.prepare_payload();
  const auto response = api::handle_request(request, fixture.services());
  const int status = response.result_int();
  if (status >= 500) fuzz::fail("status " + std::to_string(status) + " for " + target + ": " + response.body());
  if (status >= 400 && request.method() != http::verb::head) {
    const auto body = nlohmann::json::parse(response.body(), nullptr, false);
    if (!body.is_object() || !body.contains("error"))
      fuzz::fail("a refusal without a JSON error for " + target + ": " + response.body());
  }
  if (request.method() == http::verb::get) {
    api::Request upgrade{http::verb::get, target, 11};
    upgrade.set(http::field::host, "127.0.0.1:8080");
    upgrade.set(http::field::connection, "Upgrade");
    upgrade.set(http::field::upgrade, "websocket");
    upgrade.set(http::field::sec_websocket_version, "13");
    upgrade.set(http::field::sec_websocket_key, "dGhlIHNhbXBsZSBub25jZQ==");
    upgrade.set(http::field::sec_websocket_protocol, "foxglove.websocket.v1");
    upgrade.set(http::field::authorization, "Bearer fuzz-token-not-in-any-input");
    const auto refusal = api::authorize_events(upgrade, fixture.services());
    const auto map = api::foxglove_map(upgrade);
    if (!refusal && map && api::websocket_subprotocol(upgrade) == "foxglove.websocket.v1" &&
        !fixture.services().maps->find(*map))
      fuzz::fail("a Foxglove upgrade allowed for a map there is not: " + target);
  }
  return 0;
}
