#pragma once

// JSON Schemas of the Foxglove message types this server sends, as the advertise message carries them. Foxglove's
// panels recognise a channel by its schema name (foxglove.Grid, ...); the schema text tells a JSON client the fields
// and which strings are base64 (Grid.data), which it turns back into bytes. Each describes the fields of the
// Foxglove type (https://github.com/foxglove/schemas) with the same names and JSON types; the end-to-end test checks
// them, and every message, against the published schemas (@foxglove/schemas).
#include <string>

namespace wm::foxglove::schemas {

std::string grid();              // foxglove.Grid
std::string scene_update();      // foxglove.SceneUpdate (entities of line primitives)
std::string pose_in_frame();     // foxglove.PoseInFrame
std::string frame_transforms();  // foxglove.FrameTransforms
std::string log();               // foxglove.Log

}  // namespace wm::foxglove::schemas
