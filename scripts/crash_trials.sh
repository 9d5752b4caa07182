#!/usr/bin/env bash
# Crash trials beyond CI's 20: kill -9 wmd during concurrent ingest of scans and primitives N times, restarting
# it on the same database after each kill, and check that nothing acknowledged was lost, nothing applied twice
# or by half, the grid revision never went back and the file passes PRAGMA integrity_check.
#   bash scripts/crash_trials.sh [N] [SEED]     (default N = 200; SEED replays a run, printed by every run)
# BUILD_DIR picks the build directory (default build).
set -euo pipefail
cd "$(dirname "$0")/.."
trials=${1:-200}
build=${BUILD_DIR:-build}
if [ ! -f "$build/build.ninja" ]; then
  bash scripts/setup.sh
  cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWM_WERROR=ON >/dev/null
fi
cmake --build "$build" --target wmd crash_trial_tests -j"$(nproc)"
export WM_CRASH_TRIALS=$trials
if [ $# -ge 2 ]; then export WM_CRASH_SEED=$2; fi
exec "$build/bin/crash_trial_tests" --gtest_filter='CrashTrialTest.KillNine*'
