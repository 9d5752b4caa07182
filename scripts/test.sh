#!/usr/bin/env bash
# Installs what is missing, builds everything with -Werror, proves fusion builds with Eigen alone, and runs
# every test (GoogleTest suites, plunit rule tests, end-to-end tests against the real wmd) through ctest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh web
jobs=$(nproc)

echo "== fusion alone (Eigen only)"
cmake -S . -B build/fusion-only -G Ninja -DWM_FUSION_ONLY=ON -DWM_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build/fusion-only -j"$jobs"

echo "== full build"
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWM_WERROR=ON >/dev/null
cmake --build build -j"$jobs"

echo "== tests"
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 600
