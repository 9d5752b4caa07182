# Sourced by scripts/test.sh and scripts/fuzz.sh: the sanitizer run-time options for ASan/UBSan binaries, exported
# so that processes the tests spawn (wmd, wmctl) get them too.
#  - use_sigaltstack=0: SWI-Prolog handles its own signals and stack overflows; ASan's alternate signal stack
#    gets in its way.
#  - detect_stack_use_after_return=0: the fake stacks it needs confuse SWI-Prolog's C-stack checks.
#  - LeakSanitizer: SWI-Prolog's runtime is never torn down, its allocations are suppressed by name
#    (tests/sanitizer/lsan.supp); every other leak fails the run.
#  - UBSan: stop at the first report with a stack, so a finding fails the test that triggered it.
_wm_supp_dir="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
export ASAN_OPTIONS="use_sigaltstack=0:detect_leaks=1:detect_stack_use_after_return=0:abort_on_error=0:strict_string_checks=1:check_initialization_order=1"
export LSAN_OPTIONS="suppressions=$_wm_supp_dir/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$_wm_supp_dir/ubsan.supp"
unset _wm_supp_dir
