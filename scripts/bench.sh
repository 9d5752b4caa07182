#!/usr/bin/env bash
# Installs the baselines (OctoMap, OpenCV), builds the benchmarks in Release and runs them. Each prints its
# table and the ratios against its named baseline, measured side by side in the same run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh bench
cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DWM_BUILD_BENCH=ON -DWM_BUILD_TESTS=OFF >/dev/null
cmake --build build-bench -j"$(nproc)"
for bench in build-bench/bin/*_bench; do
  echo "== $bench"
  "$bench" "$@"
done
