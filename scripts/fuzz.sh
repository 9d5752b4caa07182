#!/usr/bin/env bash
# Builds the libFuzzer harnesses (fuzz/, clang with ASan + UBSan) and runs each for a bounded time:
#   bash scripts/fuzz.sh [SECONDS [HARNESS...]]      default 60 s each, every harness, nproc at a time
#   WM_FUZZ_RUNS=1000000 bash scripts/fuzz.sh 0      a number of executions each instead (0 s: no time bound)
# Each harness first re-runs its reproducers (fuzz/regressions/<harness>/), then fuzzes from the committed seeds
# (fuzz/corpus/<harness>/) plus a working corpus kept in the build directory, so longer local runs build on
# earlier ones. Exits 1 when any harness crashes, leaks, times out or trips a sanitizer; the reproducer is saved
# as <build>/fuzz-artifacts/<harness>/crash-* (minimise it with -minimize_crash=1 and commit it under
# fuzz/regressions/<harness>/). Prints executions and coverage per harness.
# Environment: WM_SANITIZE_BUILD_DIR (default build/sanitize, shared with the sanitizer suite of scripts/test.sh),
# WM_FUZZ_JOBS (build parallelism, default nproc), WM_FUZZ_PARALLEL (harnesses run at once, default nproc),
# WM_FUZZ_NO_BUILD=1 (use the binaries as they are),
# WM_FUZZ_FORK=N (libFuzzer's -fork=N: N worker processes share one corpus; -runs counts all of them).
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
# Every harness (scripts/test.sh builds this list: `bash scripts/fuzz.sh --list`).
all=(fuzz_floor_plan_json fuzz_primitives fuzz_scan fuzz_scan_cbor fuzz_scan_record fuzz_scan_alignment fuzz_dxf fuzz_rmf fuzz_carmen fuzz_servosila fuzz_robot_commands fuzz_sonar_gate fuzz_foxglove fuzz_query fuzz_rules_text fuzz_map_routes)
if [ "${1:-}" = --list ]; then
  echo "${all[@]}"
  exit 0
fi
seconds=${1:-60}
shift || true
harnesses=("$@")
[ ${#harnesses[@]} -eq 0 ] && harnesses=("${all[@]}")
build=${WM_SANITIZE_BUILD_DIR:-build/sanitize}
jobs=${WM_FUZZ_JOBS:-$(nproc)}
source tests/sanitizer/env.sh

command -v clang++ >/dev/null || { echo "fuzz: clang++ is missing (apt-get install clang)" >&2; exit 2; }
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
if [ ! -f "$build/CMakeCache.txt" ] && [ "${WM_FUZZ_NO_BUILD:-0}" != 1 ]; then
  # -Werror stays with the gcc build of scripts/test.sh; clang warns about other things.
  cmake -S . -B "$build" -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWM_SANITIZE=ON \
    -DWM_FUZZ=ON -DWM_WERROR=OFF "${launcher[@]}" >/dev/null
fi
[ "${WM_FUZZ_NO_BUILD:-0}" = 1 ] || cmake --build "$build" -j"$jobs" --target "${harnesses[@]}"

# Input size bound, dictionary and timeout per harness: texts a little bigger than the largest seed.
options_for() {
  case "$1" in
    fuzz_floor_plan_json) echo "-max_len=4096 -dict=fuzz/dict/json.dict" ;;
    fuzz_primitives | fuzz_scan) echo "-max_len=4096 -dict=fuzz/dict/json.dict" ;;
    fuzz_dxf) echo "-max_len=4096 -dict=fuzz/dict/dxf.dict" ;;
    fuzz_rmf) echo "-max_len=4096 -dict=fuzz/dict/yaml.dict" ;;
    fuzz_carmen) echo "-max_len=8192 -dict=fuzz/dict/carmen.dict" ;;
    fuzz_servosila) echo "-max_len=512" ;;  # datagrams of 57 and 275 bytes, and anything else
    fuzz_robot_commands) echo "-max_len=1024 -dict=fuzz/dict/json.dict" ;;  # "v w", {"v","w"}, a pose report
    fuzz_sonar_gate) echo "-max_len=600" ;;  # 7 doubles, then 16 bytes per reading: up to 32 readings
    fuzz_scan_record) echo "-max_len=4096" ;;  # records of 161 bytes and more (8 per reading)
    fuzz_scan_cbor) echo "-max_len=8192" ;;  # CBOR scan bodies and batches: a 1 081-beam float32 body is 4.5 kB
    fuzz_scan_alignment) echo "-max_len=8192" ;;  # 9 doubles, then 56 bytes per line: up to 144 lines
    fuzz_foxglove) echo "-max_len=1024 -dict=fuzz/dict/json.dict" ;;  # a client's subscribe/unsubscribe texts
    # SWI-Prolog interrupts a goal at its time limit with SIGUSR2, which libFuzzer would take as "stop". Its
    # handler allocates, so a signal that lands while libFuzzer's per-input leak check has stopped the world
    # deadlocks the worker (seen after 11 min of fork mode): leaks are left to the sanitizer suite here.
    fuzz_query) echo "-max_len=512 -dict=fuzz/dict/prolog.dict -handle_usr1=0 -handle_usr2=0 -detect_leaks=0" ;;
    fuzz_map_routes) echo "-max_len=512 -dict=fuzz/dict/routes.dict -handle_usr1=0 -handle_usr2=0 -detect_leaks=0" ;;
    fuzz_rules_text) echo "-max_len=8192 -dict=fuzz/dict/prolog.dict -handle_usr1=0 -handle_usr2=0 -detect_leaks=0" ;;
    *) echo "fuzz: unknown harness $1 (${all[*]})" >&2; exit 2 ;;
  esac
}

# One harness: its reproducers, then fuzzing; its table row goes to <log>.row, its result to <log>.result.
run_harness() {
  local h=$1 opts bin work artifacts log result execs rate cov ft
  opts=$(options_for "$h")
  bin="$build/bin/$h"
  work="$build/fuzz-corpus/$h"
  artifacts="$build/fuzz-artifacts/$h"
  log="$build/fuzz-logs/$h.log"
  mkdir -p "$work" "$artifacts" "$(dirname "$log")"
  result=ok
  shopt -s nullglob
  local reproducers=(fuzz/regressions/"$h"/*)
  shopt -u nullglob
  if [ ${#reproducers[@]} -gt 0 ] && ! "$bin" $opts "${reproducers[@]}" >"$log.regressions" 2>&1; then
    result="REGRESSION (see $log.regressions)"
  fi
  # -timeout: one input taking longer is a finding (the server would hang on it too).
  # shellcheck disable=SC2086
  if ! "$bin" $opts -max_total_time="$seconds" ${WM_FUZZ_RUNS:+-runs=$WM_FUZZ_RUNS} ${WM_FUZZ_FORK:+-fork=$WM_FUZZ_FORK} -timeout=25 -rss_limit_mb=2560 -print_final_stats=1 \
      -artifact_prefix="$artifacts/" "$work" "fuzz/corpus/$h" >"$log" 2>&1; then
    if [ "$result" = ok ]; then result="CRASH (see $log)"; else result="$result, CRASH (see $log)"; fi
  fi
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  # Fork mode prints no stat:: lines; its parent reports the total over all workers instead.
  [ -n "$execs" ] || execs=$(sed -n 's/^INFO: fuzzed for \([0-9]*\) iterations.*/\1/p' "$log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  ft=$(grep -o 'ft: [0-9]*' "$log" | tail -1 | cut -d' ' -f2)
  printf '%-22s %12s %8s %8s %8s  %s\n' "$h" "${execs:-?}" "${rate:-?}" "${cov:-?}" "${ft:-?}" "$result" >"$log.row"
  echo "$result" >"$log.result"
}

# WM_FUZZ_PARALLEL harnesses at a time (default nproc; each is one process unless WM_FUZZ_FORK is set), so every
# harness gets its whole time on a core of its own.
parallel=${WM_FUZZ_PARALLEL:-$(nproc)}
[ -n "${WM_FUZZ_FORK:-}" ] && parallel=1
for h in "${harnesses[@]}"; do
  options_for "$h" >/dev/null  # an unknown harness stops the run here
  rm -f "$build/fuzz-logs/$h.log.row" "$build/fuzz-logs/$h.log.result"
done
[ ${#harnesses[@]} -lt "$parallel" ] && parallel=${#harnesses[@]}
if [ "$parallel" -le 1 ]; then
  for h in "${harnesses[@]}"; do run_harness "$h"; done  # in the foreground: Ctrl-C reaches the fuzzer
else
  # Background jobs of a script ignore SIGINT: stop the whole process group (the fuzzers too) when it is stopped.
  trap 'trap - INT TERM; kill 0' INT TERM
  running=0
  for h in "${harnesses[@]}"; do
    if [ "$running" -ge "$parallel" ]; then
      wait -n || true
      running=$((running - 1))
    fi
    run_harness "$h" &
    running=$((running + 1))
  done
  wait || true
  trap - INT TERM
fi

failed=()
printf '%-22s %12s %8s %8s %8s  %s\n' harness executions exec/s cov ft result
for h in "${harnesses[@]}"; do
  log="$build/fuzz-logs/$h.log"
  cat "$log.row" 2>/dev/null || printf '%-22s %12s %8s %8s %8s  %s\n' "$h" ? ? ? ? "NO RESULT"
  result=$(cat "$log.result" 2>/dev/null || echo "NO RESULT")
  if [ "$result" != ok ]; then
    failed+=("$h")
    for f in "$log.regressions" "$log"; do
      [ -f "$f" ] && grep -av '^#[0-9]' "$f" | tail -n 60 >&2
    done
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]}; reproducers under $root/$build/fuzz-artifacts/" >&2
  exit 1
fi
