// DXF floor plans (PUT /api/v1/floorplan with Content-Type image/vnd.dxf): the reader, then the import with the
// built-in layer mapping and the server's default options. Expected: a plan or a FloorPlanError. An accepted
// plan must survive its canonical JSON round trip.
#include <cstddef>
#include <cstdint>

#include "apriori/dxf/dxf_reader.h"
#include "apriori/floor_plan.h"
#include "apriori/import/dxf_import.h"
#include "apriori/import/layer_mapping.h"
#include "fuzz/fuzz_support.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace wm;
  static const auto mapping = apriori::default_layer_mapping();
  const auto text = fuzz::as_text(data, size);
  try {
    apriori::dxf::read_dxf(text);
  } catch (const apriori::FloorPlanError&) {
  }
  try {
    fuzz::check_round_trip(apriori::import_dxf(text, mapping).plan);
  } catch (const apriori::FloorPlanError&) {
  }
  return 0;
}
