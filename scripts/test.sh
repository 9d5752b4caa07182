#!/usr/bin/env bash
# Installs what is missing (ROS 1 included, for the bridge's tests), checks that every C++ file is clang-formatted (scripts/check_format.sh), builds
# everything with -Werror, proves fusion builds with Eigen alone, and runs every test (GoogleTest suites, plunit
# rule tests, end-to-end tests against the real wmd) through ctest.
# Then, in a second build directory (clang, -DWM_SANITIZE=ON -DWM_FUZZ=ON), runs the suite under
# AddressSanitizer + UndefinedBehaviorSanitizer (tests/sanitizer/: run-time options and suppressions) and each
# libFuzzer harness for WM_FUZZ_SECONDS (default 30). Any sanitizer report, leak outside SWI-Prolog or fuzzer
# crash fails the run. Times each phase.
# The sanitizer run covers the parsers, rules, storage, server and wmd end to end (apriori, logs, rules, server
# and integration tests); it leaves out, to stay within CI's time, fusion_tests (pure maths, a quarter of the
# compile time; fusion runs under ASan inside wmd in the integration tests), crash_trial_tests (kill -9 trials)
# and the browser tests (JavaScript).
# WM_SANITIZE_TESTS=0 skips the sanitizer build, its tests and the fuzzers.
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=$(nproc)
sanitize=${WM_SANITIZE_TESTS:-1}
# The sanitizer build needs clang with its sanitizer and libFuzzer run-times, and llvm-symbolizer.
extras=(web ros)
[ "$sanitize" != 0 ] && extras+=(sanitize)
bash scripts/setup.sh "${extras[@]}"
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)

timings=()
phase_name=
phase() {
  finish_phase
  phase_name=$1
  phase_start=$SECONDS
  echo "== $phase_name"
}
finish_phase() {
  if [ -n "$phase_name" ]; then
    timings+=("$(printf '%-28s %5d s' "$phase_name" $((SECONDS - phase_start)))")
    phase_name=
  fi
}
report() {
  finish_phase
  echo "== phase times"
  printf '%s\n' "${timings[@]}"
}
trap report EXIT

phase "format (clang-format)"
bash scripts/check_format.sh

phase "fusion alone (Eigen only)"
cmake -S . -B build/fusion-only -G Ninja -DWM_FUSION_ONLY=ON -DWM_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" >/dev/null
cmake --build build/fusion-only -j"$jobs"

phase "full build"
# WM_BUILD_ROS=ON: the ROS bridge's tests run (setup.sh ros installed ROS 1), or say "skipped" when ROS is missing.
# -g1 (line tables and functions, no variables): a failing test's backtrace names the line, and the build takes
# about a quarter less time than with -g. A developer who wants variables in gdb reconfigures build/ with -g.
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" \
  -DWM_WERROR=ON -DWM_BUILD_ROS=ON "${launcher[@]}" >/dev/null
cmake --build build -j"$jobs"

phase "tests"
ctest --test-dir build --output-on-failure -j"$jobs" --timeout 600

[ "$sanitize" = 0 ] && exit 0

# The sanitizer options are exported for the build too: gtest_discover_tests runs the test binaries.
source tests/sanitizer/env.sh
phase "sanitizer build (clang)"
# -g1 (line tables only) as in the full build: a sanitizer report's stack names file and line, and the build, the
# longest phase, takes about a fifth less time than with -g.
cmake -S . -B build/sanitize -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O2 -g1 -DNDEBUG" -DWM_SANITIZE=ON -DWM_FUZZ=ON -DWM_WERROR=OFF "${launcher[@]}" >/dev/null
# The harnesses are the ones scripts/fuzz.sh runs (one list, there).
read -r -a harnesses <<< "$(bash scripts/fuzz.sh --list)"
cmake --build build/sanitize -j"$jobs" --target wmd wmctl apriori_tests logs_tests rules_tests server_tests integration_tests \
  "${harnesses[@]}"

phase "sanitizer tests"
# Test binaries that were not built register as <name>_NOT_BUILT. Also left out: the accept back-off test, which
# runs wmd out of file descriptors, and then UBSan's vptr check cannot open the pipe it probes memory with and
# reports every virtual call as an invalid vptr; the Freiburg replay (the Intel replay runs the same path on a
# smaller log), which takes over its 120 s limit under ASan.
ctest --test-dir build/sanitize --output-on-failure -j"$jobs" --timeout 900 \
  -E '^web_|_NOT_BUILT$|^SecurityHttpTest[.]AcceptBacksOffWhenFileDescriptorsRunOut$|^ReplayTest[.]Freiburg079'

phase "fuzzers"
WM_SANITIZE_BUILD_DIR=build/sanitize WM_FUZZ_NO_BUILD=1 bash scripts/fuzz.sh "${WM_FUZZ_SECONDS:-30}"
