#include "server/api/router.h"

#include "apriori/export/dxf_writer.h"
#include "apriori/export/geojson_writer.h"
#include "apriori/import/amrl_import.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/rmf_import.h"

#include <algorithm>
#include <fstream>
#include <filesystem>
#include <optional>
#include <sstream>
#include <cmath>

#include <charconv>
#include <map>

#include <boost/asio/ip/address.hpp>
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

// Query parameters become names (?name=, ?level=) that end up in JSON: each must be UTF-8.
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
    if (!pair.empty()) {
      auto key = percent_decode(pair.substr(0, eq));
      auto value = eq == std::string_view::npos ? std::string() : percent_decode(pair.substr(eq + 1));
      if (json_codec::invalid_utf8_offset(key)) throw bad_request("", "a query parameter's name is not UTF-8");
      if (auto at = json_codec::invalid_utf8_offset(value))
        throw bad_request(key, "invalid UTF-8 at byte " + std::to_string(*at) + " of the query parameter");
      t.query[std::move(key)] = std::move(value);
    }
    rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
  }
  return t;
}

std::string_view header_target(const Request& req) {
  const auto target = req.target();
  return {target.data(), target.size()};
}

std::string lower(std::string_view text) {
  std::string out(text);
  for (auto& c : out)
    if (c >= 'A' && c <= 'Z') c = static_cast<char>(c - 'A' + 'a');
  return out;
}

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  return text;
}

std::string_view header(const Request& req, http::field field) {
  const auto value = req[field];
  return {value.data(), value.size()};
}

// The host of a Host header or an origin's authority, lower case, without port or trailing dot; IPv6
// keeps its brackets ("[::1]").
std::string host_of_authority(std::string_view authority) {
  std::string host = lower(trimmed(authority));
  if (!host.empty() && host.front() == '[') {
    const auto close = host.find(']');
    return close == std::string::npos ? host : host.substr(0, close + 1);
  }
  host = host.substr(0, host.find(':'));
  if (!host.empty() && host.back() == '.') host.pop_back();
  return host;
}

bool is_ip_literal(const std::string& host) {
  std::string address = host;
  if (address.size() > 2 && address.front() == '[' && address.back() == ']') {
    address = address.substr(1, address.size() - 2);
  } else if (address.find(':') != std::string::npos) {
    return false;  // an IPv6 address in a Host header has brackets
  }
  boost::system::error_code ec;
  boost::asio::ip::make_address(address, ec);
  return !ec;
}

// Host check against DNS rebinding: a page of attacker.example that re-resolves its name to 127.0.0.1
// reaches us with "Host: attacker.example". IP literals cannot be rebound, so they always pass; a
// request without Host (HTTP/1.0, no browser) too.
void require_allowed_host(const Request& req, const Services& s) {
  if (s.options.allowed_hosts.empty()) return;
  const auto value = header(req, http::field::host);
  if (trimmed(value).empty()) return;
  const auto host = host_of_authority(value);
  if (is_ip_literal(host)) return;
  if (std::find(s.options.allowed_hosts.begin(), s.options.allowed_hosts.end(), host) != s.options.allowed_hosts.end())
    return;
  throw ApiError(421, "misdirected_request",
                 "this server does not answer to Host '" + host + "' (DNS rebinding?); start wmd with --allowed-hosts " +
                     host + " to allow it");
}

// Origin allow-list: same origin (the origin's host:port is the Host header) or --allowed-origins. A
// request without Origin does not come from a browser page and passes.
void require_allowed_origin(const Request& req, const Services& s) {
  const auto origin = lower(trimmed(header(req, http::field::origin)));
  if (origin.empty()) return;
  std::string normalised = origin;
  while (!normalised.empty() && normalised.back() == '/') normalised.pop_back();
  if (std::find(s.options.allowed_origins.begin(), s.options.allowed_origins.end(), normalised) !=
      s.options.allowed_origins.end())
    return;
  const auto scheme_end = normalised.find("://");
  const auto host = lower(trimmed(header(req, http::field::host)));
  if (scheme_end != std::string::npos && !host.empty()) {
    const auto scheme = normalised.substr(0, scheme_end);
    auto authority = normalised.substr(scheme_end + 3);
    // Browsers leave the default port out of Origin; a client may still write it in Host.
    const bool same = authority == host || (scheme == "http" && authority + ":80" == host) ||
                      (scheme == "https" && authority + ":443" == host);
    if ((scheme == "http" || scheme == "https") && same) return;
  }
  throw ApiError(403, "forbidden_origin",
                 "requests from pages of '" + origin + "' are refused (not this server's origin); start wmd with "
                 "--allowed-origins " + origin + " to allow them");
}

// Compares without stopping at the first difference, so the time taken says nothing about the token.
bool same_secret(std::string_view given, std::string_view expected) {
  unsigned char difference = given.size() == expected.size() ? 0 : 1;
  for (std::size_t i = 0; i < given.size(); ++i)
    difference |= static_cast<unsigned char>(given[i] ^ (expected.empty() ? 0 : expected[i % expected.size()]));
  return difference == 0;
}

// "Bearer <token>", the scheme in any case (RFC 7235 section 2.1), one or more spaces before the token.
bool bearer_matches(std::string_view authorization, std::string_view token) {
  constexpr std::string_view kScheme = "bearer";
  authorization = trimmed(authorization);
  if (authorization.size() <= kScheme.size() || lower(authorization.substr(0, kScheme.size())) != kScheme ||
      authorization[kScheme.size()] != ' ')
    return false;
  return same_secret(trimmed(authorization.substr(kScheme.size())), token);
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

// Text that was not checked as UTF-8 on its way in is written with U+FFFD rather than failing the request
// (nlohmann's type_error 316) after the work is done.
Response json_response(const Request& req, const json& body, http::status status = http::status::ok,
                       std::size_t max_bytes = std::numeric_limits<std::size_t>::max()) {
  Response res{status, req.version()};
  res.set(http::field::content_type, "application/json");
  res.set(http::field::cache_control, "no-store");
  res.keep_alive(req.keep_alive());
  res.body() = body.dump(-1, ' ', false, json::error_handler_t::replace);
  if (res.body().size() > max_bytes)
    throw ApiError(422, "answer_too_large",
                   "the answer is " + std::to_string(res.body().size()) + " bytes, more than the " +
                       std::to_string(max_bytes) + " this server sends; ask for less");
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
  if (!bearer_matches(header(req, http::field::authorization), s.options.token))
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
  json doc = json_codec::parse_json(req.body());
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
  // A dry run loads rule text into this process: like any write it needs the token, and with none
  // configured only an explicit start-up flag allows it.
  if (s.options.token.empty() && !s.options.allow_dry_run_without_token)
    throw ApiError(403, "forbidden",
                   "dry runs load rule text into the server and need a token: start wmd with --token TOKEN and send "
                   "'Authorization: Bearer TOKEN' (or, where every local user is trusted, with "
                   "--allow-dry-run-without-token)");
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
    const auto answer = s.world.query(goal, max_solutions);
    return json_response(req, json_codec::query_result_json(answer, s.options.max_query_answer_bytes), http::status::ok,
                         s.options.max_query_answer_bytes);
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

// The client's request id: the Idempotency-Key header (optional), see WorldService::post_primitives.
std::optional<std::string> request_id(const Request& req) {
  const auto value = req["Idempotency-Key"];
  try {
    return service::parse_request_id(std::string_view(value.data(), value.size()));
  } catch (const std::invalid_argument& e) {
    throw bad_request("Idempotency-Key", e.what());
  }
}

// Runs a post that may carry a request id: an id reused for another request is 409; a retry's answer (the
// original one, nothing applied again) says so in `Idempotent-Replayed: true`.
template <typename Post, typename Answer>
Response idempotent_post(const Request& req, Post&& post, Answer&& answer) {
  try {
    const auto outcome = post(request_id(req));
    auto res = json_response(req, answer(outcome));
    if (outcome.replayed) res.set("Idempotent-Replayed", "true");
    return res;
  } catch (const service::RequestIdConflict& e) {
    throw ApiError(409, "request_id_conflict", e.what());
  }
}

Response post_scan(const Request& req, Services& s) {
  require_token(req, s);
  require_json_body(req);
  auto scan = json_codec::parse_scan(req.body(), s.options.scan_limits);
  return idempotent_post(
      req, [&](std::optional<std::string> id) { return s.world.post_scan(std::move(scan), req.body(), std::move(id)); },
      [](const service::WorldService::ScanOutcome& outcome) {
        json answer = {{"seq", outcome.seq}, {"grid_revision", outcome.grid_revision}, {"lines", nullptr}};
        if (outcome.lines) {
          json decisions = json::array();
          for (const auto& d : outcome.lines->decisions) decisions.push_back(json_codec::decision_json(d));
          answer["lines"] = {{"observation", outcome.lines->seq}, {"version", outcome.lines->version}, {"decisions", decisions}};
        }
        return answer;
      });
}

using Layer = fusion::OccupancyGrid::Layer;

Layer grid_layer(const Target& t) {
  const auto it = t.query.find("layer");
  if (it == t.query.end() || it->second == "bayes") return Layer::bayes_probability;
  if (it->second == "ds_belief") return Layer::ds_belief;
  if (it->second == "ds_plausibility") return Layer::ds_plausibility;
  if (it->second == "ds_conflict") return Layer::ds_conflict;
  throw bad_request("layer", "expected bayes, ds_belief, ds_plausibility or ds_conflict");
}

// The cells to export: the bbox given (x0,y0,x1,y1 in metres, snapped outwards to cells) or everything
// observed so far. nullopt when the grid is empty and no bbox was given.
std::optional<fusion::GridGeometry> grid_region(const Target& t, Services& s, std::int64_t max_cells) {
  const double resolution = s.world.read_grid([](const fusion::OccupancyGrid& g) { return g.resolution_m(); });
  std::optional<fusion::GridGeometry> region;
  if (auto it = t.query.find("bbox"); it != t.query.end()) {
    double v[4];
    std::size_t start = 0;
    for (int i = 0; i < 4; ++i) {
      const auto comma = it->second.find(',', start);
      if ((i < 3) != (comma != std::string::npos)) throw bad_request("bbox", "expected x0,y0,x1,y1 in metres");
      const std::string part = it->second.substr(start, i < 3 ? comma - start : std::string::npos);
      char* end = nullptr;
      v[i] = std::strtod(part.c_str(), &end);
      if (part.empty() || *end != '\0' || !std::isfinite(v[i]) || std::abs(v[i]) > 1e6)
        throw bad_request("bbox", "expected four finite numbers x0,y0,x1,y1");
      start = comma + 1;
    }
    if (v[2] <= v[0] || v[3] <= v[1]) throw bad_request("bbox", "x1 must exceed x0 and y1 must exceed y0");
    const auto x0 = static_cast<std::int64_t>(std::floor(v[0] / resolution));
    const auto y0 = static_cast<std::int64_t>(std::floor(v[1] / resolution));
    const auto x1 = static_cast<std::int64_t>(std::ceil(v[2] / resolution));
    const auto y1 = static_cast<std::int64_t>(std::ceil(v[3] / resolution));
    if ((x1 - x0) * (y1 - y0) > max_cells)
      throw bad_request("bbox", "more than " + std::to_string(max_cells) + " cells; ask for a smaller box");
    region = fusion::GridGeometry({static_cast<double>(x0) * resolution, static_cast<double>(y0) * resolution}, resolution,
                                  x1 - x0, y1 - y0);
  } else {
    region = s.world.read_grid([](const fusion::OccupancyGrid& g) { return g.bounds(); });
    if (region && region->width() * region->height() > max_cells)
      throw bad_request("bbox", "the grid has more than " + std::to_string(max_cells) + " cells; give a bbox");
  }
  return region;
}

// ROS map_server convention: a pixel's occupancy is (255 - value) / 255 with negate 0; unknown is 205
// (between free_thresh 0.196 and occupied_thresh 0.65, so it reads as unknown).
std::string pgm_image(const std::vector<float>& values, const fusion::GridGeometry& region) {
  const auto width = region.width(), height = region.height();
  // The comment says where the raster lies, so one request is enough (map_server takes it from the YAML).
  std::ostringstream head;
  head.precision(10);
  head << "P5\n# worldmodel occupancy grid; origin " << region.origin_m().x() << " " << region.origin_m().y()
         << " resolution " << region.resolution_m() << "\n"
         << width << " " << height << "\n255\n";
  std::string out = head.str();
  const auto header = out.size();
  out.resize(header + static_cast<std::size_t>(width * height));
  for (std::int64_t row = 0; row < height; ++row) {
    // PGM rows run from the top (largest y); the grid's from the bottom.
    const float* src = values.data() + (height - 1 - row) * width;
    char* dst = out.data() + header + row * width;
    for (std::int64_t x = 0; x < width; ++x) {
      const float p = src[x];
      dst[x] = static_cast<char>(std::isnan(p) ? 205 : static_cast<int>(std::lround(255.0 * (1.0 - std::clamp(p, 0.0f, 1.0f)))));
    }
  }
  return out;
}

Response raw_response(const Request& req, std::string body, const char* content_type) {
  Response res{http::status::ok, req.version()};
  res.set(http::field::content_type, content_type);
  res.keep_alive(req.keep_alive());
  res.body() = std::move(body);
  res.prepare_payload();
  return res;
}

Response get_grid(const Request& req, const Target& t, Services& s) {
  const auto layer = grid_layer(t);
  std::string format = "json";
  if (auto it = t.query.find("format"); it != t.query.end()) format = it->second;
  if (format != "json" && format != "pgm") throw bad_request("format", "expected json or pgm");
  const auto region = grid_region(t, s, format == "json" ? 4'000'000 : 64'000'000);
  if (!region) throw ApiError(404, "empty_grid", "no scan has reached the grid yet; POST /api/v1/scans first");
  const auto values = s.world.read_grid([&](const fusion::OccupancyGrid& g) { return g.export_layer(layer, *region); });
  if (format == "pgm") return raw_response(req, pgm_image(values, *region), "image/x-portable-graymap");
  const json head = {{"layer", t.query.count("layer") ? t.query.at("layer") : "bayes"},
                     {"resolution", region->resolution_m()},
                     {"origin", json::array({region->origin_m().x(), region->origin_m().y()})},
                     {"width", region->width()},
                     {"height", region->height()},
                     {"revision", s.world.grid_revision()},
                     {"order", "row-major from the lower-left cell; null = unknown"}};
  auto res = json_response(req, head);
  // The cells are written here rather than as a JSON array of a million values: nlohmann builds one
  // node per cell and formats each double on its own, 1 s for the 1.4 M cells of the Intel lab.
  std::string& body = res.body();
  body.pop_back();  // the head's closing brace
  body.reserve(body.size() + 16 + values.size() * 7);
  body += ",\"data\":[";
  char number[32];
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i > 0) body += ',';
    if (std::isnan(values[i])) {
      body += "null";
      continue;
    }
    const double rounded = std::round(static_cast<double>(values[i]) * 1e4) / 1e4;  // [0, 1] to 4 decimals
    const auto [end, ec] = std::to_chars(number, number + sizeof number, rounded);
    body.append(number, ec == std::errc() ? end : number);
  }
  body += "]}";
  res.prepare_payload();
  return res;
}

// The map_server pair: the YAML names map.pgm beside it; both describe the same region.
Response get_map_yaml(const Request& req, const Target& t, Services& s) {
  const auto region = grid_region(t, s, 64'000'000);
  if (!region) throw ApiError(404, "empty_grid", "no scan has reached the grid yet");
  std::ostringstream yaml;
  yaml.precision(10);
  yaml << "image: map.pgm\n"
       << "mode: trinary\n"
       << "resolution: " << region->resolution_m() << "\n"
       << "origin: [" << region->origin_m().x() << ", " << region->origin_m().y() << ", 0.0]\n"
       << "negate: 0\n"
       << "occupied_thresh: 0.65\n"
       << "free_thresh: 0.196\n";
  return raw_response(req, yaml.str(), "application/yaml");
}

// A file of the web viewer. Paths are checked against the directory: no "..", no hidden files, no escape.
Response get_static(const Request& req, const Services& s, const std::string& relative) {
  if (s.options.web_dir.empty()) throw ApiError(404, "not_found", "this server has no web viewer (--web DIR)");
  if (relative.empty() || relative.find("..") != std::string::npos || relative.front() == '/' ||
      relative.find("/.") != std::string::npos || relative.front() == '.')
    throw ApiError(404, "not_found", "no file '" + relative + "'");
  const std::filesystem::path path = std::filesystem::path(s.options.web_dir) / relative;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) throw ApiError(404, "not_found", "no file '" + relative + "'");
  std::ifstream in(path, std::ios::binary);
  std::ostringstream content;
  content << in.rdbuf();
  static const std::map<std::string, std::string> kTypes = {
      {".html", "text/html; charset=utf-8"}, {".js", "text/javascript; charset=utf-8"}, {".mjs", "text/javascript; charset=utf-8"},
      {".css", "text/css; charset=utf-8"},   {".svg", "image/svg+xml"},                   {".png", "image/png"},
      {".json", "application/json"},         {".ico", "image/x-icon"}};
  const auto type = kTypes.find(path.extension().string());
  auto res = raw_response(req, content.str(), type == kTypes.end() ? "application/octet-stream" : type->second.c_str());
  res.set(http::field::cache_control, "no-cache");
  return res;
}

Response get_history(const Request& req, Services& s, const std::string& id, bool exists, bool is_object) {
  // An object's history includes the decisions about each of its edges ("table-1/2").
  const auto rows = is_object ? s.world.store().object_decisions(id, 10000) : s.world.store().decisions(0, 10000, id);
  if (rows.empty() && !exists) throw ApiError(404, "not_found", "no element or object '" + id + "' and no decision about it");
  json list = json::array();
  for (const auto& d : rows) list.push_back(json_codec::decision_json(d));
  return json_response(req, {{"id", id}, {"exists", exists}, {"decisions", std::move(list)}});
}

// Every name of a plan is stored and written as JSON: one that is not UTF-8 (from a file format that does
// not check it) is refused here, by field, instead of failing when it is written.
void require_utf8_names(const apriori::FloorPlan& plan) {
  const auto check = [](const std::string& text, const std::string& path) {
    if (const auto at = json_codec::invalid_utf8_offset(text))
      throw bad_request(path, "invalid UTF-8 at byte " + std::to_string(*at));
  };
  check(plan.name, "name");
  for (std::size_t i = 0; i < plan.objects.size(); ++i) {
    const auto path = "objects[" + std::to_string(i) + "]";
    check(plan.objects[i].id, path + ".id");
    check(plan.objects[i].kind, path + ".kind");
    for (std::size_t k = 0; k < plan.objects[i].attributes.size(); ++k)
      check(plan.objects[i].attributes[k], path + ".attributes[" + std::to_string(k) + "]");
  }
}

// Units names for ?units= and "units" of an import envelope.
double units_to_metres(const std::string& units, const std::string& path) {
  if (units == "m") return 1.0;
  if (units == "cm") return 0.01;
  if (units == "mm") return 0.001;
  if (units == "in") return 0.0254;
  if (units == "ft") return 0.3048;
  throw bad_request(path, "expected m, cm, mm, in or ft");
}

// An import of a CAD or robotics file: DXF (with a layer mapping), Open-RMF building.yaml or an AMRL vector map.
apriori::ImportResult import_plan(const std::string& format, std::string_view data, const nlohmann::ordered_json& options,
                                  Services& s) {
  if (format == "dxf") {
    apriori::DxfImportOptions o;
    o.limits = s.options.plan_limits;
    if (options.contains("units")) o.units_to_m = units_to_metres(options["units"].get<std::string>(), "import.units");
    if (options.contains("name")) o.name = options["name"].get<std::string>();
    const auto mapping = options.contains("mapping") ? apriori::parse_layer_mapping_json(options["mapping"].dump())
                                                     : s.options.layer_mapping;
    return apriori::import_dxf(data, mapping, o);
  }
  if (format == "rmf") {
    apriori::RmfImportOptions o;
    o.limits = s.options.plan_limits;
    if (options.contains("level")) o.level = options["level"].get<std::string>();
    if (options.contains("name")) o.name = options["name"].get<std::string>();
    return apriori::import_rmf_building(data, o);
  }
  if (format == "amrl") {
    apriori::AmrlImportOptions o;
    o.limits = s.options.plan_limits;
    if (options.contains("name")) o.name = options["name"].get<std::string>();
    return apriori::import_amrl_vectormap(data, o);
  }
  throw bad_request("import.format", "expected dxf, rmf or amrl");
}

Response put_floor_plan(const Request& req, Services& s) {
  require_token(req, s);
  if (req.body().empty()) throw bad_request("", "empty body");
  std::optional<apriori::ImportResult> imported;
  const auto raw_target = req.target();
  const Target t = parse_target(std::string_view(raw_target.data(), raw_target.size()));
  nlohmann::ordered_json query_options = nlohmann::ordered_json::object();
  for (const auto& key : {"units", "level", "name"})
    if (auto it = t.query.find(key); it != t.query.end()) query_options[key] = it->second;
  if (has_content_type(req, "image/vnd.dxf") || has_content_type(req, "application/dxf")) {
    imported = import_plan("dxf", req.body(), query_options, s);
  } else if (has_content_type(req, "application/yaml") || has_content_type(req, "application/x-yaml")) {
    if (const auto at = json_codec::invalid_utf8_offset(req.body())) {
      const auto line = 1 + std::count(req.body().begin(), req.body().begin() + static_cast<std::ptrdiff_t>(*at), '\n');
      throw bad_request("body", "invalid UTF-8 at byte " + std::to_string(*at) + " (line " + std::to_string(line) +
                                    "); YAML is UTF-8 text");
    }
    imported = import_plan("rmf", req.body(), query_options, s);
  } else {
    require_json_body(req);
    // Ordered: a layer mapping's rules apply in file order (first match wins).
    const auto doc = json_codec::parse_ordered_json(req.body());
    if (doc.is_object() && doc.contains("import")) {
      // {"import": {"format": "dxf", "data": "<the file's text>", "mapping": {...}, "units": "mm", ...}}
      const auto& spec = doc["import"];
      if (!spec.is_object()) throw bad_request("import", "expected an object");
      for (const auto& [key, value] : spec.items())
        if (key != "format" && key != "data" && key != "mapping" && key != "units" && key != "level" && key != "name")
          throw bad_request("import." + key, "unknown field");
      if (!spec.contains("format") || !spec["format"].is_string()) throw bad_request("import.format", "expected dxf, rmf or amrl");
      if (!spec.contains("data") || !spec["data"].is_string()) throw bad_request("import.data", "expected the file's text");
      for (const auto& key : {"units", "level", "name"})
        if (spec.contains(key) && !spec[key].is_string()) throw bad_request(std::string("import.") + key, "expected a string");
      if (spec.contains("mapping") && !spec["mapping"].is_object()) throw bad_request("import.mapping", "expected a layer mapping object");
      imported = import_plan(spec["format"].get<std::string>(), spec["data"].get<std::string>(), spec, s);
    } else if (doc.is_array()) {
      imported = import_plan("amrl", req.body(), query_options, s);  // an AMRL vector map is a bare array of lines
    }
  }
  auto plan = imported ? std::move(imported->plan) : apriori::parse_floor_plan_json(req.body(), s.options.plan_limits);
  require_utf8_names(plan);
  std::size_t edges = 0;
  for (const auto& o : plan.objects) edges += o.edges().size();
  const auto objects = plan.objects.size();
  const auto name = plan.name;
  const auto version = s.world.load_floor_plan(std::move(plan));
  json answer = {{"name", name}, {"objects", objects}, {"edges", edges}, {"version", version}};
  if (imported) answer["report"] = json_codec::parse_json(apriori::to_json_text(imported->report));
  return json_response(req, answer);
}

// The observed map in CAD/GIS form: one layer per state.
std::vector<apriori::LayerLines> map_layers(const world::WorldState& state, const world::WorldOptions& options) {
  apriori::LayerLines plan{"plan_unobserved", {}, {}, 8}, confirmed{"confirmed", {}, {}, 3}, adjusted{"adjusted", {}, {}, 1},
      merged{"merged", {}, {}, 5}, added{"new", {}, {}, 6};
  for (const auto& object : state.objects) {
    auto& layer = object.adjustments > 0 ? adjusted : object.confirmations > 0 ? confirmed : plan;
    for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
      const auto edge = world::apriori_edge(object, k, options);
      layer.polylines.push_back({edge.p0(), edge.p1()});
      layer.ids.push_back(world::edge_id(object.plan->id, k));
    }
  }
  for (const auto& [number, element] : state.elements) {
    auto& layer = element.support > 1 ? merged : added;
    layer.polylines.push_back({element.segment.p0(), element.segment.p1()});
    layer.ids.push_back(element.id());
  }
  std::vector<apriori::LayerLines> layers;
  for (auto* l : {&plan, &confirmed, &adjusted, &merged, &added})
    if (!l->polylines.empty()) layers.push_back(std::move(*l));
  return layers;
}

// Where the building differs from its drawing: per CAD object confirmed / moved / never observed.
json as_built_report(const world::WorldState& state) {
  json objects = json::array();
  std::size_t confirmed = 0, moved = 0, unobserved = 0;
  for (const auto& object : state.objects) {
    const auto& drawn = object.plan->pose;
    const auto& now = object.body.pose();
    const double dx = now.x_m - drawn.x_m, dy = now.y_m - drawn.y_m;
    const double dtheta = std::remainder(now.theta_rad - drawn.theta_rad, 2 * M_PI);
    std::string status = "never_observed";
    if (object.adjustments > 0) {
      status = "moved";
      ++moved;
    } else if (object.confirmations > 0) {
      status = "confirmed";
      ++confirmed;
    } else {
      ++unobserved;
    }
    json entry = {{"id", object.plan->id},
                  {"kind", object.plan->kind},
                  {"attributes", object.plan->attributes},
                  {"status", status},
                  {"confirmations", object.confirmations},
                  {"adjustments", object.adjustments}};
    if (object.adjustments > 0) {
      entry["moved_by"] = {{"dx", dx}, {"dy", dy}, {"dtheta", dtheta}, {"distance", std::hypot(dx, dy)},
                           {"sigma_xy", std::sqrt(std::max(object.body.pose_cov()(0, 0), object.body.pose_cov()(1, 1)))}};
    }
    objects.push_back(std::move(entry));
  }
  json extra = json::array();
  for (const auto& [number, element] : state.elements) {
    extra.push_back({{"id", element.id()}, {"p0", json::array({element.segment.p0().x(), element.segment.p0().y()})},
                     {"p1", json::array({element.segment.p1().x(), element.segment.p1().y()})},
                     {"length", element.segment.length_m()}, {"support", element.support}, {"source", element.source}});
  }
  return {{"plan", state.plan_name},
          {"version", state.version},
          {"summary", {{"objects", state.objects.size()}, {"confirmed", confirmed}, {"moved", moved},
                       {"never_observed", unobserved}, {"not_in_plan", state.elements.size()}}},
          {"objects", objects},
          {"not_in_plan", extra}};
}

Response get_floor_plan(const Request& req, Services& s) {
  const auto snap = s.world.snapshot();
  apriori::FloorPlan plan{snap->plan_name, {}};
  for (const auto& o : snap->objects) plan.objects.push_back(*o.plan);
  return json_response(req, json_codec::parse_json(apriori::to_json_text(plan)));
}

Response post_primitives(const Request& req, Services& s) {
  require_token(req, s);
  require_json_body(req);
  auto observation = json_codec::parse_primitives(req.body(), s.world.options().world, s.options.primitive_limits);
  return idempotent_post(
      req,
      [&](std::optional<std::string> id) { return s.world.post_primitives(std::move(observation), req.body(), std::move(id)); },
      [](const service::WorldService::PrimitivesOutcome& outcome) {
        json decisions = json::array();
        for (const auto& d : outcome.decisions) decisions.push_back(json_codec::decision_json(d));
        return json{{"seq", outcome.seq}, {"version", outcome.version}, {"decisions", std::move(decisions)}};
      });
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
    const auto snap = s.world.snapshot();
    if (auto it = t.query.find("format"); it != t.query.end() && it->second != "json") {
      if (it->second == "dxf") return raw_response(req, apriori::write_dxf(map_layers(*snap, s.world.options().world)), "image/vnd.dxf");
      if (it->second == "geojson")
        return raw_response(req, apriori::write_geojson(map_layers(*snap, s.world.options().world)), "application/geo+json");
      throw bad_request("format", "expected json, dxf or geojson");
    }
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
  if (path == "/api/v1/report/as-built") {
    if (method != http::verb::get) method_not_allowed("GET");
    return json_response(req, as_built_report(*s.world.snapshot()));
  }
  if (path == "/api/v1/scans") {
    if (method != http::verb::post) method_not_allowed("POST");
    return post_scan(req, s);
  }
  if (path == "/api/v1/grid") {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_grid(req, t, s);
  }
  if (path == "/api/v1/grid/extract") {
    if (method != http::verb::post) method_not_allowed("POST");
    require_token(req, s);
    const auto outcome = s.world.extract_grid_lines();
    json answer = {{"segments", 0}, {"observation", nullptr}, {"decisions", json::array()}};
    if (outcome) {
      answer["segments"] = outcome->decisions.size();
      answer["observation"] = outcome->seq;
      for (const auto& d : outcome->decisions) answer["decisions"].push_back(json_codec::decision_json(d));
    }
    return json_response(req, answer);
  }
  if (path == "/api/v1/grid/map.yaml") {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_map_yaml(req, t, s);
  }
  if (path == "/api/v1/grid/map.pgm") {
    if (method != http::verb::get) method_not_allowed("GET");
    Target pgm = t;
    pgm.query["format"] = "pgm";
    pgm.query["layer"] = "bayes";
    return get_grid(req, pgm, s);
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
    return get_history(req, s, id, exists, is_object);
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
  if (path.rfind("/web/", 0) == 0) {
    if (method != http::verb::get) method_not_allowed("GET");
    return get_static(req, s, path.substr(5));
  }
  std::error_code no_index;
  if (path == "/" && method == http::verb::get && !s.options.web_dir.empty() &&
      std::filesystem::is_regular_file(std::filesystem::path(s.options.web_dir) / "index.html", no_index))
    return get_static(req, s, "index.html");
  if ((path == "/" || path == "/api/v1") && method == http::verb::get) {
    return json_response(req, {{"service", "worldmodel"},
                               {"api", "/api/v1"},
                               {"endpoints", {"GET /api/v1/health", "GET /api/v1/map", "GET /api/v1/objects[/{id}]",
                                              "GET /api/v1/elements[/{id}]", "GET|PUT /api/v1/floorplan",
                                              "POST /api/v1/primitives", "GET /api/v1/decisions?since=SEQ&limit=N",
                                              "GET /api/v1/rules", "POST /api/v1/rules/reload",
                                              "POST /api/v1/rules/dry-run", "POST /api/v1/query", "POST /api/v1/scans",
                                              "GET /api/v1/grid?layer=L&bbox=x0,y0,x1,y1&format=json|pgm",
                                              "GET /api/v1/grid/map.yaml", "GET /api/v1/grid/map.pgm",
                                              "GET /api/v1/map?format=json|dxf|geojson", "GET /api/v1/report/as-built",
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

Lane handler_lane(const Request& req) {
  const auto target = header_target(req);
  const auto path = target.substr(0, target.find('?'));
  const auto method = req.method();
  if (method == http::verb::get && (path == "/api/v1/health" || path == "/api/v1")) return Lane::immediate;
  if (method == http::verb::get || method == http::verb::head) return Lane::read;
  // Queries and dry runs wait for the Prolog reader, not the writer.
  if (path == "/api/v1/query" || path == "/api/v1/rules/dry-run") return Lane::read;
  return Lane::write;
}

std::optional<Response> authorize_events(const Request& req, const Services& services) {
  try {
    require_allowed_host(req, services);
    require_allowed_origin(req, services);
    const auto& token = services.options.token;
    if (token.empty() || bearer_matches(header(req, http::field::authorization), token)) return std::nullopt;
    const auto raw_target = req.target();
    const Target t = parse_target(std::string_view(raw_target.data(), raw_target.size()));
    if (const auto it = t.query.find("token"); it != t.query.end() && same_secret(it->second, token)) return std::nullopt;
    throw ApiError(401, "unauthorized",
                   "the events stream of this server needs 'Authorization: Bearer <token>' or ?token=<token>");
  } catch (const ApiError& e) {
    return error_response(req.version(), false, e.status(), e.error(), e.what());
  } catch (const std::exception& e) {
    return error_response(req.version(), false, 500, "internal_error", e.what());
  }
}

Response handle_request(const Request& req, Services& services) {
  const auto fail = [&](int status, const std::string& error, const std::string& detail) {
    auto res = error_response(req.version(), req.keep_alive(), status, error, detail);
    if (status == 405) res.set(http::field::allow, detail.substr(detail.find(':') + 2));
    return res;
  };
  try {
    require_allowed_host(req, services);
    // Browsers send simple cross-site POSTs (a form, text/plain) without asking first: whatever changes
    // state must come from our own pages or an allowed origin.
    if (req.method() != http::verb::get && req.method() != http::verb::head) require_allowed_origin(req, services);
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
