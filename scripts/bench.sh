#!/usr/bin/env bash
# Installs the baselines (OctoMap, OpenCV), builds the benchmarks in Release and runs them. Each prints its
# table and the ratios against its named baseline, measured side by side in the same run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh bench
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B build-bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DWM_BUILD_BENCH=ON -DWM_BUILD_TESTS=OFF \
  "${launcher[@]}" >/dev/null
# The benchmarks and what they start only: the tools and clients are not measured here.
cmake --build build-bench -j"$(nproc)" --target benchmarks
for bench in build-bench/bin/*_bench; do
  echo "== $bench"
  "$bench" "$@"
done
