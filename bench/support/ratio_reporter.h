#pragma once

// A console reporter that, after the usual table, prints each benchmark's throughput as a ratio to a
// named baseline benchmark of the same run, so comparisons are side by side and never across runs.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace wm::bench {

class RatioReporter : public benchmark::ConsoleReporter {
 public:
  /// `baselines`: (title, baseline benchmark name); every benchmark is reported against each baseline.
  explicit RatioReporter(std::vector<std::pair<std::string, std::string>> baselines)
      : baselines_(std::move(baselines)) {}

  void ReportRuns(const std::vector<Run>& runs) override {
    for (const auto& run : runs) {
      if (run.run_type != Run::RT_Iteration || run.error_occurred) continue;
      const auto it = run.counters.find("items_per_second");
      if (it != run.counters.end()) rates_[run.benchmark_name()] = it->second.value;
    }
    ConsoleReporter::ReportRuns(runs);
  }

  /// items/s of a benchmark of this run, 0 when it did not run.
  double rate(const std::string& name) const {
    const auto it = rates_.find(name);
    return it == rates_.end() ? 0.0 : it->second;
  }

  void Finalize() override {
    ConsoleReporter::Finalize();
    for (const auto& [title, baseline] : baselines_) {
      const auto base = rates_.find(baseline);
      if (base == rates_.end() || base->second <= 0) continue;
      std::printf("\n%s (items/s relative to %s):\n", title.c_str(), baseline.c_str());
      // A baseline with an argument ("BM_X/400") is compared only with the benchmarks of the same argument.
      const auto slash = baseline.find('/');
      const std::string suffix = slash == std::string::npos ? "" : baseline.substr(slash);
      for (const auto& [name, rate] : rates_) {
        if (!suffix.empty() &&
            (name.size() < suffix.size() || name.compare(name.size() - suffix.size(), suffix.size(), suffix) != 0))
          continue;
        std::printf("  %-40s %10.3fx\n", name.c_str(), rate / base->second);
      }
    }
  }

 private:
  std::vector<std::pair<std::string, std::string>> baselines_;
  std::map<std::string, double> rates_;
};

/// main() for benches that report ratios.
inline int run_with_ratios(int argc, char** argv, std::vector<std::pair<std::string, std::string>> baselines) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  RatioReporter reporter(std::move(baselines));
  benchmark::RunSpecifiedBenchmarks(&reporter);
  benchmark::Shutdown();
  return 0;
}

}  // namespace wm::bench
