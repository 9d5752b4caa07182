#!/usr/bin/env bash
# Cluster trials beyond CI's 20: three wmd nodes on one PostgreSQL (started by the test), six maps, four robots per
# map posting scans through any node with request ids and retries; N times the owner of two maps is killed (kill -9)
# or, every tenth trial, paused (SIGSTOP) past its lease and resumed. Checks the takeover time (at most 5 s), that
# no acknowledged scan was lost or applied twice, that a resumed node committed nothing under its old leases, and
# that each map equals a single-node replay of its scans. Prints the takeover times, worst first.
#   bash scripts/cluster_trials.sh [N]     (default N = 50)
# BUILD_DIR picks the build directory (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
trials=${1:-50}
build=${BUILD_DIR:-build}
if [ ! -f "$build/build.ninja" ]; then
  bash scripts/setup.sh
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWM_WERROR=ON >/dev/null
fi
cmake --build "$build" --target wmd cluster_tests -j"$(nproc)"
export WM_CLUSTER_TRIALS=$trials
exec "$build/bin/cluster_tests"
