#include "server/api/router.h"

#include <algorithm>

#include <charconv>
#include <map>

#include <nlohmann/json.hpp>

#include "rules/engine.h"
#include "server/api/api_error.h"
#include "server/storage/sqlite.h"

namespace wm::api {
namespace {

namespace http = boost::beast::http;
using nlohmann::json;

struct Target {
  std::string path;
  std::map<std::string, std::string> query;
};

std::string percent_decode(std::string_view in) {
  std::string out;
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (in[i] == '%' && i + 2 < in.size()) {
      int value = 0;
      auto [p, ec] = std::from_chars(in.data() + i + 1, in.data() + i + 3, value, 16);
      if (ec != std::errc() || p != in.data() + i + 3) throw bad_request("", "bad percent-encoding in the URL");
      out.push_back(static_cast<char>(value));
      i += 2;
    } else if (in[i] == '+') {
      out.push_back(' ');
    } else {
      out.push_back(in[i]);
    }
  }
  return out;
}

Target parse_target(std::string_view target) {
  Target t;
  const auto q = target.find('?');
  t.path = percent_decode(target.substr(0, q));
  if (q == std::string_view::npos) return t;
  std::string_view rest = target.substr(q + 1);
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const auto pair = rest.substr(0, amp);
    const auto eq = pair.find('=');
    if (!pair.empty())
      t.query[percent_decode(pair.substr(0, eq))] = eq == std::string_view::npos ? "" : percent_decode(pair.substr(eq + 1));
    rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
  }
  return t;
}

std::int64_t query_int(const Target& t, const std::string& key, std::int64_t fallback, std::int64_t min, std::int64_t max) {
  auto it = t.query.find(key);
  if (it == t.query.end()) return fallback;
  std::int64_t v = 0;
  const auto& s = it->second;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || p != s.data() + s.size() || v < min || v > max)
    throw bad_request(key, "expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "], got '" + s + "'");
  return v;
}

Response json_response(const Request& req, const json& body, http::status status = http::status::ok) {
  Response res{status, req.version()};
  res.set(http::field::content_type, "application/json");
  res.set(http::field::cache_control, "no-store");
  res.keep_alive(req.keep_alive());
  res.body() = body.dump();
  res.prepare_payload();
  return res;
}

bool has_content_type(const Request& req, std::string_view wanted) {
  const auto value = req[http::field::content_type];
  const auto semicolon = value.find(';');
  auto type = value.substr(0, semicolon);
  while (!type.empty() && type.back() == ' ') type.remove_suffix(1);
  return boost::beast::iequals(type, boost::beast::string_view(wanted.data(), wanted.size()));
}

void require_json_body(const Request& req) {
  if (req.body().empty()) throw bad_request("", "empty body");
  if (!has_content_type(req, "application/json"))
    throw ApiError(415, "unsupported_media_type",
                   "send the body as Content-Type: application/json (got '" + std::string(req[http::field::content_type]) + "')");
}

void require_token(const Request& req, const Services& s) {
  if (s.options.token.empty()) return;
  if (req[http::field::authorization] != "Bearer " + s.options.token)
    throw ApiError(401, "unauthorized", "this server needs 'Authorization: Bearer <token>' to change state");
}

[[noreturn]] void method_not_allowed(const std::string& allowed) {
  throw ApiError(405, "method_not_allowed", "allowed: " + allowed);
}

Response get_health(const Request& req, Services& s) {
  const auto snap = s.world.snapshot();
  return json_response(req, {{"status", "ok"},
                             {"version", snap->version},
                             {"plan", snap->plan_name},
                             {"objects", snap->objects.size()},
                             {"elements", snap->elements.size()},
                             {"last_decision_seq", snap->last_decision_seq},
                             {"rules", json_codec::rules_status_json(s.world.rules_status())}});
}

Response get_rules(const Request& req, Services& s) {
  return json_response(req, json_codec::rules_status_json(s.world.rules_status()));
}

json parse_json_object(const Request& req) {
  require_json_body(req);
  json doc = json::parse(req.body(), nullptr, false);
  if (doc.is_discarded()) throw bad_request("", "malformed JSON");
  if (!doc.is_object()) throw bad_request("", "expected a JSON object");
  return doc;
}

std::string string_field(const json& doc, const std::string& key, std::size_t max_size) {
  const auto it = doc.find(key);
  if (it == doc.end()) throw bad_request(key, "missing field");
  if (!it->is_string()) throw bad_request(key, "expected a string");
  const auto text = it->get<std::string>();
  if (text.empty() || text.size() > max_size)
    throw bad_request(key, "expected 1 to " + std::to_string(max_size) + " characters");
  return text;
}

std::size_t count_field(const json& doc, const std::string& key, std::size_t fallback, std::size_t max) {
  const auto it = doc.find(key);
  if (it == doc.end()) return fallback;
  if (!it->is_number_integer() || it->get<std::int64_t>() < 1 || it->get<std::int64_t>() > static_cast<std::int64_t>(max))
    throw bad_request(key, "expected an integer in [1, " + std::to_string(max) + "]");
  return static_cast<std::size_t>(it->get<std::int64_t>());
}

void require_known_keys(const json& doc, std::initializer_list<std::string_view> known) {
  for (const auto& [key, value] : doc.items())
    if (std::find(known.begin(), known.end(), key) == known.end()) throw bad_request(key, "unknown field");
}

Response post_rules_reload(const Request& req, Services& s) {
  require_token(req, s);
  const auto status = s.world.reload_rules();
  return json_response(req, json_codec::rules_status_json(status));
}

Response post_rules_dry_run(const Request& req, Services& s) {
  require_token(req, s);
  const json doc = parse_json_object(req);
  require_known_keys(doc, {"file", "text", "last"});
  rules::RuleText candidate{string_field(doc, "file", 255), string_field(doc, "text", 4u << 20)};
  const std::size_t last = count_field(doc, "last", 1000, 100000);
  const auto outcome = s.world.dry_run(candidate, last);
  json changes = json::array();
  for (const auto& c : outcome.changes)
    changes.push_back({{"recorded", json_codec::decision_json(c.recorded)}, {"candidate", json_codec::decision_json(c.candidate)}});
  return json_response(req, {{"file", candidate.name}, {"redecided", outcome.redecided}, {"changed", outcome.changes.size()},
                             {"changes", changes}});
}

Response post_query(const Request& req, Services& s) {
  const json doc = parse_json_object(req);
  require_known_keys(doc, {"goal", "max_solutions"});
  const auto goal = string_field(doc, "goal", 64 * 1024);
  const auto max_solutions = count_field(doc, "max_solutions", 100, 10000);
  try {
    return json_response(req, json_codec::query_result_json(s.world.query(goal, max_solutions)));
  } catch (const rules::QueryError& e) {
    switch (e.reason()) {
      case rules::QueryError::Reason::syntax: throw ApiError(400, "bad_query", e.what());
      case rules::QueryError::Reason::unsafe: throw ApiError(403, "forbidden_goal", e.what());
      case rules::QueryError::Reason::limit: throw ApiError(422, "query_limit", e.what());
      case rules::QueryError::Reason::failed: break;
    }
    throw ApiError(422, "query_error", e.what());
  }
}

Response get_history(const Request& req, Services& s, const std::string& id, bool exists) {
  const auto rows = s.world.store().decisions(0, 10000, id);
  if (rows.empty() && !exists) throw ApiError(404, "not_found", "no element or object '" + id + "' and no decision about it");
  json list = json::array();
  for (const auto& d : rows) list.push_back(json_codec::decision_json(d));
  return json_response(req, {{"id", id}, {"exists", exists}, {"decisions", std::move(list)}});
}

Response put_floor_plan(const Request& req, Services& s) {
  require_token(req, s);
  if (has_content_type(req, "image/vnd.dxf"))
    throw ApiError(415, "unsupported_media_type", "DXF floor plans are not supported yet; send the JSON floor plan");
  require_json_body(req);
  auto plan = apriori::parse_floor_plan_json(req.body(), s.options.plan_limits);
  std::size_t edges = 0;
  for (const auto& o : plan.objects) edges += o.edges().size();
  const auto objects = plan.objects.size();
  const auto name = plan.name;
  const auto version = s.world.load_floor_plan(std::move(plan));
  return json_response(req, {{"name", name}, {"objects", objects}, {"edges", edges}, {"version", version}});
}

Response get_floor_plan(const Request& req, Services& s) {
  const auto snap = s.world.snapshot();
  apriori::FloorPlan plan{snap->plan_name, {}};
  for (const auto& o : snap->objects) plan.objects.push_back(*o.plan);
  return json_response(req, json::parse(apriori::to_json_text(plan)));
}

Response post_primitives(const Request& req, Services& s) {
  require_token(req, s);
  require_json_body(req);
  auto observation = json_codec::parse_primitives(req.body(), s.world.options().world, s.options.primitive_limits);
  const auto outcome = s.world.post_primitives(std::move(observation), req.body());
  json decisions = json::array();
  for (const auto& d : outcome.decisions) decisions.push_back(json_codec::decision_json(d));
  return json_response(req, {{"seq", outcome.seq}, {"version", outcome.version}, {"decisions", std::move(decisions)}});
}

Response get_decisions(const Request& req, const Target& t, Services& s) {
  const auto since = query_int(t, "since", 0, 0, std::numeric_limits<std::int64_t>::max());
  const auto limit = query_int(t, "limit", 1000, 1, static_cast<std::int64_t>(s.options.max_decisions_per_page));
  std::optional<std::string> element;
  if (auto it = t.query.find("element"); it != t.query.end()) element = it->second;
  const auto rows = s.world.store().decisions(since, static_cast<std::size_t>(limit), element);
  json list = json::array();
  for (const auto& d : rows) list.push_back(json_codec::decision_json(d));
  const auto next = rows.empty() ? since : rows.back().seq;
  return json_response(req, {{"decisions", std::move(list)}, {"next", next}});
}

Response route(const Request& req, Services& s) {
  const auto raw_target = req.target();
  const Target t = parse_target(std::string_view(raw_target.data(), raw_target.size()));
  const auto method = req.method();
  const auto& path = t.path;
  const std::string objects_prefix = "/api/v1/objects/";
  const std::string elements_prefix = "/api/v1/elements/";

  if (path == "/api/v1/health") {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_health(req, s);
  }
  if (path == "/api/v1/map") {
    if (method != http::verb::get) method_not_allowed("GET");
    if (auto it = t.query.find("format"); it != t.query.end() && it->second != "json")
      throw bad_request("format", "only format=json is supported");
    const auto snap = s.world.snapshot();
    return json_response(req, json_codec::map_json(*snap, s.world.options().world));
  }
  if (path == "/api/v1/floorplan") {
    if (method == http::verb::put) return put_floor_plan(req, s);
    if (method == http::verb::get) return get_floor_plan(req, s);
    method_not_allowed("GET, PUT");
  }
  if (path == "/api/v1/primitives") {
    if (method != http::verb::post) method_not_allowed("POST");
    return post_primitives(req, s);
  }
  if (path == "/api/v1/decisions") {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_decisions(req, t, s);
  }
  if (path == "/api/v1/rules") {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_rules(req, s);
  }
  if (path == "/api/v1/rules/reload") {
    if (method != http::verb::post) method_not_allowed("POST");
    return post_rules_reload(req, s);
  }
  if (path == "/api/v1/rules/dry-run") {
    if (method != http::verb::post) method_not_allowed("POST");
    return post_rules_dry_run(req, s);
  }
  if (path == "/api/v1/query") {
    if (method != http::verb::post) method_not_allowed("POST");
    return post_query(req, s);
  }
  if (path == "/api/v1/objects" || path == "/api/v1/elements") {
    if (method != http::verb::get) method_not_allowed("GET");
    const auto snap = s.world.snapshot();
    json list = json::array();
    if (path == "/api/v1/objects")
      for (const auto& o : snap->objects) list.push_back(json_codec::object_json(o, s.world.options().world));
    else
      for (const auto& [n, e] : snap->elements) list.push_back(json_codec::element_json(e));
    return json_response(req, {{"version", snap->version}, {path == "/api/v1/objects" ? "objects" : "elements", list}});
  }
  const std::string history_suffix = "/history";
  if ((path.rfind(objects_prefix, 0) == 0 || path.rfind(elements_prefix, 0) == 0) && path.size() > history_suffix.size() &&
      path.compare(path.size() - history_suffix.size(), history_suffix.size(), history_suffix) == 0) {
    if (method != http::verb::get) method_not_allowed("GET");
    const bool is_object = path.rfind(objects_prefix, 0) == 0;
    const auto prefix_size = is_object ? objects_prefix.size() : elements_prefix.size();
    const auto id = path.substr(prefix_size, path.size() - prefix_size - history_suffix.size());
    const auto snap = s.world.snapshot();
    const bool exists = is_object ? snap->find_object(id) != nullptr : snap->find_element(id) != nullptr;
    return get_history(req, s, id, exists);
  }
  if (path.rfind(objects_prefix, 0) == 0) {
    if (method != http::verb::get) method_not_allowed("GET");
    const auto id = path.substr(objects_prefix.size());
    const auto snap = s.world.snapshot();
    const auto* object = snap->find_object(id);
    if (!object) throw ApiError(404, "not_found", "no object '" + id + "' in the floor plan");
    return json_response(req, json_codec::object_json(*object, s.world.options().world));
  }
  if (path.rfind(elements_prefix, 0) == 0) {
    if (method != http::verb::get) method_not_allowed("GET");
    const auto id = path.substr(elements_prefix.size());
    const auto snap = s.world.snapshot();
    const auto* element = snap->find_element(id);
    if (!element) throw ApiError(404, "not_found", "no element '" + id + "' in the map");
    return json_response(req, json_codec::element_json(*element));
  }
  if (path == "/" && method == http::verb::get) {
    return json_response(req, {{"service", "worldmodel"},
                               {"api", "/api/v1"},
                               {"endpoints", {"GET /api/v1/health", "GET /api/v1/map", "GET /api/v1/objects[/{id}]",
                                              "GET /api/v1/elements[/{id}]", "GET|PUT /api/v1/floorplan",
                                              "POST /api/v1/primitives", "GET /api/v1/decisions?since=SEQ&limit=N",
                                              "GET /api/v1/rules", "POST /api/v1/rules/reload",
                                              "POST /api/v1/rules/dry-run", "POST /api/v1/query",
                                              "GET /api/v1/elements/{id}/history", "GET /api/v1/objects/{id}/history"}}});
  }
  throw ApiError(404, "not_found", "no resource at '" + path + "'");
}

}  // namespace

Response error_response(unsigned http_version, bool keep_alive, int status, const std::string& error, const std::string& detail) {
  Response res{static_cast<http::status>(status), http_version};
  res.set(http::field::content_type, "application/json");
  res.keep_alive(keep_alive);
  res.body() = json{{"error", error}, {"detail", detail}}.dump(-1, ' ', false, json::error_handler_t::replace);
  res.prepare_payload();
  return res;
}

Response handle_request(const Request& req, Services& services) {
  const auto fail = [&](int status, const std::string& error, const std::string& detail) {
    auto res = error_response(req.version(), req.keep_alive(), status, error, detail);
    if (status == 405) res.set(http::field::allow, detail.substr(detail.find(':') + 2));
    return res;
  };
  try {
    return route(req, services);
  } catch (const ApiError& e) {
    return fail(e.status(), e.error(), e.what());
  } catch (const apriori::FloorPlanError& e) {
    return fail(400, "bad_floor_plan", e.what());
  } catch (const rules::RuleError& e) {
    return fail(422, "rule_error", e.what());
  } catch (const service::Busy& e) {
    return fail(503, "busy", e.what());
  } catch (const storage::StorageError& e) {
    return fail(503, "storage_error", e.what());
  } catch (const std::invalid_argument& e) {
    return fail(422, "rejected", e.what());
  } catch (const std::exception& e) {
    return fail(500, "internal_error", e.what());
  }
}

}  // namespace wm::api
