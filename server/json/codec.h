#pragma once

#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "fusion/grid/scan.h"
#include "server/json/codec_error.h"
#include "server/world/scan_observation.h"
#include "server/world/update.h"

namespace wm::json_codec {

/// Parses a JSON request body: refuses nesting deeper than apriori::kMaxJsonDepth before nlohmann's
/// recursive DOM sees it, malformed JSON (including invalid UTF-8 in strings) and numbers that overflow a
/// double. Every JSON body the server reads goes through one of these two.
/// @throw CodecError (bad_request) saying what and where.
nlohmann::json parse_json(std::string_view text);
/// The same, keeping the order of object keys (layer mappings apply their rules in file order).
nlohmann::ordered_json parse_ordered_json(std::string_view text);

/// The byte offset of the first byte of `text` that is not part of well-formed UTF-8 (RFC 3629: no
/// overlong forms, no surrogates, nothing above U+10FFFF), or nullopt when all of it is. nlohmann refuses
/// such strings only when it writes them (type_error 316), so text that did not come through a JSON
/// parser (YAML, query parameters) is checked with this where it enters.
std::optional<std::size_t> invalid_utf8_offset(std::string_view text);

/// Limits on a posted primitives request; bigger or stranger input is refused with 400.
struct PrimitiveLimits {
  std::size_t max_segments = 10000;
  double max_abs_coordinate_m = 1.0e5;
  double min_length_m = 1.0e-3;
};

/// Who sent a request body: its "observer", or "source", the older name of the same field (still accepted); nullopt
/// when it has neither. @throw CodecError when it is not a non-empty string of at most 128 characters, or when both
/// are given and differ.
std::optional<std::string> observer_of(const nlohmann::json& doc);

/// Checks a pose covariance over (x, y, θ) a client sent as `field`. @throw CodecError (bad_request naming `field`)
/// unless it is symmetric, its variances are not negative and it is positive semi-definite.
void require_pose_covariance(const Eigen::Matrix3d& cov, const std::string& field);

/// Parses and validates POST /api/v1/primitives. @throw CodecError (bad_request) naming the bad field.
world::Observation parse_primitives(std::string_view body, const world::WorldOptions& options,
                                    const PrimitiveLimits& limits);

struct ScanLimits {
  std::size_t max_beams = 10000;
  double max_range_m = 1000.0;
  double max_abs_coordinate_m = 1.0e5;
  /// Scans in one batch body ({"scans": [...]}); the store commits at most 64 requests in one transaction by default.
  std::size_t max_batch_scans = 64;
};

/// How a request body is encoded: JSON text (application/json) or CBOR (application/cbor, RFC 8949).
enum class BodyFormat { json, cbor };

/// The RFC 8746 tag of a little-endian float32 typed array (a byte string of 4 bytes per number).
inline constexpr std::uint64_t kCborFloat32LeTag = 85;

/// Decodes a CBOR request body into the same document a JSON body gives, for one validation of both. A byte string
/// under a tag of 24 or more becomes a binary value with the tag as its subtype (tag 85: a float32 array); tags 6–20
/// are dropped (nlohmann's reader), other tags, an undefined value or trailing bytes are refused. Refuses nesting
/// deeper than apriori::kMaxJsonDepth, more than `max_values` values in all (a byte each in CBOR: the document would
/// take 16 bytes per value), text that is not UTF-8, and map keys that are not text.
/// @throw CodecError (bad_request) saying what and where.
nlohmann::json parse_cbor(std::string_view bytes, std::size_t max_values);

/// Parses and validates one scan of POST /api/v1/scans into the world model's scan. A range may be null (no reading);
/// out-of-range readings are kept and ignored per beam by the grid; a number must be finite (also a float32 of a
/// typed array: NaN and ±Inf are refused like any value that is not a finite number). `ranges` and a sonar's `angles`
/// are arrays of numbers or (from CBOR) float32 typed arrays. @throw CodecError (bad_request) naming the bad field.
world::ScanObservation parse_scan(std::string_view body, const ScanLimits& limits);
world::ScanObservation scan_from_document(const nlohmann::json& doc, const ScanLimits& limits);

/// A POST /api/v1/scans body: one scan object, or a batch {"scans": [scan, ...]} of 1 to limits.max_batch_scans.
struct ScanBody {
  std::vector<world::ScanObservation> scans;
  bool batch = false;
};
/// Decodes and validates a whole body before anything is applied: an error in a batch names its scan
/// ("scans[2].ranges[7]: ..."). @throw CodecError (bad_request).
ScanBody parse_scan_body(std::string_view body, BodyFormat format, const ScanLimits& limits);

nlohmann::json object_json(const world::ObjectState& object, const world::WorldOptions& options);
nlohmann::json element_json(const world::Element& element);
/// With an excerpt, only its objects and elements (the answer to ?bbox=).
/// {"x", "y", "theta", "scale", "cov": 4×4 over (x, y, θ, scale)}.
nlohmann::json placement_json(const fusion::Similarity2D& placement, const Eigen::Matrix4d& cov);
/// {"latitude", "longitude", "heading"} in degrees, or null.
nlohmann::json georeference_json(const std::optional<apriori::Georeference>& georeference);
nlohmann::json map_json(const world::WorldState& state, const world::WorldOptions& options,
                        const std::optional<world::MapExcerpt>& excerpt = std::nullopt);
nlohmann::json decision_json(const world::DecisionRecord& decision);
nlohmann::json decision_json(const rules::Decision& decision);
/// The rules' status with file paths relative to the rules directory's parent ("prolog/world_model.pl"),
/// also inside `last_error`: an unauthenticated reader learns nothing about the server's file system.
nlohmann::json rules_status_json(const rules::RulesStatus& status);
/// {"variables": [...], "solutions": [{"X": value, ...}], "count": n, "truncated": bool}; atoms and strings
/// as JSON strings, numbers as numbers, lists as arrays, other compound terms as their Prolog text.
/// @throw CodecError (answer_too_large) when the texts of the answer add up to more than
/// `max_bytes`, or lists nest deeper than apriori::kMaxJsonDepth (checked while building, so a huge answer
/// is refused before its JSON exists).
nlohmann::json query_result_json(const rules::QueryResult& result,
                                 std::size_t max_bytes = std::numeric_limits<std::size_t>::max());

}  // namespace wm::json_codec
