// Open-RMF building.yaml floor plans (PUT /api/v1/floorplan with Content-Type application/yaml), default
// options. Expected: a plan or a FloorPlanError (malformed YAML included). An accepted plan must survive its
// canonical JSON round trip.
#include <cstddef>
#include <cstdint>

#include "apriori/floor_plan.h"
#include "apriori/import/rmf_import.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  try {
    fuzz::check_round_trip(apriori::import_rmf_building(fuzz::as_text(data, size)).plan);
  } catch (const apriori::FloorPlanError&) {
  }
  return 0;
}
