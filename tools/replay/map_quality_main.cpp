// wm-map-quality LOG...: replays each log into a fresh in-process world service (the shipped rules, default
// settings) and prints one row of map-quality figures per log — the table in the README's "Map quality" section.
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "apriori/import/amrl_import.h"
#include "common/parse_number.h"
#include "tools/replay/log_replay.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: wm-map-quality [--every K] [--rules DIR] [--pose-sigma XY,THETA] [--plan FILE] "
                 "[--grid-trim-every N] [--no-scan-alignment] [--no-line-continuation] LOG...\n"
                 "  --plan: a floor plan (JSON, or an AMRL *.vectormap.json) loaded before each replay\n"
                 "  --grid-trim-every: as wmd's (default 10; 0: elements are not trimmed to the grid)\n"
                 "  --no-scan-alignment: as wmd's (scans keep their posted poses)\n"
                 "  --no-line-continuation: no views of elements past their ends from sparse grazing returns\n");
    return 2;
  }
  wm::replay::LogReplayOptions options;
  options.rules_dir = WM_DEFAULT_RULES_DIR;
  std::printf("%-28s %6s %7s %9s %8s %9s %7s %6s %8s %11s %7s\n", "log", "scans", "scans/s", "elements", "metres",
              "median_m", "per_m", "prec", "recall", "redundancy", "calib");
  int status = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if ((arg == "--every" || arg == "--grid-trim-every") && i + 1 < argc) {
      try {
        (arg == "--every" ? options.every : options.service.ingest.grid_trim_every) =
            wm::parse_number<std::size_t>(arg, argv[++i], arg == "--every" ? 1 : 0, 1'000'000);
      } catch (const std::invalid_argument& e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 2;
      }
      continue;
    }
    if (arg == "--no-scan-alignment") {
      options.service.ingest.align_scans = false;
      continue;
    }
    if (arg == "--no-line-continuation") {
      options.service.ingest.continue_lines = false;
      continue;
    }
    if (arg == "--pose-sigma" && i + 1 < argc) {
      if (std::sscanf(argv[++i], "%lf,%lf", &options.sigma_xy_m, &options.sigma_theta_rad) != 2) {
        std::fprintf(stderr, "--pose-sigma: expected XY,THETA (m, rad)\n");
        return 2;
      }
      continue;
    }
    if (arg == "--plan" && i + 1 < argc) {
      const std::string path = argv[++i];
      try {
        std::ifstream in(path, std::ios::binary);
        if (!in) throw std::runtime_error("cannot open");
        const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
        options.plan = path.ends_with(".vectormap.json") ? wm::apriori::import_amrl_vectormap(text).plan
                                                         : wm::apriori::parse_floor_plan_json(text);
      } catch (const std::exception& e) {
        std::fprintf(stderr, "--plan %s: %s\n", path.c_str(), e.what());
        return 2;
      }
      std::size_t edges = 0;
      for (const auto& object : options.plan->objects) edges += object.edges().size();
      std::fprintf(stderr, "plan %s: %zu objects, %zu edges\n", path.c_str(), options.plan->objects.size(), edges);
      continue;
    }
    if (arg == "--rules" && i + 1 < argc) {
      options.rules_dir = argv[++i];
      continue;
    }
    const std::filesystem::path log = arg;
    try {
      const auto work = std::filesystem::temp_directory_path() /
                        ("wm-map-quality-" + std::to_string(::getpid()) + "-" + std::to_string(i));
      std::filesystem::create_directories(work);
      options.work_dir = work;
      const auto r = wm::replay::replay_log(log, options);
      std::filesystem::remove_all(work);
      const auto& q = r.quality.map;
      std::printf("%-28s %6zu %7.1f %9zu %8.1f %9.3f %7.3f %6.3f %8.3f %11.3f %7s\n",
                  log.stem().stem().string().c_str(), r.scans, r.scans / r.seconds, q.elements, q.total_length_m,
                  q.median_length_m, q.elements_per_m, q.precision, q.recall, q.redundancy,
                  r.quality.calibration ? std::to_string(*r.quality.calibration).substr(0, 5).c_str() : "-");
      std::fflush(stdout);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "%s: %s\n", log.c_str(), e.what());
      status = 1;
    }
  }
  return status;
}
