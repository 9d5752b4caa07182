// wm-truth: the truth benchmark. A simulated robot drives through real plans as built (walls demolished, partitions
// added, the table moved, people walking), its scans are replayed in-process without and with the plan, and both
// maps are scored against the walls as built; one table row per building and pose noise, the worst last.
#include <cstdio>
#include <exception>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/parse_number.h"
#include "tools/truth/sonar.h"
#include "tools/truth/truth.h"

namespace {

// A count on the command line: digits only, at most 999 999 999.
std::size_t parse_count(const std::string& flag, const std::string& value) {
  return wm::parse_number<std::size_t>(flag, value, 0, 999'999'999);
}

const char* kUsage =
    "usage: wm-truth [--building gdc1|ahg2|rmf-office|barcelona|all] [--pose-noise low|high|both] [--seed N]\n"
    "                [--max-route M] [--step M] [--fov 360|270] [--demolished N] [--partitions N] [--people N]\n"
    "                [--table DX,DY,DTHETA_DEG|removed] [--no-plan] [--no-scan-alignment]\n"
    "                [--no-line-continuation] [--data DIR] [--rules DIR] [--grid-extract-every N] [--sonar]\n"
    "  --max-route          drive only the first M metres of each route (default: all)\n"
    "  --no-plan            only the mapping figures (one replay per row instead of two)\n"
    "  --no-scan-alignment  the server keeps each scan's posted pose (wmd --no-scan-alignment), for comparison\n"
    "  --no-line-continuation  no views of elements past their ends from sparse returns, for comparison\n"
    "  --sonar              a sonar ring beside the laser: the fused grid's walls with and without judging sonar\n"
    "                       by the laser, against laser-only (no store, no rules; --seed, --max-route, --data)\n"
    "  --grid-extract-every run the grid line extractor every N scans (wmd --grid-extract-every; default 0: never)\n";

}  // namespace

int main(int argc, char** argv) {
  using namespace wm::truth;
  TruthOptions options;
  options.data_dir = WM_DEFAULT_DATA_DIR;
  options.rules_dir = WM_DEFAULT_RULES_DIR;
  std::vector<std::string> buildings{"gdc1"};
  std::vector<PoseNoise> noises{PoseNoise::low};
  bool sonar = false;
  try {
    for (int i = 1; i < argc; ++i) {
      const std::string flag = argv[i];
      if (flag == "--no-plan") {
        options.with_plan = false;
        continue;
      }
      if (flag == "--no-scan-alignment") {
        options.service.ingest.align_scans = false;
        continue;
      }
      if (flag == "--sonar") {
        sonar = true;
        continue;
      }
      if (flag == "--no-line-continuation") {
        options.service.ingest.continue_lines = false;
        continue;
      }
      if (i + 1 >= argc) throw std::invalid_argument(flag + " needs a value");
      const std::string value = argv[++i];
      if (flag == "--building") {
        buildings = value == "all" ? building_names() : std::vector<std::string>{value};
      } else if (flag == "--pose-noise") {
        if (value == "low")
          noises = {PoseNoise::low};
        else if (value == "high")
          noises = {PoseNoise::high};
        else if (value == "both")
          noises = {PoseNoise::low, PoseNoise::high};
        else
          throw std::invalid_argument("--pose-noise: low, high or both");
      } else if (flag == "--seed") {
        options.seed = static_cast<unsigned>(parse_count(flag, value));
      } else if (flag == "--max-route") {
        options.max_route_m = wm::parse_number<double>(flag, value, 0, 1e6);
      } else if (flag == "--grid-extract-every") {
        options.service.ingest.grid_extract_every = parse_count(flag, value);
      } else if (flag == "--step") {
        options.laser.step_m = wm::parse_number<double>(flag, value, 0.01, 100);
      } else if (flag == "--fov") {
        options.laser.field_of_view_deg = wm::parse_number<double>(flag, value, 1, 360);
      } else if (flag == "--demolished") {
        options.edits.demolished = parse_count(flag, value);
      } else if (flag == "--partitions") {
        options.edits.partitions = parse_count(flag, value);
      } else if (flag == "--people") {
        options.edits.people = parse_count(flag, value);
      } else if (flag == "--table") {
        if (value == "removed") {
          options.edits.table_removed = true;
        } else {
          double dx = 0, dy = 0, dtheta = 0;
          if (std::sscanf(value.c_str(), "%lf,%lf,%lf", &dx, &dy, &dtheta) != 3 || std::hypot(dx, dy) > 0.5 ||
              std::abs(dtheta) > 20)
            throw std::invalid_argument("--table: DX,DY,DTHETA_DEG within 0.5 m and 20°, or removed");
          options.edits.table_shift = {dx, dy, dtheta * std::numbers::pi / 180};
        }
      } else if (flag == "--data") {
        options.data_dir = value;
      } else if (flag == "--rules") {
        options.rules_dir = value;
      } else {
        throw std::invalid_argument("unknown flag " + flag);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "wm-truth: %s\n%s", e.what(), kUsage);
    return 2;
  }
  int status = 0;
  if (sonar) {
    std::vector<SonarFusionResult> rows;
    for (const auto& building : buildings) {
      try {
        rows.push_back(run_sonar_fusion(building, options.data_dir, options.seed, options.max_route_m));
      } catch (const std::exception& e) {
        std::fprintf(stderr, "wm-truth: %s: %s\n", building.c_str(), e.what());
        status = 1;
      }
    }
    std::fputs(format_sonar_table(rows).c_str(), stdout);
    return status;
  }
  std::vector<TruthResult> results;
  for (const auto& building : buildings)
    for (const auto noise : noises) {
      options.pose_noise = noise;
      try {
        results.push_back(run_truth(building, options));
        std::fprintf(stderr, "wm-truth: %s %s: %zu scans over %.0f m in %.1f s\n", building.c_str(),
                     pose_noise_name(noise), results.back().scans, results.back().route_m, results.back().seconds);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "wm-truth: %s %s: %s\n", building.c_str(), pose_noise_name(noise), e.what());
        status = 1;
      }
    }
  std::fputs(format_table(results).c_str(), stdout);
  return status;
}
