// PUT /api/v1/floorplan JSON bodies: the JSON floor plan, an AMRL vector map (a bare array of lines) and a layer
// mapping (the "mapping" of an import envelope), each parsed from the same input. Expected: a plan or a
// FloorPlanError. Every accepted plan must survive its canonical JSON round trip (what the store relies on).
#include <cstddef>
#include <cstdint>
#include <string>

#include "apriori/floor_plan.h"
#include "apriori/import/amrl_import.h"
#include "apriori/import/layer_mapping.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  const auto text = fuzz::as_text(data, size);
  try {
    fuzz::check_round_trip(apriori::parse_floor_plan_json(text));
  } catch (const apriori::FloorPlanError&) {
  }
  try {
    fuzz::check_round_trip(apriori::import_amrl_vectormap(text).plan);
  } catch (const apriori::FloorPlanError&) {
  }
  try {
    apriori::parse_layer_mapping_json(text);
  } catch (const apriori::FloorPlanError&) {
  }
  return 0;
}
