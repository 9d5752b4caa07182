// Serving the map: one body per version with its ETag, 304 on If-None-Match, gzip, and ?since= deltas
// that bring an old map to the new one exactly, over random sequences of writes.
#include <zlib.h>

#include <algorithm>
#include <map>
#include <random>
#include <stdexcept>
#include <thread>

#include "e2e_fixture.h"

namespace wm::testing {
namespace {

namespace bhttp = boost::beast::http;

std::string gunzip(const std::string& bytes) {
  z_stream stream{};
  if (inflateInit2(&stream, 15 + 16) != Z_OK) throw std::runtime_error("inflateInit2");
  std::string out;
  char buffer[65536];
  stream.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(bytes.data()));
  stream.avail_in = static_cast<uInt>(bytes.size());
  int rc = Z_OK;
  while (rc == Z_OK) {
    stream.next_out = reinterpret_cast<Bytef*>(buffer);
    stream.avail_out = sizeof buffer;
    rc = inflate(&stream, Z_NO_FLUSH);
    out.append(buffer, sizeof buffer - stream.avail_out);
  }
  inflateEnd(&stream);
  if (rc != Z_STREAM_END) throw std::runtime_error("not a whole gzip stream");
  return out;
}

json segment(double x0, double y0, double x1, double y1) { return {{"p0", {x0, y0}}, {"p1", {x1, y1}}}; }

// Applies a ?since= delta to a full map: removals first, then the upserts by id; the top-level fields are replaced.
json apply_delta(json map, const json& delta) {
  for (const auto* kind : {"objects", "elements"}) {
    std::map<std::string, json> by_id;
    for (const auto& item : map[kind]) by_id[item["id"].get<std::string>()] = item;
    for (const auto& id : delta["removed"][kind]) by_id.erase(id.get<std::string>());
    for (const auto& item : delta[kind]) by_id[item["id"].get<std::string>()] = item;
    json list = json::array();
    for (auto& [id, item] : by_id) list.push_back(std::move(item));
    map[kind] = std::move(list);
  }
  for (const auto* key : {"version", "plan", "placement", "georeference", "server_instance"}) map[key] = delta[key];
  return map;
}

// The map with its lists in id order (a delta does not keep the order of the full map).
json by_id(json map) {
  for (const auto* kind : {"objects", "elements"}) {
    auto& list = map[kind];
    std::sort(list.begin(), list.end(),
              [](const json& a, const json& b) { return a["id"].get<std::string>() < b["id"].get<std::string>(); });
  }
  return map;
}

class MapServingTest : public ServerFixture {
 protected:
  bhttp::response<bhttp::string_body> get(const std::string& target, const Headers& headers = {}) {
    return raw_request(server_->port(), bhttp::verb::get, target, headers);
  }
  static std::string etag(const bhttp::response<bhttp::string_body>& res) {
    return std::string(res[bhttp::field::etag]);
  }
};

TEST_F(MapServingTest, OneBodyPerVersionWithItsTagAnd304WhenTheClientHasIt) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const auto first = get("/api/v1/map");
  ASSERT_EQ(first.result_int(), 200);
  const auto tag = etag(first);
  const auto version = json::parse(first.body())["version"].get<std::int64_t>();
  EXPECT_NE(tag.find("-v" + std::to_string(version) + "\""), std::string::npos) << tag;
  EXPECT_EQ(first[bhttp::field::cache_control], "no-cache");
  EXPECT_EQ(first[bhttp::field::vary], "Accept-Encoding");

  const auto again = get("/api/v1/map");
  EXPECT_EQ(etag(again), tag);
  EXPECT_EQ(again.body(), first.body());

  const auto not_modified = get("/api/v1/map", {{"If-None-Match", tag}});
  EXPECT_EQ(not_modified.result_int(), 304);
  EXPECT_TRUE(not_modified.body().empty());
  EXPECT_EQ(etag(not_modified), tag);
  // In a list, weak, or "*": still the same version.
  EXPECT_EQ(get("/api/v1/map", {{"If-None-Match", "\"other\", W/" + tag}}).result_int(), 304);
  EXPECT_EQ(get("/api/v1/map", {{"If-None-Match", "*"}}).result_int(), 304);
  EXPECT_EQ(get("/api/v1/map", {{"If-None-Match", "\"other\""}}).result_int(), 200);

  // A write makes a new version: the old tag no longer matches.
  send_json("POST", "/api/v1/primitives", {{"source", "robot-1"}, {"segments", {segment(10, 3, 13, 3.02)}}});
  const auto changed = get("/api/v1/map", {{"If-None-Match", tag}});
  ASSERT_EQ(changed.result_int(), 200);
  EXPECT_NE(etag(changed), tag);
  EXPECT_EQ(json::parse(changed.body())["version"], version + 1);
  EXPECT_EQ(json::parse(changed.body())["elements"].size(), 1u);

  // DXF and GeoJSON are made once per version as well.
  const auto dxf = get("/api/v1/map?format=dxf");
  ASSERT_EQ(dxf.result_int(), 200);
  EXPECT_EQ(get("/api/v1/map?format=dxf", {{"If-None-Match", etag(dxf)}}).result_int(), 304);
  EXPECT_EQ(get("/api/v1/map?format=dxf").body(), dxf.body());
  EXPECT_NE(dxf.body().find("ENTITIES"), std::string::npos);

  // After a restart the same version has another tag: a version number may name another map by then.
  const auto before_restart = etag(get("/api/v1/map"));
  restart();
  const auto after = get("/api/v1/map", {{"If-None-Match", before_restart}});
  EXPECT_EQ(after.result_int(), 200);
  EXPECT_EQ(json::parse(after.body())["version"], version + 1);
  EXPECT_NE(etag(after), before_restart);
}

TEST_F(MapServingTest, AClientThatAcceptsAStaleMapIsAnsweredAtOnceAndTheNewOneIsMadeMeanwhile) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const auto first = get("/api/v1/map");
  const auto v1 = json::parse(first.body())["version"].get<std::int64_t>();
  send_json("POST", "/api/v1/primitives", {{"source", "robot-1"}, {"segments", {segment(10, 3, 13, 3.02)}}});
  // Allowed up to a minute: the body made before the write, and how old it is.
  const auto stale = get("/api/v1/map", {{"Cache-Control", "max-stale=60"}});
  ASSERT_EQ(stale.result_int(), 200);
  EXPECT_EQ(json::parse(stale.body())["version"], v1);
  EXPECT_EQ(etag(stale), etag(first));
  EXPECT_FALSE(stale[bhttp::field::age].empty());
  // Without the directive (or with a malformed one) the answer is the newest map.
  EXPECT_EQ(json::parse(get("/api/v1/map", {{"Cache-Control", "max-stale=soon"}}).body())["version"], v1 + 1);
  // The newer body was made in the background: a stale-accepting client gets it next without waiting.
  send_json("POST", "/api/v1/primitives", {{"source", "robot-1"}, {"segments", {segment(10, 6, 13, 6.02)}}});
  std::int64_t seen = 0;
  for (int attempt = 0; attempt < 200 && seen != v1 + 2; ++attempt) {
    seen = json::parse(get("/api/v1/map", {{"Cache-Control", "no-transform, max-stale=60"}}).body())["version"];
    if (seen != v1 + 2) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  EXPECT_EQ(seen, v1 + 2) << "the background build never came";
}

TEST_F(MapServingTest, GzipBodiesDecodeToTheSameJson) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  for (int i = 0; i < 20; ++i)
    send_json("POST", "/api/v1/primitives",
              {{"source", "robot-1"}, {"segments", {segment(1 + i, 1 + 0.3 * i, 1.5 + i, 2 + 0.3 * i)}}});
  const auto plain = get("/api/v1/map");
  const auto zipped = get("/api/v1/map", {{"Accept-Encoding", "br;q=1.0, gzip;q=0.8"}});
  ASSERT_EQ(zipped.result_int(), 200);
  EXPECT_EQ(zipped[bhttp::field::content_encoding], "gzip");
  EXPECT_LT(zipped.body().size(), plain.body().size() / 2);
  EXPECT_EQ(gunzip(zipped.body()), plain.body());
  EXPECT_EQ(etag(zipped), etag(plain).substr(0, etag(plain).size() - 1) + "-gzip\"");
  EXPECT_EQ(get("/api/v1/map", {{"Accept-Encoding", "gzip"}, {"If-None-Match", etag(zipped)}}).result_int(), 304);
  // Refused or not asked for: identity.
  EXPECT_TRUE(get("/api/v1/map", {{"Accept-Encoding", "gzip;q=0"}})[bhttp::field::content_encoding].empty());
  EXPECT_TRUE(get("/api/v1/map", {{"Accept-Encoding", "gzip;level=1;q=0.0"}})[bhttp::field::content_encoding].empty());
  EXPECT_TRUE(get("/api/v1/map", {{"Accept-Encoding", "identity"}})[bhttp::field::content_encoding].empty());
  EXPECT_EQ(get("/api/v1/map", {{"Accept-Encoding", "*"}})[bhttp::field::content_encoding], "gzip");
}

TEST_F(MapServingTest, BadSinceIsRefusedWithTheReason) {
  send_json("PUT", "/api/v1/floorplan", lab_plan());
  const auto version = get_json("/api/v1/map")["version"].get<std::int64_t>();
  const auto refused = [&](const std::string& query, int status, const std::string& part) {
    const auto res = call("GET", "/api/v1/map?" + query);
    EXPECT_EQ(res.status, status) << query << ": " << res.body;
    EXPECT_NE(res.body.find(part), std::string::npos) << query << ": " << res.body;
  };
  refused("since=abc", 400, "since");
  refused("since=-1", 400, "since");
  refused("since=" + std::to_string(version + 1), 400, "after the map's version");
  refused("since=0&format=dxf", 400, "JSON only");
  refused("since=0&bbox=0,0,1,1", 400, "whole map");
  EXPECT_EQ(get_json("/api/v1/map?since=" + std::to_string(version))["elements"].size(), 0u);
  // A poller that holds the newest version gets 304 until something changes.
  const auto since_now = "/api/v1/map?since=" + std::to_string(version);
  const auto poll = get(since_now);
  ASSERT_FALSE(etag(poll).empty());
  EXPECT_EQ(get(since_now, {{"If-None-Match", etag(poll)}}).result_int(), 304);
  send_json("POST", "/api/v1/primitives", {{"source", "robot-1"}, {"segments", {segment(10, 3, 13, 3.02)}}});
  const auto changed = get(since_now, {{"If-None-Match", etag(poll)}});
  ASSERT_EQ(changed.result_int(), 200);
  EXPECT_EQ(json::parse(changed.body())["elements"].size(), 1u);
  // From before this start the server cannot tell what was removed.
  restart();
  refused("since=0", 410, "no longer knows");
  EXPECT_EQ(call("GET", "/api/v1/map?since=" + std::to_string(version + 1)).status, 200);
}

// The property: for random sequences of writes (adds, merges, joins, plan changes that drop objects, redecides that
// delete elements), the delta since any earlier version applied to the map of that version is the map now.
TEST_F(MapServingTest, DeltasBringEveryEarlierMapToTheCurrentOne) {
  json plan_without_table = lab_plan();
  plan_without_table["objects"].erase(1);
  std::size_t removed_elements = 0, removed_objects = 0, checks = 0;
  for (unsigned seed = 1; seed <= 3; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> along(0.0, 16.0), length(0.5, 4.0), noise(-0.01, 0.01);
    std::uniform_int_distribution<int> op(0, 9), line(0, 3), count(1, 3);
    const double lines[] = {3.0, 6.0, 10.0, 8.0};  // y of the walls seen; 10 is the plan's solid wall
    std::vector<json> earlier{get_json("/api/v1/map")};
    for (int step = 0; step < 30; ++step) {
      const int what = op(rng);
      if (what <= 5) {
        json segments = json::array();
        for (int k = count(rng); k > 0; --k) {
          const double y = lines[line(rng)], x = along(rng);
          segments.push_back(segment(x, y + noise(rng), x + length(rng), y + noise(rng)));
        }
        send_json("POST", "/api/v1/primitives", {{"source", "robot-" + std::to_string(seed)}, {"segments", segments}});
      } else if (what == 6) {
        send_json("PUT", "/api/v1/floorplan", step % 2 ? lab_plan() : plan_without_table);
      } else if (what == 7) {
        send_json("POST", "/api/v1/floorplan/redecide", {{"source", "test"}});
      } else {
        earlier.push_back(get_json("/api/v1/map"));
      }
    }
    const json now = get_json("/api/v1/map");
    for (const auto& old : earlier) {
      const auto delta = get_json("/api/v1/map?since=" + std::to_string(old["version"].get<std::int64_t>()));
      EXPECT_EQ(delta["version"], now["version"]);
      removed_elements += delta["removed"]["elements"].size();
      removed_objects += delta["removed"]["objects"].size();
      EXPECT_EQ(by_id(apply_delta(old, delta)), by_id(now)) << "seed " << seed << ", since " << old["version"];
      ++checks;
    }
  }
  EXPECT_GE(checks, 6u);
  // The sequences did remove things, so the removals were tested.
  EXPECT_GT(removed_elements, 0u);
  EXPECT_GT(removed_objects, 0u);
}

}  // namespace
}  // namespace wm::testing
