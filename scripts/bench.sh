#!/usr/bin/env bash
# Installs the baselines (OctoMap, OpenCV), builds the benchmarks in Release and runs them. Each prints its
# table and the ratios against its named baseline, measured side by side in the same run.
# WM_BENCH_BUILD_DIR=DIR builds them in an already configured build directory instead (CI: the test build, so only
# the benchmarks compile; its figures are then those of that build's flags, not Release's).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh bench
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
dir=${WM_BENCH_BUILD_DIR:-build-bench}
if [ -n "${WM_BENCH_BUILD_DIR:-}" ]; then
  cmake -S . -B "$dir" -DWM_BUILD_BENCH=ON >/dev/null
else
  cmake -S . -B "$dir" -G Ninja -DCMAKE_BUILD_TYPE=Release -DWM_BUILD_BENCH=ON -DWM_BUILD_TESTS=OFF \
    "${launcher[@]}" >/dev/null
fi
# The benchmarks and what they start only: the tools and clients are not measured here.
cmake --build "$dir" -j"$(nproc)" --target benchmarks
for bench in "$dir"/bin/*_bench; do
  echo "== $bench"
  "$bench" "$@"
done
