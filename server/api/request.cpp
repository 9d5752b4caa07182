#include "server/api/request.h"

#include <algorithm>
#include <boost/beast/core/string.hpp>
#include <charconv>
#include <cmath>
#include <cstdlib>

#include "server/api/api_error.h"
#include "server/json/codec.h"

namespace wm::api {
namespace {

namespace http = boost::beast::http;

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

constexpr std::size_t kMaxRequestIdLength = 200;

}  // namespace

std::optional<std::string> Target::param(const std::string& name) const {
  const auto it = query.find(name);
  if (it == query.end()) return std::nullopt;
  return it->second;
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

std::string_view header(const Request& request, http::field field) {
  const auto value = request[field];
  return {value.data(), value.size()};
}

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  return text;
}

bool iequals(std::string_view a, std::string_view b) {
  return boost::beast::iequals(boost::beast::string_view(a.data(), a.size()),
                               boost::beast::string_view(b.data(), b.size()));
}

std::chrono::milliseconds accepted_staleness(const Request& request) {
  std::optional<std::chrono::milliseconds> accepted;  // the first well-formed max-stale
  for_each_list_item(request, http::field::cache_control, [&](std::string_view item) {
    constexpr std::string_view kName = "max-stale";
    if (accepted || item.size() < kName.size() || !iequals(item.substr(0, kName.size()), kName)) return;
    auto rest = item.substr(kName.size());
    if (rest.empty()) {
      accepted = std::chrono::seconds(60);
      return;
    }
    if (rest.front() != '=') return;
    rest.remove_prefix(1);
    if (rest.size() >= 2 && rest.front() == '"' && rest.back() == '"') rest = rest.substr(1, rest.size() - 2);
    if (rest.empty() || rest.size() > 6 || rest.find_first_not_of("0123456789") != std::string_view::npos) return;
    accepted = std::chrono::seconds(std::stoi(std::string(rest)));
  });
  return accepted.value_or(std::chrono::milliseconds(0));
}

bool has_content_type(const Request& request, std::string_view wanted) {
  const auto value = request[http::field::content_type];
  auto type = value.substr(0, value.find(';'));
  while (!type.empty() && type.back() == ' ') type.remove_suffix(1);
  return iequals(std::string_view(type.data(), type.size()), wanted);
}

std::int64_t query_int(const Target& target, const std::string& key, std::int64_t fallback, std::int64_t min,
                       std::int64_t max) {
  const auto it = target.query.find(key);
  if (it == target.query.end()) return fallback;
  std::int64_t v = 0;
  const auto& s = it->second;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || p != s.data() + s.size() || v < min || v > max)
    throw bad_request(
        key, "expected an integer in [" + std::to_string(min) + ", " + std::to_string(max) + "], got '" + s + "'");
  return v;
}

std::optional<QueryBox> query_bbox(const Target& target) {
  const auto bbox = target.param("bbox");
  if (!bbox) return std::nullopt;
  double v[4];
  std::size_t start = 0;
  for (int i = 0; i < 4; ++i) {
    const auto comma = bbox->find(',', start);
    if ((i < 3) != (comma != std::string::npos)) throw bad_request("bbox", "expected x0,y0,x1,y1 in metres");
    const std::string part = bbox->substr(start, i < 3 ? comma - start : std::string::npos);
    char* end = nullptr;
    v[i] = std::strtod(part.c_str(), &end);
    if (part.empty() || *end != '\0' || !std::isfinite(v[i]) || std::abs(v[i]) > 1e6)
      throw bad_request("bbox", "expected four finite numbers x0,y0,x1,y1");
    start = comma + 1;
  }
  if (v[2] <= v[0] || v[3] <= v[1]) throw bad_request("bbox", "x1 must exceed x0 and y1 must exceed y0");
  return QueryBox{v[0], v[1], v[2], v[3]};
}

void require_json_body(const Request& request) {
  if (request.body().empty()) throw bad_request("", "empty body");
  if (!has_content_type(request, "application/json"))
    throw ApiError(415, "unsupported_media_type",
                   "send the body as Content-Type: application/json (got '" +
                       std::string(header(request, http::field::content_type)) + "')");
}

nlohmann::json parse_json_object(const Request& request) {
  require_json_body(request);
  auto doc = json_codec::parse_json(request.body());
  if (!doc.is_object()) throw bad_request("", "expected a JSON object");
  return doc;
}

std::string string_field(const nlohmann::json& doc, const std::string& key, std::size_t max_size) {
  const auto it = doc.find(key);
  if (it == doc.end()) throw bad_request(key, "missing field");
  if (!it->is_string()) throw bad_request(key, "expected a string");
  auto text = it->get<std::string>();
  if (text.empty() || text.size() > max_size)
    throw bad_request(key, "expected 1 to " + std::to_string(max_size) + " characters");
  return text;
}

std::size_t count_field(const nlohmann::json& doc, const std::string& key, std::size_t fallback, std::size_t max) {
  const auto it = doc.find(key);
  if (it == doc.end()) return fallback;
  if (!it->is_number_integer() || it->get<std::int64_t>() < 1 ||
      it->get<std::int64_t>() > static_cast<std::int64_t>(max))
    throw bad_request(key, "expected an integer in [1, " + std::to_string(max) + "]");
  return static_cast<std::size_t>(it->get<std::int64_t>());
}

void require_known_keys(const nlohmann::json& doc, std::initializer_list<std::string_view> known) {
  for (const auto& [key, value] : doc.items())
    if (std::find(known.begin(), known.end(), key) == known.end()) throw bad_request(key, "unknown field");
}

std::optional<std::string> request_id(const Request& request) {
  const auto raw = request["Idempotency-Key"];
  std::string_view value(raw.data(), raw.size());
  const auto refuse = [](const std::string& why) { return bad_request("Idempotency-Key", why); };
  while (!value.empty() && (value.front() == ' ' || value.front() == '\t')) value.remove_prefix(1);
  while (!value.empty() && (value.back() == ' ' || value.back() == '\t')) value.remove_suffix(1);
  if (value.empty()) return std::nullopt;
  if (value.size() >= 2 && value.front() == '"' && value.back() == '"') value = value.substr(1, value.size() - 2);
  if (value.empty() || value.size() > kMaxRequestIdLength)
    throw refuse("expected 1 to " + std::to_string(kMaxRequestIdLength) + " characters");
  for (const char c : value)
    if (c < 0x21 || c > 0x7e || c == '"' || c == '\\')
      throw refuse("only visible ASCII characters other than '\"' and '\\' are allowed");
  return std::string(value);
}

}  // namespace wm::api
