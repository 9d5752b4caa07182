#include "server/json/codec.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <filesystem>
#include <limits>
#include <regex>

#include "apriori/import/json_limits.h"
#include "common/utf8.h"
#include "server/json/codec_error.h"

namespace wm::json_codec {
namespace {

using nlohmann::json;

template <typename Json>
Json parse_checked(std::string_view text) {
  if (auto error = apriori::json_nesting_error(text)) throw bad_request("", *error);
  try {
    return Json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::parse_error& e) {
    throw bad_request("", std::string("malformed JSON: ") + e.what());
  } catch (const nlohmann::json::out_of_range& e) {
    // nlohmann refuses literals like 1e999 that overflow a double: they would become Inf.
    throw bad_request("", std::string("number out of range (must be finite): ") + e.what());
  }
}

std::string field(const std::string& path, const std::string& key) { return path.empty() ? key : path + "." + key; }
std::string item(const std::string& path, std::size_t i) { return path + "[" + std::to_string(i) + "]"; }

double finite_number(const json& value, const std::string& path, double limit) {
  if (!value.is_number()) throw bad_request(path, "expected a number");
  const double v = value.get<double>();
  if (!std::isfinite(v)) throw bad_request(path, "not a finite number");
  if (std::abs(v) > limit) throw bad_request(path, "absurd value");
  return v;
}

Eigen::Vector2d point(const json& value, const std::string& path, double limit) {
  if (!value.is_array() || value.size() != 2) throw bad_request(path, "expected a point [x, y]");
  return {finite_number(value[0], item(path, 0), limit), finite_number(value[1], item(path, 1), limit)};
}

Eigen::Matrix2d covariance(const json& value, const std::string& path) {
  if (!value.is_array() || value.size() != 2) throw bad_request(path, "expected a 2x2 matrix [[a, b], [b, c]]");
  Eigen::Matrix2d m;
  for (int r = 0; r < 2; ++r) {
    if (!value[r].is_array() || value[r].size() != 2) throw bad_request(item(path, r), "expected 2 numbers");
    for (int c = 0; c < 2; ++c) m(r, c) = finite_number(value[r][c], item(item(path, r), c), 1e6);
  }
  if (std::abs(m(0, 1) - m(1, 0)) > 1e-12 * std::max(1.0, std::abs(m(0, 1)))) throw bad_request(path, "not symmetric");
  if (m(0, 0) <= 0.0 || m(0, 0) * m(1, 1) - m(0, 1) * m(1, 0) <= 0.0) throw bad_request(path, "not positive definite");
  return m;
}

json point_json(const Eigen::Vector2d& p) { return json::array({p.x(), p.y()}); }

json matrix_json(const Eigen::MatrixXd& m) {
  json rows = json::array();
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    json row = json::array();
    for (Eigen::Index c = 0; c < m.cols(); ++c) row.push_back(m(r, c));
    rows.push_back(std::move(row));
  }
  return rows;
}

json segment_json(const fusion::LineSegment& s) {
  return {{"p0", point_json(s.p0())}, {"p1", point_json(s.p1())},       {"rho", s.line.rho_m},
          {"phi", s.line.phi_rad},    {"cov", matrix_json(s.line.cov)}, {"length", s.length_m()}};
}

}  // namespace

json parse_json(std::string_view text) { return parse_checked<json>(text); }
nlohmann::ordered_json parse_ordered_json(std::string_view text) { return parse_checked<nlohmann::ordered_json>(text); }

std::optional<std::size_t> invalid_utf8_offset(std::string_view text) { return common::invalid_utf8_offset(text); }

std::optional<std::string> observer_of(const json& doc) {
  std::optional<std::string> observer;
  for (const char* key : {"observer", "source"}) {
    const auto it = doc.find(key);
    if (it == doc.end()) continue;
    if (!it->is_string() || it->get<std::string>().empty() || it->get<std::string>().size() > 128)
      throw bad_request(key, "expected a non-empty string of at most 128 characters");
    // A name is shown, logged and stored as text (PostgreSQL's text holds no NUL): no control characters.
    const auto& name = it->get_ref<const std::string&>();
    if (std::any_of(name.begin(), name.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; }))
      throw bad_request(key, "expected a name without control characters");
    if (observer && *observer != it->get<std::string>())
      throw bad_request("source", "\"source\" is the older name of \"observer\": give one, or both the same");
    observer = it->get<std::string>();
  }
  return observer;
}

world::Observation parse_primitives(std::string_view body, const world::WorldOptions& options,
                                    const PrimitiveLimits& limits) {
  const json doc = parse_json(body);
  if (!doc.is_object()) throw bad_request("", "expected an object with \"segments\"");
  for (const auto& [key, value] : doc.items())
    if (key != "observer" && key != "source" && key != "stamp" && key != "segments" && key != "sensor")
      throw bad_request(key, "unknown field");
  world::Observation observation;
  observation.observer = observer_of(doc).value_or("anonymous");
  if (auto it = doc.find("sensor"); it != doc.end()) {
    // An atom the rules compare against (observation_sensor/1), e.g. laser or sonar.
    static const std::regex kSensor("[a-z][a-z0-9_]{0,31}");
    if (!it->is_string() || !std::regex_match(it->get<std::string>(), kSensor))
      throw bad_request("sensor", "expected a lower-case name like \"laser\" or \"sonar\"");
    observation.sensor = it->get<std::string>();
  }
  if (auto it = doc.find("stamp"); it != doc.end()) observation.stamp_s = finite_number(*it, "stamp", 1e12);
  auto it = doc.find("segments");
  if (it == doc.end()) throw bad_request("segments", "missing field");
  if (!it->is_array()) throw bad_request("segments", "expected an array");
  if (it->empty()) throw bad_request("segments", "must not be empty");
  if (it->size() > limits.max_segments)
    throw bad_request("segments", "more than " + std::to_string(limits.max_segments) + " segments in one request");
  for (std::size_t i = 0; i < it->size(); ++i) {
    const auto path = item("segments", i);
    const json& s = (*it)[i];
    if (!s.is_object()) throw bad_request(path, "expected {\"p0\", \"p1\", \"cov\"?}");
    for (const auto& [key, value] : s.items())
      if (key != "p0" && key != "p1" && key != "cov") throw bad_request(field(path, key), "unknown field");
    if (!s.contains("p0")) throw bad_request(field(path, "p0"), "missing field");
    if (!s.contains("p1")) throw bad_request(field(path, "p1"), "missing field");
    const auto p0 = point(s["p0"], field(path, "p0"), limits.max_abs_coordinate_m);
    const auto p1 = point(s["p1"], field(path, "p1"), limits.max_abs_coordinate_m);
    if ((p1 - p0).norm() < limits.min_length_m)
      throw bad_request(path, "segment shorter than " + std::to_string(limits.min_length_m) + " m");
    try {
      if (s.contains("cov")) {
        observation.segments.push_back(
            {fusion::LineSegment::from_points(p0, p1, covariance(s["cov"], field(path, "cov")))});
      } else {
        auto segment = fusion::LineSegment::from_points(p0, p1, Eigen::Matrix2d::Identity());
        segment.line.cov =
            world::midpoint_line_cov(segment, options.default_offset_sigma_m, options.default_angle_sigma_rad);
        observation.segments.push_back({segment});
      }
    } catch (const std::invalid_argument& e) {
      throw bad_request(path, e.what());
    }
  }
  return observation;
}

namespace {

// A float32 typed array (RFC 8746 tag 85, little-endian), each value checked as a JSON number would be.
std::vector<double> float32_list(const json::binary_t& bytes, const std::string& key, std::size_t max_items) {
  if (!bytes.has_subtype() || bytes.subtype() != kCborFloat32LeTag)
    throw bad_request(key, "expected an array of numbers or a float32 array (CBOR tag 85 over a byte string)");
  if (bytes.size() % 4 != 0) throw bad_request(key, "a float32 array needs 4 bytes per value");
  const std::size_t count = bytes.size() / 4;
  if (count == 0) throw bad_request(key, "must not be empty");
  if (count > max_items) throw bad_request(key, "more than " + std::to_string(max_items) + " values");
  std::vector<double> values;
  values.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t bits =
        static_cast<std::uint32_t>(bytes[4 * i]) | static_cast<std::uint32_t>(bytes[4 * i + 1]) << 8 |
        static_cast<std::uint32_t>(bytes[4 * i + 2]) << 16 | static_cast<std::uint32_t>(bytes[4 * i + 3]) << 24;
    const auto v = static_cast<double>(std::bit_cast<float>(bits));
    if (!std::isfinite(v)) throw bad_request(item(key, i), "not a finite number");
    if (std::abs(v) > 1e9) throw bad_request(item(key, i), "absurd value");
    values.push_back(v);
  }
  return values;
}

std::vector<double> number_list(const json& doc, const std::string& key, std::size_t max_items, bool allow_null) {
  const auto it = doc.find(key);
  if (it == doc.end()) throw bad_request(key, "missing field");
  if (it->is_binary()) return float32_list(it->get_binary(), key, max_items);
  if (!it->is_array()) throw bad_request(key, "expected an array of numbers");
  if (it->empty()) throw bad_request(key, "must not be empty");
  if (it->size() > max_items) throw bad_request(key, "more than " + std::to_string(max_items) + " values");
  std::vector<double> values;
  values.reserve(it->size());
  for (std::size_t i = 0; i < it->size(); ++i) {
    const json& v = (*it)[i];
    if (allow_null && v.is_null()) {
      values.push_back(std::numeric_limits<double>::quiet_NaN());  // no reading: ignored per beam
    } else {
      values.push_back(finite_number(v, item(key, i), 1e9));
    }
  }
  return values;
}

double required_number(const json& doc, const std::string& key, double limit, const std::string& parent = "") {
  const auto path = parent.empty() ? key : parent + "." + key;
  const auto it = doc.find(key);
  if (it == doc.end()) throw bad_request(path, "missing field");
  return finite_number(*it, path, limit);
}

}  // namespace

void require_pose_covariance(const Eigen::Matrix3d& cov, const std::string& field) {
  const double scale = std::max(1e-300, cov.cwiseAbs().maxCoeff());
  if ((cov - cov.transpose()).cwiseAbs().maxCoeff() > 1e-9 * scale) throw bad_request(field, "not symmetric");
  if (cov.diagonal().minCoeff() < 0) throw bad_request(field, "a variance is negative");
  // One that is not positive semi-definite would weigh the pose negatively where a scan is aligned to the map, and
  // spread a line's covariance into a negative variance.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(cov);
  if (eigen.eigenvalues().minCoeff() < -1e-9 * scale)
    throw bad_request(field, "not positive semi-definite (a correlation above 1)");
}

world::ScanObservation parse_scan(std::string_view body, const ScanLimits& limits) {
  return scan_from_document(parse_json(body), limits);
}

namespace {

// nlohmann's DOM builder behind a guard: the reader recurses once per level of nesting, and a CBOR byte makes a value
// (an array of a million nulls is a megabyte of CBOR), so both are counted before the DOM grows. Text must be UTF-8
// (nlohmann's CBOR reader does not check it; its JSON writer would throw on it in an answer or the journal).
class BoundedCborDom {
 public:
  BoundedCborDom(json& result, std::size_t max_values) : dom_(result, true), max_values_(max_values) {}

  bool null() { return value() && dom_.null(); }
  bool boolean(bool v) { return value() && dom_.boolean(v); }
  bool number_integer(json::number_integer_t v) { return value() && dom_.number_integer(v); }
  bool number_unsigned(json::number_unsigned_t v) { return value() && dom_.number_unsigned(v); }
  bool number_float(json::number_float_t v, const json::string_t& text) {
    return value() && dom_.number_float(v, text);
  }
  bool string(json::string_t& s) { return utf8(s, "a text string") && value() && dom_.string(s); }
  bool binary(json::binary_t& b) { return value() && dom_.binary(b); }
  bool start_object(std::size_t n) { return deeper() && value() && dom_.start_object(n); }
  bool key(json::string_t& k) { return utf8(k, "a map key") && dom_.key(k); }
  bool end_object() {
    --depth_;
    return dom_.end_object();
  }
  bool start_array(std::size_t n) { return deeper() && value() && dom_.start_array(n); }
  bool end_array() {
    --depth_;
    return dom_.end_array();
  }
  template <class Exception>
  bool parse_error(std::size_t position, const std::string& token, const Exception& e) {
    return dom_.parse_error(position, token, e);  // throws e
  }

  const std::string& refusal() const { return refusal_; }

 private:
  bool refuse(std::string why) {
    refusal_ = std::move(why);
    return false;
  }
  bool value() {
    return ++values_ <= max_values_ || refuse("more than " + std::to_string(max_values_) + " values in one body");
  }
  bool deeper() {
    return ++depth_ <= apriori::kMaxJsonDepth ||
           refuse("nested deeper than " + std::to_string(apriori::kMaxJsonDepth) + " levels");
  }
  bool utf8(const std::string& text, const char* what) {
    if (const auto at = common::invalid_utf8_offset(text))
      return refuse(std::string(what) + " that is not UTF-8 (at its byte " + std::to_string(*at) + ")");
    return true;
  }

  nlohmann::detail::json_sax_dom_parser<json> dom_;
  std::size_t max_values_;
  std::size_t values_ = 0;
  std::size_t depth_ = 0;
  std::string refusal_;
};

}  // namespace

json parse_cbor(std::string_view bytes, std::size_t max_values) {
  namespace detail = nlohmann::detail;
  json result;
  BoundedCborDom sax(result, max_values);
  auto input = detail::input_adapter(bytes.data(), bytes.data() + bytes.size());
  detail::binary_reader<json, decltype(input), BoundedCborDom> reader(std::move(input), detail::input_format_t::cbor);
  try {
    if (!reader.sax_parse(detail::input_format_t::cbor, &sax, true, nlohmann::json::cbor_tag_handler_t::store))
      throw bad_request("", "CBOR refused: " + sax.refusal());
  } catch (const nlohmann::json::exception& e) {  // parse_error, or out_of_range for an absurd declared size
    throw bad_request("", std::string("malformed CBOR: ") + e.what());
  }
  return result;
}

namespace {

// Values a body of `scans` scans may hold: ranges and angles, a pose covariance, the other fields.
std::size_t max_body_values(const ScanLimits& limits, std::size_t scans) {
  return scans * (2 * limits.max_beams + 64) + 16;
}

json decode_body(std::string_view body, BodyFormat format, const ScanLimits& limits) {
  if (format == BodyFormat::json) return parse_json(body);
  return parse_cbor(body, max_body_values(limits, std::max<std::size_t>(1, limits.max_batch_scans)));
}

}  // namespace

ScanBody parse_scan_body(std::string_view body, BodyFormat format, const ScanLimits& limits) {
  const json doc = decode_body(body, format, limits);
  ScanBody result;
  const auto batch = doc.is_object() ? doc.find("scans") : doc.end();
  if (!doc.is_object() || batch == doc.end()) {
    result.scans.push_back(scan_from_document(doc, limits));
    return result;
  }
  result.batch = true;
  for (const auto& [key, value] : doc.items())
    if (key != "scans") throw bad_request(key, "unknown field for a batch of scans (only \"scans\")");
  if (!batch->is_array()) throw bad_request("scans", "expected an array of scan objects");
  if (batch->empty()) throw bad_request("scans", "must not be empty");
  if (batch->size() > limits.max_batch_scans)
    throw bad_request("scans", "more than " + std::to_string(limits.max_batch_scans) + " scans in one batch");
  result.scans.reserve(batch->size());
  for (std::size_t i = 0; i < batch->size(); ++i) {
    try {
      result.scans.push_back(scan_from_document((*batch)[i], limits));
    } catch (const CodecError& e) {
      const auto path = item("scans", i);
      throw bad_request(e.path().empty() ? path : path + "." + e.path(), e.message());
    }
  }
  return result;
}

world::ScanObservation scan_from_document(const json& doc, const ScanLimits& limits) {
  if (!doc.is_object()) throw bad_request("", "expected a scan object");
  const auto sensor_it = doc.find("sensor");
  if (sensor_it == doc.end()) throw bad_request("sensor", "missing field (\"laser\" or \"sonar\")");
  if (!sensor_it->is_string() || (*sensor_it != "laser" && *sensor_it != "sonar"))
    throw bad_request("sensor", "expected \"laser\" or \"sonar\"");
  const bool laser = *sensor_it == "laser";
  static const std::vector<std::string> kLaserKeys = {
      "sensor", "observer",  "source",    "stamp",       "pose",     "angle_min",         "angle_increment",
      "ranges", "range_min", "range_max", "sigma_range", "pose_cov", "sigma_range_per_m", "usable_range"};
  static const std::vector<std::string> kSonarKeys = {"sensor",    "observer",  "source",      "stamp",
                                                      "pose",      "angles",    "ranges",      "beam_width",
                                                      "range_min", "range_max", "sigma_range", "pose_cov"};
  const auto& known = laser ? kLaserKeys : kSonarKeys;
  for (const auto& [key, value] : doc.items())
    if (std::find(known.begin(), known.end(), key) == known.end())
      throw bad_request(key, std::string("unknown field for a ") + (laser ? "laser" : "sonar") + " scan");

  world::ScanObservation request;
  if (auto observer = observer_of(doc)) request.observer = std::move(*observer);
  if (auto it = doc.find("stamp"); it != doc.end()) request.stamp_s = finite_number(*it, "stamp", 1e12);
  const auto pose_it = doc.find("pose");
  if (pose_it == doc.end()) throw bad_request("pose", "missing field (the sensor pose in the world)");
  if (!pose_it->is_object()) throw bad_request("pose", "expected {\"x\", \"y\", \"theta\"}");
  for (const auto& [key, value] : pose_it->items())
    if (key != "x" && key != "y" && key != "theta") throw bad_request("pose." + key, "unknown field");
  const fusion::Pose2D pose{required_number(*pose_it, "x", limits.max_abs_coordinate_m, "pose"),
                            required_number(*pose_it, "y", limits.max_abs_coordinate_m, "pose"),
                            required_number(*pose_it, "theta", 1e3, "pose")};
  if (auto it = doc.find("pose_cov"); it != doc.end()) {
    if (!it->is_array() || it->size() != 3) throw bad_request("pose_cov", "expected a 3x3 matrix over x, y, theta");
    for (int r = 0; r < 3; ++r) {
      if (!(*it)[r].is_array() || (*it)[r].size() != 3) throw bad_request(item("pose_cov", r), "expected 3 numbers");
      for (int c = 0; c < 3; ++c)
        request.pose_cov(r, c) = finite_number((*it)[r][c], item(item("pose_cov", r), c), 1e6);
    }
    require_pose_covariance(request.pose_cov, "pose_cov");
  }
  const double range_min =
      doc.contains("range_min") ? finite_number(doc["range_min"], "range_min", limits.max_range_m) : 0.0;
  const double range_max = required_number(doc, "range_max", limits.max_range_m);
  if (range_min < 0) throw bad_request("range_min", "must be >= 0");
  if (range_max <= range_min) throw bad_request("range_max", "must be greater than range_min");
  auto ranges = number_list(doc, "ranges", limits.max_beams, true);

  if (laser) {
    fusion::LaserScan scan;
    scan.sensor_pose = pose;
    scan.angle_min_rad = required_number(doc, "angle_min", 10.0);
    scan.angle_increment_rad = required_number(doc, "angle_increment", 1.0);
    if (scan.angle_increment_rad == 0.0) throw bad_request("angle_increment", "must not be 0");
    scan.ranges_m = std::move(ranges);
    scan.range_min_m = range_min;
    scan.range_max_m = range_max;
    if (doc.contains("sigma_range")) scan.sigma_range_m = finite_number(doc["sigma_range"], "sigma_range", 10.0);
    if (scan.sigma_range_m <= 0) throw bad_request("sigma_range", "must be > 0");
    if (doc.contains("sigma_range_per_m")) {
      scan.sigma_range_per_m = finite_number(doc["sigma_range_per_m"], "sigma_range_per_m", 1.0);
      if (scan.sigma_range_per_m < 0) throw bad_request("sigma_range_per_m", "must be >= 0 [m/m]");
    }
    if (doc.contains("usable_range")) {
      scan.usable_range_m = finite_number(doc["usable_range"], "usable_range", limits.max_range_m);
      if (scan.usable_range_m <= 0) throw bad_request("usable_range", "must be > 0 [m]");
    }
    request.scan = std::move(scan);
  } else {
    fusion::SonarScan scan;
    scan.sensor_pose = pose;
    scan.angles_rad = number_list(doc, "angles", limits.max_beams, false);
    if (scan.angles_rad.size() != ranges.size())
      throw bad_request("angles", "needs one angle per range (" + std::to_string(ranges.size()) + ")");
    for (std::size_t i = 0; i < scan.angles_rad.size(); ++i)
      if (std::abs(scan.angles_rad[i]) > 10.0) throw bad_request(item("angles", i), "absurd angle [rad]");
    scan.ranges_m = std::move(ranges);
    scan.range_min_m = range_min;
    scan.range_max_m = range_max;
    if (doc.contains("beam_width")) scan.beam_width_rad = finite_number(doc["beam_width"], "beam_width", 3.2);
    if (scan.beam_width_rad <= 0) throw bad_request("beam_width", "must be > 0 [rad]");
    if (doc.contains("sigma_range")) scan.sigma_range_m = finite_number(doc["sigma_range"], "sigma_range", 10.0);
    if (scan.sigma_range_m <= 0) throw bad_request("sigma_range", "must be > 0");
    request.scan = std::move(scan);
  }
  // The grid's own checks (sizes, finiteness) as a 400 rather than an internal error.
  try {
    std::visit([](const auto& scan) { fusion::validate(scan); }, request.scan);
  } catch (const std::invalid_argument& e) {
    throw bad_request("", std::string("invalid scan: ") + e.what());
  }
  return request;
}

json object_json(const world::ObjectState& object, const world::WorldOptions& options) {
  const auto& plan = *object.plan;
  const auto& pose = object.body.pose();
  json edges = json::array();
  for (std::size_t k = 0; k < object.body.edges().size(); ++k) {
    json e = segment_json(world::apriori_edge(object, k, options));
    e["id"] = world::edge_id(plan.id, k);
    edges.push_back(std::move(e));
  }
  return {{"id", plan.id},
          {"kind", plan.kind},
          {"attributes", plan.attributes},
          {"pose", {{"x", pose.x_m}, {"y", pose.y_m}, {"theta", pose.theta_rad}}},
          {"pose_cov", matrix_json(object.body.pose_cov())},
          {"drawn_pose", {{"x", plan.pose.x_m}, {"y", plan.pose.y_m}, {"theta", plan.pose.theta_rad}}},
          {"confirmations", object.confirmations},
          {"adjustments", object.adjustments},
          {"updated_version", object.updated_version},
          {"edges", std::move(edges)}};
}

json element_json(const world::Element& element) {
  json j = segment_json(element.segment);
  j["id"] = element.id();
  j["support"] = element.support;
  j["origin"] = element.origin;
  j["source"] = element.origin;  // the name before "origin", kept for clients
  j["observer"] = element.observer;
  j["created_version"] = element.created_version;
  j["updated_version"] = element.updated_version;
  return j;
}

json map_json(const world::WorldState& state, const world::WorldOptions& options,
              const std::optional<world::MapExcerpt>& excerpt) {
  json objects = json::array();
  json elements = json::array();
  if (excerpt) {
    for (const auto index : excerpt->objects) objects.push_back(object_json(state.objects[index], options));
    for (const auto number : excerpt->elements) elements.push_back(element_json(state.elements.at(number)));
  } else {
    for (const auto& o : state.objects) objects.push_back(object_json(o, options));
    for (const auto& [number, e] : state.elements) elements.push_back(element_json(e));
  }
  return {{"version", state.version},
          {"plan", state.plan_name},
          {"placement", placement_json(state.placement, state.placement_cov)},
          {"georeference", georeference_json(state.georeference)},
          {"objects", std::move(objects)},
          {"elements", std::move(elements)}};
}

json placement_json(const fusion::Similarity2D& placement, const Eigen::Matrix4d& cov) {
  json rows = json::array();
  for (int r = 0; r < 4; ++r) rows.push_back(json::array({cov(r, 0), cov(r, 1), cov(r, 2), cov(r, 3)}));
  return {{"x", placement.x_m},
          {"y", placement.y_m},
          {"theta", placement.theta_rad},
          {"scale", placement.scale},
          {"cov", std::move(rows)}};
}

json georeference_json(const std::optional<apriori::Georeference>& georeference) {
  if (!georeference) return nullptr;
  return {{"latitude", georeference->latitude_deg},
          {"longitude", georeference->longitude_deg},
          {"heading", georeference->heading_deg}};
}

namespace {

json optional_text(const std::optional<std::string>& text) { return text ? json(*text) : json(nullptr); }

// The numbers a decision changed (see DecisionRecord::before), labelled.
json state_numbers_json(const std::vector<double>& v) {
  if (v.size() == 6) {
    return {{"rho", v[0]}, {"phi", v[1]}, {"cov", json::array({json::array({v[2], v[3]}), json::array({v[4], v[5]})})}};
  }
  if (v.size() == 4) return {{"p0", json::array({v[0], v[1]})}, {"p1", json::array({v[2], v[3]})}};  // a trim
  if (v.size() == 20) {  // a placement: x, y, θ, scale, C(4×4)
    Eigen::Matrix4d cov;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) cov(r, c) = v[static_cast<std::size_t>(4 + 4 * r + c)];
    return placement_json({v[0], v[1], v[2], v[3]}, cov);
  }
  if (v.size() == 12) {
    json cov = json::array();
    for (int r = 0; r < 3; ++r) cov.push_back(json::array({v[3 + 3 * r], v[4 + 3 * r], v[5 + 3 * r]}));
    return {{"pose", {{"x", v[0]}, {"y", v[1]}, {"theta", v[2]}}}, {"pose_cov", cov}};
  }
  return nullptr;
}

}  // namespace

json decision_json(const world::DecisionRecord& d) {
  json j = {{"seq", d.seq},
            {"observation", d.observation_seq},
            {"index", d.index},
            {"action", rules::wire_name(d.action)},
            {"rule", d.rule},
            {"explanation", d.explanation},
            {"element", optional_text(d.element)},
            {"object", optional_text(d.object)},
            {"matched", {{"element", optional_text(d.matched_element)}, {"object", optional_text(d.matched_object)}}},
            {"mahalanobis_sq", d.mahalanobis_sq ? json(*d.mahalanobis_sq) : json(nullptr)},
            {"fallback", d.fallback},
            {"observer", d.observer},
            {"source", d.observer},  // the name before "observer", kept for clients
            {"origin", d.origin},
            {"sensor", d.sensor},
            {"observed",
             {{"p0", point_json(d.p0)},
              {"p1", point_json(d.p1)},
              {"rho", d.rho_m},
              {"phi", d.phi_rad},
              {"cov", matrix_json(d.observed_cov)}}}};
  if (!d.before.empty()) j["before"] = state_numbers_json(d.before);
  if (!d.after.empty()) j["after"] = state_numbers_json(d.after);
  return j;
}

json decision_json(const rules::Decision& d) {
  return {{"action", d.action}, {"rule", d.rule}, {"explanation", d.explanation}, {"fallback", d.fallback}};
}

json rules_status_json(const rules::RulesStatus& status) {
  // Every rule file lies in the rules directory: what precedes its name ("/home/x/wm/rules/") is cut.
  std::string prefix;
  if (!status.files.empty()) {
    const auto parent = std::filesystem::path(status.files.front().path).parent_path().parent_path().string();
    if (!parent.empty()) prefix = parent.back() == '/' ? parent : parent + "/";
  }
  const auto relative = [&prefix](std::string text) {
    if (prefix.empty()) return text;
    for (auto at = text.find(prefix); at != std::string::npos; at = text.find(prefix, at))
      text.erase(at, prefix.size());
    return text;
  };
  json files = json::array();
  for (const auto& f : status.files)
    files.push_back(
        {{"path", relative(f.path)}, {"checksum", f.sha256_or_checksum}, {"loaded_at", f.loaded_at_unix_s}});
  return {{"files", files}, {"generation", status.generation}, {"last_error", relative(status.last_error)}};
}

namespace {

struct AnswerBudget {
  std::size_t max_bytes;
  std::size_t left;
};

// Builds one answer value, counting the bytes of its texts against what is left of the answer's budget.
json query_value_json(const rules::QueryValue& v, std::size_t depth, AnswerBudget& budget) {
  using Kind = rules::QueryValue::Kind;
  const auto spend = [&budget](std::size_t bytes) {
    if (bytes > budget.left)
      throw CodecError(CodecError::Kind::answer_too_large, "",
                       "the answer is larger than " + std::to_string(budget.max_bytes) +
                           " bytes; ask for fewer solutions (max_solutions) or smaller terms");
    budget.left -= bytes;
  };
  // What each value adds to the text, its comma included (escapes aside: the dumped size is checked again).
  switch (v.kind) {
    case Kind::unbound:
      spend(5);
      return nullptr;
    case Kind::atom:
    case Kind::string:
    case Kind::compound:
      spend(v.text.size() + 3);
      return v.text;
    case Kind::integer:
      spend(std::to_string(v.integer).size() + 1);
      return v.integer;
    case Kind::floating:
      spend(25);
      return std::isfinite(v.floating) ? json(v.floating) : json(nullptr);
    case Kind::list: {
      if (depth >= apriori::kMaxJsonDepth)
        throw CodecError(CodecError::Kind::answer_too_large, "",
                         "the answer nests lists deeper than " + std::to_string(apriori::kMaxJsonDepth) + " levels");
      spend(3);
      json items = json::array();
      for (const auto& item : v.items) items.push_back(query_value_json(item, depth + 1, budget));
      return items;
    }
  }
  return nullptr;
}

}  // namespace

json query_result_json(const rules::QueryResult& result, std::size_t max_bytes) {
  AnswerBudget budget{max_bytes, max_bytes};
  json solutions = json::array();
  for (const auto& row : result.solutions) {
    json solution = json::object();
    for (std::size_t i = 0; i < row.size() && i < result.variables.size(); ++i)
      solution[result.variables[i]] = query_value_json(row[i], 1, budget);
    solutions.push_back(std::move(solution));
  }
  return {{"variables", result.variables},
          {"solutions", solutions},
          {"count", result.solutions.size()},
          {"truncated", result.truncated}};
}

}  // namespace wm::json_codec
