// POST /api/v1/scans over loopback HTTP to a real wmd: CBOR bodies (RFC 8949, float32 typed arrays of RFC 8746) and
// batches {"scans": [...]} — applied like JSON, refused with the same answers, a batch committed whole in one
// transaction and durable across a restart, a bad scan refusing the batch without changing anything.
#include <sqlite3.h>

#include <bit>
#include <cstdint>
#include <string>
#include <vector>

#include "e2e_fixture.h"
#include "grid_room.h"

namespace wm::testing {
namespace {

namespace http = boost::beast::http;
using grid_room::room_scan;

struct Answer {
  int status = 0;
  json body;
  bool replayed = false;
};

std::string cbor_of(const json& doc) {
  const auto bytes = json::to_cbor(doc);
  return std::string(bytes.begin(), bytes.end());
}

// The scan with its ranges as a float32 typed array (tag 85 over little-endian bytes).
json with_float32_ranges(json scan) {
  std::vector<std::uint8_t> bytes;
  for (const auto& r : scan["ranges"]) {
    const auto bits = std::bit_cast<std::uint32_t>(r.get<float>());
    for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<std::uint8_t>(bits >> (8 * k)));
  }
  scan["ranges"] = json::binary_t(bytes, 85);
  return scan;
}

std::int64_t count_rows(const std::filesystem::path& db, const std::string& sql) {
  sqlite3* handle = nullptr;
  if (sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr) != SQLITE_OK) {
    sqlite3_close(handle);
    throw std::runtime_error("cannot open " + db.string());
  }
  sqlite3_stmt* statement = nullptr;
  std::int64_t n = -1;
  if (sqlite3_prepare_v2(handle, sql.c_str(), -1, &statement, nullptr) == SQLITE_OK &&
      sqlite3_step(statement) == SQLITE_ROW)
    n = sqlite3_column_int64(statement, 0);
  sqlite3_finalize(statement);
  sqlite3_close(handle);
  return n;
}

class ScanBodyE2eTest : public ServerFixture {
 protected:
  Answer post(const std::string& body, const std::string& type, const std::string& key = {}) {
    namespace net = boost::asio;
    net::io_context ioc;
    boost::beast::tcp_stream stream(ioc);
    stream.expires_after(std::chrono::seconds(60));
    stream.connect(
        net::ip::tcp::endpoint(net::ip::make_address("127.0.0.1"), static_cast<unsigned short>(server_->port())));
    http::request<http::string_body> req{http::verb::post, "/api/v1/scans", 11};
    req.set(http::field::host, "127.0.0.1");
    req.set(http::field::content_type, type);
    if (!key.empty()) req.set("Idempotency-Key", key);
    req.body() = body;
    req.prepare_payload();
    http::write(stream, req);
    boost::beast::flat_buffer buffer;
    http::response<http::string_body> res;
    http::read(stream, buffer, res);
    EXPECT_EQ(res[http::field::content_type].substr(0, 16), "application/json") << res.body();
    return {static_cast<int>(res.result_int()), json::parse(res.body()), res["Idempotent-Replayed"] == "true"};
  }
  std::int64_t scans_journaled() const { return count_rows(dir_.path() / "wm.db", "SELECT COUNT(*) FROM scans"); }
};

TEST_F(ScanBodyE2eTest, ACborScanIsAppliedAsItsJsonIs) {
  const auto first = post(room_scan(3, 3, 0.2).dump(), "application/json");
  ASSERT_EQ(first.status, 200) << first.body;
  const auto plain = post(cbor_of(room_scan(3.1, 3, 0.2)), "application/cbor");
  ASSERT_EQ(plain.status, 200) << plain.body;
  const auto typed = post(cbor_of(with_float32_ranges(room_scan(3.2, 3, 0.2))), "application/cbor; charset=binary");
  ASSERT_EQ(typed.status, 200) << typed.body;
  EXPECT_EQ(first.body["seq"], 1);
  EXPECT_EQ(plain.body["seq"], 2);
  EXPECT_EQ(typed.body["seq"], 3);
  EXPECT_EQ(typed.body["grid_revision"], 3);
  // The same room from 10 cm further: its walls' lines are decided, as for the JSON scan.
  ASSERT_TRUE(typed.body["lines"].is_object()) << typed.body;
  EXPECT_FALSE(typed.body["lines"]["decisions"].empty());
  EXPECT_EQ(first.body["lines"]["decisions"].size(), typed.body["lines"]["decisions"].size());
  EXPECT_EQ(scans_journaled(), 3);
}

TEST_F(ScanBodyE2eTest, CborIsRefusedWithTheAnswersOfJson) {
  auto bad = room_scan(3, 3, 0);
  bad["ranges"][7] = "far";
  const auto as_json = post(bad.dump(), "application/json");
  const auto as_cbor = post(cbor_of(bad), "application/cbor");
  EXPECT_EQ(as_json.status, 400);
  EXPECT_EQ(as_cbor.status, 400);
  EXPECT_EQ(as_cbor.body, as_json.body);
  EXPECT_EQ(as_cbor.body["detail"], "ranges[7]: expected a number");

  const auto nan = post(cbor_of(with_float32_ranges([] {
                          auto scan = room_scan(3, 3, 0);
                          scan["ranges"][2] = std::numeric_limits<double>::infinity();
                          return scan;
                        }())),
                        "application/cbor");
  EXPECT_EQ(nan.status, 400);
  EXPECT_EQ(nan.body["detail"], "ranges[2]: not a finite number");

  const auto cut = post(cbor_of(room_scan(3, 3, 0)).substr(0, 100), "application/cbor");
  EXPECT_EQ(cut.status, 400);
  EXPECT_EQ(cut.body["detail"].get<std::string>().substr(0, 15), "malformed CBOR:");

  for (const char* type : {"text/plain", "application/octet-stream", "application/cbor-seq"}) {
    const auto refused = post(cbor_of(room_scan(3, 3, 0)), type);
    EXPECT_EQ(refused.status, 415) << type;
    EXPECT_EQ(refused.body["error"], "unsupported_media_type") << type;
  }
  EXPECT_EQ(scans_journaled(), 0);
}

TEST_F(ScanBodyE2eTest, ACborScanRetriedWithItsRequestIdIsAnsweredNotApplied) {
  const auto body = cbor_of(with_float32_ranges(room_scan(3, 3, 0)));
  const auto first = post(body, "application/cbor", "robot-1-scan-1");
  const auto retried = post(body, "application/cbor", "robot-1-scan-1");
  ASSERT_EQ(first.status, 200) << first.body;
  ASSERT_EQ(retried.status, 200) << retried.body;
  EXPECT_FALSE(first.replayed);
  EXPECT_TRUE(retried.replayed);
  EXPECT_EQ(retried.body["seq"], first.body["seq"]);
  EXPECT_EQ(post(cbor_of(room_scan(3, 3, 0)), "application/cbor", "robot-1-scan-1").status, 409);  // other bytes
  EXPECT_EQ(scans_journaled(), 1);
}

TEST_F(ScanBodyE2eTest, ABatchIsCommittedTogetherAnsweredInOrderAndKeptAcrossARestart) {
  const json batch = {{"scans", {room_scan(3, 3, 0), room_scan(3.1, 3, 0), room_scan(3.2, 3, 0)}}};
  const auto answer = post(batch.dump(), "application/json");
  ASSERT_EQ(answer.status, 200) << answer.body;
  ASSERT_EQ(answer.body["scans"].size(), 3u);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(answer.body["scans"][i]["seq"], i + 1);
    EXPECT_EQ(answer.body["scans"][i]["grid_revision"], i + 1);
  }
  // Each scan was decided against the map the one before it left.
  EXPECT_LE(answer.body["scans"][0]["lines"]["version"].get<int>(),
            answer.body["scans"][1]["lines"]["version"].get<int>());

  const json cbor_batch = {
      {"scans", {with_float32_ranges(room_scan(3.3, 3, 0)), with_float32_ranges(room_scan(3.4, 3, 0))}}};
  const auto body = cbor_of(cbor_batch);
  const auto second = post(body, "application/cbor", "robot-1-batch-2");
  ASSERT_EQ(second.status, 200) << second.body;
  EXPECT_EQ(second.body["scans"][0]["seq"], 4);
  EXPECT_EQ(second.body["scans"][1]["seq"], 5);

  restart();
  EXPECT_EQ(scans_journaled(), 5);
  EXPECT_EQ(
      count_rows(dir_.path() / "wm.db",
                 "SELECT COUNT(*) FROM requests WHERE request_id IN ('robot-1-batch-2[0]', 'robot-1-batch-2[1]')"),
      2);
  const auto retried = post(body, "application/cbor", "robot-1-batch-2");
  ASSERT_EQ(retried.status, 200) << retried.body;
  EXPECT_TRUE(retried.replayed);
  EXPECT_EQ(retried.body["scans"][0]["seq"], 4);
  EXPECT_EQ(retried.body["scans"][1]["seq"], 5);
  EXPECT_EQ(scans_journaled(), 5);
  EXPECT_EQ(get_json("/api/v1/grid")["revision"], 5);
}

TEST_F(ScanBodyE2eTest, ABadScanRefusesTheWholeBatchAndChangesNothing) {
  ASSERT_EQ(post(room_scan(3, 3, 0).dump(), "application/json").status, 200);
  const auto map_before = get_json("/api/v1/map");
  json batch = {{"scans", {room_scan(3.1, 3, 0), room_scan(3.2, 3, 0), room_scan(3.3, 3, 0)}}};
  batch["scans"][1]["pose"].erase("theta");
  for (const auto& [body, type] :
       {std::pair{batch.dump(), "application/json"}, std::pair{cbor_of(batch), "application/cbor"}}) {
    const auto refused = post(body, type);
    EXPECT_EQ(refused.status, 400) << type;
    EXPECT_EQ(refused.body["detail"], "scans[1].pose.theta: missing field") << type;
  }
  json too_many = {{"scans", json::array()}};
  for (int i = 0; i < 65; ++i) too_many["scans"].push_back(room_scan(3, 3, 0));
  const auto refused = post(cbor_of(too_many), "application/cbor");
  EXPECT_EQ(refused.status, 400);
  EXPECT_EQ(refused.body["detail"], "scans: more than 64 scans in one batch");

  EXPECT_EQ(scans_journaled(), 1);
  EXPECT_EQ(get_json("/api/v1/map")["version"], map_before["version"]);
  const auto next = post(room_scan(3.1, 3, 0).dump(), "application/json");
  EXPECT_EQ(next.body["seq"], 2);  // no sequence number was taken by the refused batches
}

}  // namespace
}  // namespace wm::testing
