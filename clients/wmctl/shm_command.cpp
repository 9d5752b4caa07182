// wmctl shm: checks the shared-memory export against the server's HTTP answers, the way a local reader sees it.
#include <chrono>
#include <cmath>
#include <cstring>
#include <iostream>
#include <string>
#include <vector>

#include "clients/wmctl/commands.h"
#include "wire/shm/worldmodel_shm.h"

namespace wm::wmctl {
namespace {

namespace shm = worldmodel::shm;

// The tile revision an ETag names ("<run>-r<revision>"), nullopt for another form.
std::optional<std::uint64_t> tile_revision(const std::string& etag) {
  const auto at = etag.rfind("-r");
  if (at == std::string::npos) return std::nullopt;
  try {
    return std::stoull(etag.substr(at + 2));
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// Same float32 bits, NaN included (unknown cells are NaN in both).
bool same_cells(const std::vector<float>& a, const std::string& bytes) {
  return bytes.size() == a.size() * sizeof(float) && std::memcmp(a.data(), bytes.data(), bytes.size()) == 0;
}

}  // namespace

int shm_check(const Invocation& in) {
  const auto info = parse_answer(in.client.request("GET", "/api/v1/shm"));
  const std::string name = info.at("name").get<std::string>();
  const std::size_t max_tiles = std::stoul(in.flag("--tiles").value_or("64"));

  std::optional<shm::Reader> opened;
  try {
    opened.emplace(name);
  } catch (const shm::Error& e) {
    throw ServerError(std::string(e.what()) +
                      " (wmctl shm must run on the server's machine, as a user who may read /dev/shm)");
  }
  auto& reader = *opened;
  std::vector<std::string> problems;
  const auto& header = reader.header();
  const std::string instance(header.server_instance, strnlen(header.server_instance, sizeof header.server_instance));
  if (instance != info.at("server_instance").get<std::string>())
    problems.push_back("the segment belongs to server run " + instance + ", the server is run " +
                       info.at("server_instance").get<std::string>());
  if (reader.state() != shm::SegmentState::live) problems.push_back("the segment is not live (retired or stopped)");
  const auto age_ms =
      (std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
           .count() -
       header.updated_unix_ns.load()) /
      1'000'000;
  const auto period_ms = info.at("period_ms").get<std::int64_t>();
  if (age_ms > std::max<std::int64_t>(1000, 10 * period_ms))
    problems.push_back("the exporter has not finished a pass for " + std::to_string(age_ms) + " ms");

  // Every tile read whole; a sample compared bit for bit with the HTTP tile of the same revision.
  const auto t = static_cast<std::size_t>(reader.tile_size_cells());
  std::vector<float> layers(shm::kLayerCount * t * t);
  std::size_t compared = 0, changed_meanwhile = 0, known = 0;
  const auto count = reader.tile_count();
  for (std::size_t slot = 0; slot < count; ++slot) {
    const auto revision = reader.read_tile_layers(slot, layers.data());
    for (std::size_t i = 0; i < t * t; ++i) known += std::isnan(layers[i]) ? 0 : 1;
    if (slot >= max_tiles) continue;
    const auto key = reader.tile_key(slot);
    for (std::uint32_t l = 0; l < shm::kLayerCount; ++l) {
      const auto layer = static_cast<shm::Layer>(l);
      const auto answer = in.client.request("GET", "/api/v1/grid/tiles/" + std::string(shm::layer_name(layer)) + "/" +
                                                       std::to_string(key.tx) + "/" + std::to_string(key.ty));
      if (answer.status != 200) {
        problems.push_back("tile (" + std::to_string(key.tx) + ", " + std::to_string(key.ty) +
                           ") is in the segment but GET answers " + std::to_string(answer.status));
        break;
      }
      if (tile_revision(answer.etag) != revision) {
        ++changed_meanwhile;  // a scan reached it between the two reads: nothing to compare
        break;
      }
      const std::vector<float> cells(layers.begin() + static_cast<std::ptrdiff_t>(l * t * t),
                                     layers.begin() + static_cast<std::ptrdiff_t>((l + 1) * t * t));
      if (!same_cells(cells, answer.body))
        problems.push_back("tile (" + std::to_string(key.tx) + ", " + std::to_string(key.ty) + ") layer " +
                           shm::layer_name(layer) + " differs from GET at the same revision " +
                           std::to_string(revision));
      if (l + 1 == shm::kLayerCount) ++compared;
    }
  }
  const auto map = reader.read_map();

  json report = {{"name", name},
                 {"bytes", info.at("bytes")},
                 {"state", reader.state() == shm::SegmentState::live ? "live" : "not live"},
                 {"tiles", count},
                 {"tile_capacity", header.tile_capacity},
                 {"known_cells", known},
                 {"grid_revision", reader.grid_revision()},
                 {"tiles_compared", compared},
                 {"tiles_changed_meanwhile", changed_meanwhile},
                 {"map_version", map.version},
                 {"elements", map.elements.size()},
                 {"objects", map.objects.size()},
                 {"edges", map.edges.size()},
                 {"truncated", header.truncated.load()},
                 {"age_ms", age_ms},
                 {"problems", problems}};
  in.emit(report, [&](const json& r) {
    std::cout << "shared memory /dev/shm/" << name << " (" << (info.at("bytes").get<std::uint64_t>() >> 20) << " MB, "
              << r["state"].get<std::string>() << ", updated " << age_ms << " ms ago)\n"
              << "  grid: " << count << " tiles of " << t << "² cells (room for " << header.tile_capacity << "), "
              << known << " known cells, revision " << reader.grid_revision() << "\n"
              << "  map: version " << map.version << ", " << map.elements.size() << " elements, " << map.objects.size()
              << " objects, " << map.edges.size() << " edges\n"
              << "  compared with GET /api/v1/grid/tiles: " << compared << " tiles equal bit for bit";
    if (changed_meanwhile > 0) std::cout << ", " << changed_meanwhile << " changed between the two reads";
    std::cout << "\n";
    if (header.truncated.load() != 0)
      std::cout << "  warning: " << info.value("warning", std::string("the segment is full")) << "\n";
    for (const auto& p : problems) std::cout << "  problem: " << p << "\n";
    if (problems.empty()) std::cout << "ok\n";
  });
  return problems.empty() ? kExitOk : kExitServerError;
}

}  // namespace wm::wmctl
