#include "server/foxglove/schemas.h"

#include <nlohmann/json.hpp>

namespace wm::foxglove::schemas {
namespace {

using json = nlohmann::json;

json object(const char* title, json properties) {
  return {{"title", title}, {"type", "object"}, {"properties", std::move(properties)}};
}
json number() { return {{"type", "number"}}; }
json text_type() { return {{"type", "string"}}; }
json boolean() { return {{"type", "boolean"}}; }
json non_negative_integer() { return {{"type", "integer"}, {"minimum", 0}}; }
json integer_enum(int max, const char* meaning) {
  return {{"type", "integer"}, {"minimum", 0}, {"maximum", max}, {"description", meaning}};
}
json array_of(json items) { return {{"type", "array"}, {"items", std::move(items)}}; }

json stamp() {
  return object("time", {{"sec", non_negative_integer()},
                         {"nsec", {{"type", "integer"}, {"minimum", 0}, {"maximum", 999999999}}}});
}
json duration() {
  return object("duration", {{"sec", {{"type", "integer"}}},
                             {"nsec", {{"type", "integer"}, {"minimum", 0}, {"maximum", 999999999}}}});
}
json vector2() { return object("foxglove.Vector2", {{"x", number()}, {"y", number()}}); }
json vector3() { return object("foxglove.Vector3", {{"x", number()}, {"y", number()}, {"z", number()}}); }
json point3() { return object("foxglove.Point3", {{"x", number()}, {"y", number()}, {"z", number()}}); }
json quaternion() {
  return object("foxglove.Quaternion", {{"x", number()}, {"y", number()}, {"z", number()}, {"w", number()}});
}
json pose() { return object("foxglove.Pose", {{"position", vector3()}, {"orientation", quaternion()}}); }
json color() { return object("foxglove.Color", {{"r", number()}, {"g", number()}, {"b", number()}, {"a", number()}}); }

json line_primitive() {
  return object("foxglove.LinePrimitive", {{"type", integer_enum(2, "0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST")},
                                           {"pose", pose()},
                                           {"thickness", number()},
                                           {"scale_invariant", boolean()},
                                           {"points", array_of(point3())},
                                           {"color", color()},
                                           {"colors", array_of(color())},
                                           {"indices", array_of(non_negative_integer())}});
}

std::string text(const char* title, const char* description, json properties) {
  auto schema = object(title, std::move(properties));
  schema["description"] = description;
  return schema.dump();
}

}  // namespace

std::string grid() {
  const auto field = object("foxglove.PackedElementField", {{"name", text_type()},
                                                            {"offset", non_negative_integer()},
                                                            {"type", integer_enum(8, "numeric type; 7 FLOAT32")}});
  return text("foxglove.Grid", "A 2D grid of data",
              {{"timestamp", stamp()},
               {"frame_id", text_type()},
               {"pose", pose()},
               {"column_count", non_negative_integer()},
               {"cell_size", vector2()},
               {"row_stride", non_negative_integer()},
               {"cell_stride", non_negative_integer()},
               {"fields", array_of(field)},
               {"data", {{"type", "string"}, {"contentEncoding", "base64"}}}});
}

std::string scene_update() {
  const auto deletion =
      object("foxglove.SceneEntityDeletion",
             {{"timestamp", stamp()}, {"type", integer_enum(1, "0 MATCHING_ID, 1 ALL")}, {"id", text_type()}});
  const auto key_value = object("foxglove.KeyValuePair", {{"key", text_type()}, {"value", text_type()}});
  const auto entity = object("foxglove.SceneEntity", {{"timestamp", stamp()},
                                                      {"frame_id", text_type()},
                                                      {"id", text_type()},
                                                      {"lifetime", duration()},
                                                      {"frame_locked", boolean()},
                                                      {"metadata", array_of(key_value)},
                                                      {"lines", array_of(line_primitive())}});
  return text("foxglove.SceneUpdate", "An update to the entities displayed in a 3D scene",
              {{"deletions", array_of(deletion)}, {"entities", array_of(entity)}});
}

std::string pose_in_frame() {
  return text("foxglove.PoseInFrame", "A timestamped pose in a named frame",
              {{"timestamp", stamp()}, {"frame_id", text_type()}, {"pose", pose()}});
}

std::string frame_transforms() {
  const auto transform = object("foxglove.FrameTransform", {{"timestamp", stamp()},
                                                            {"parent_frame_id", text_type()},
                                                            {"child_frame_id", text_type()},
                                                            {"translation", vector3()},
                                                            {"rotation", quaternion()}});
  return text("foxglove.FrameTransforms", "An array of FrameTransform messages", {{"transforms", array_of(transform)}});
}

std::string log() {
  return text("foxglove.Log", "A log message",
              {{"timestamp", stamp()},
               {"level", integer_enum(5, "0 UNKNOWN, 1 DEBUG, 2 INFO, 3 WARNING, 4 ERROR, 5 FATAL")},
               {"message", text_type()},
               {"name", text_type()},
               {"file", text_type()},
               {"line", non_negative_integer()}});
}

}  // namespace wm::foxglove::schemas
