// The incremental map JSON writer against the codec's whole-map JSON: the same bytes after every change.
#include "server/api/map_json_writer.h"

#include <gtest/gtest.h>

#include <random>

#include "server/json/codec.h"
#include "tests/server/api/fake_world_port.h"
#include "tests/support/lab_plan.h"

namespace wm::testing {
namespace {

std::string whole_map(const world::WorldState& state, const world::WorldOptions& options) {
  auto map = json_codec::map_json(state, options, std::nullopt);
  map["server_instance"] = "run-1";
  return map.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

TEST(MapJsonWriterTest, WritesTheCodecsBytesThroughRandomAddsChangesAndRemovals) {
  FakeWorldPort port;
  port.load_plan(lab_plan());
  auto& state = port.state();
  const auto& options = port.world_options();
  api::MapJsonWriter writer;
  std::mt19937 random(15);
  std::uniform_real_distribution<double> coordinate(-10, 10);
  std::size_t reused_checks = 0;
  const auto pick = [&] {  // the number of a random element
    auto k = random() % state.elements.size();
    for (const auto& [number, element] : state.elements)
      if (k-- == 0) return number;
    return std::int64_t{0};
  };
  for (int step = 0; step < 300; ++step) {
    ++state.version;
    const auto choice = random() % 10;
    if (choice < 5 || state.elements.empty()) {  // add
      world::Element e;
      e.number = state.next_element_number++;
      const double x = coordinate(random), y = coordinate(random);
      e.segment = fusion::LineSegment::from_points({x, y}, {x + 1.5, y + 0.2}, Eigen::Matrix2d::Identity() * 1e-4);
      e.origin = "scan";
      e.observer = "robot-\"7\"\n";  // text that needs escaping
      e.created_version = e.updated_version = state.version;
      state.elements.put(e);
    } else if (choice < 8) {  // change one, as the world update does: a new updated_version
      auto e = state.elements.at(pick());
      ++e.support;
      e.updated_version = state.version;
      state.elements.put(e);
    } else if (choice < 9) {  // remove one
      state.elements.erase(pick());
    } else {  // an object confirmed
      auto object = state.objects[1];
      ++object.confirmations;
      object.updated_version = state.version;
      state.objects.put(1, object);
    }
    ASSERT_EQ(writer.write(state, options, "run-1"), whole_map(state, options)) << "step " << step;
    ++reused_checks;
  }
  EXPECT_GT(state.elements.size(), 50u);
  EXPECT_EQ(reused_checks, 300u);
  // A new plan (new objects, versions that may repeat old numbers) is written from scratch.
  port.load_plan(lab_plan());
  EXPECT_EQ(writer.write(port.state(), options, "run-1"), whole_map(port.state(), options));
}

}  // namespace
}  // namespace wm::testing
