#!/usr/bin/env bash
# Runs one libFuzzer target of tests/fuzz for a while (docs/reliability.md, "Fuzzing and sanitizers").
#
#   scripts/fuzz.sh [--merge] TARGET SECONDS [LIBFUZZER_FLAG...]
#   scripts/fuzz.sh config 1800                # targets: config scene transforms checkpoint image
#   scripts/fuzz.sh --merge image 600          # also merge the new coverage into tests/fuzz/corpus/image
#
# Configures and builds the fuzz build (clang, ASan + UBSan + libFuzzer; $RELIT_FUZZ_BUILD_DIR, default
# build-fuzz/) when needed, then fuzzes TARGET for SECONDS seconds starting from its seed corpus,
# tests/fuzz/corpus/TARGET/. New inputs go to a scratch corpus in the build tree
# (build-fuzz/fuzz/TARGET/corpus), not into the repository unless --merge is given. Prints the executions per
# second and the coverage at the end. On a finding (crash, uncaught exception other than relit::Error,
# sanitizer report, hang over 10 s, over 2 GiB of memory) it prints the path of the input that caused it
# (in build-fuzz/fuzz/TARGET/findings/) and exits non-zero.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${RELIT_FUZZ_BUILD_DIR:-$root/build-fuzz}"
targets=(config scene transforms checkpoint image)

merge=0
if [ "${1:-}" = "--merge" ]; then
  merge=1
  shift
fi
if [ $# -lt 2 ] || ! [[ "$2" =~ ^[0-9]+$ ]]; then
  echo "usage: scripts/fuzz.sh [--merge] TARGET SECONDS [LIBFUZZER_FLAG...]  (targets: ${targets[*]})" >&2
  exit 2
fi
target="$1"
seconds="$2"
shift 2
if ! printf '%s\n' "${targets[@]}" | grep -qx "$target"; then
  echo "fuzz: unknown target '$target'; targets: ${targets[*]}" >&2
  exit 2
fi

mkdir -p "$build"
if [ ! -f "$build/CMakeCache.txt" ]; then
  generator=()
  command -v ninja >/dev/null && generator=(-G Ninja)
  echo "fuzz: configuring the fuzz build in $build (clang, ASan + UBSan + libFuzzer)"
  CC=clang CXX=clang++ cmake -S "$root" -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ -DRELIT_BUILD_FUZZERS=ON -DRELIT_BUILD_TESTS=OFF \
    -DRELIT_BUILD_APPS=OFF -DRELIT_BUILD_PYTHON=OFF -DRELIT_BUILD_BENCH=OFF >"$build/configure.log" 2>&1 ||
    { cat "$build/configure.log"; exit 1; }
fi
# One build at a time: several fuzz.sh runs may start together.
exec 9>"$build/.fuzz-build.lock"
flock 9
cmake --build "$build" --target "fuzz_$target" --parallel "$(nproc)"
flock -u 9

seeds="$root/tests/fuzz/corpus/$target"
work="$build/fuzz/$target"
mkdir -p "$work/corpus" "$work/findings" "$work/tmp"
log="$work/fuzz-$(date +%Y%m%d-%H%M%S).log"
# The targets load no OpenCL driver; leaks are findings (libFuzzer checks them per input), except the
# third-party ones of tests/sanitizers/lsan.supp. Matching those needs full allocation stacks (slow unwinding),
# so only the image target, whose OpenImageIO leaks one, pays for it.
asan="detect_leaks=1:allocator_may_return_null=0"
[ "$target" = image ] && asan="$asan:fast_unwind_on_malloc=0"
export ASAN_OPTIONS="${ASAN_OPTIONS:-$asan}"
export LSAN_OPTIONS="${LSAN_OPTIONS:-suppressions=$root/tests/sanitizers/lsan.supp:print_suppressions=0}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
export RELIT_LOG="${RELIT_LOG:-warning}"
export TMPDIR="$work/tmp"  # the targets' scratch files

echo "fuzz: $target for $seconds s; seeds $seeds, new inputs in $work/corpus, log $log"
start=$SECONDS
set +e
"$build/tests/fuzz/fuzz_$target" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 \
  -artifact_prefix="$work/findings/" "$@" "$work/corpus" "$seeds" </dev/null 2>&1 | tee "$log" |
  grep -E --line-buffered '(NEW|REDUCE|pulse|DONE|INITED|ERROR|SUMMARY|==ERROR|runtime error|Test unit written)'
rc=${PIPESTATUS[0]}
set -e
elapsed=$((SECONDS - start))

last=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
cov=$(sed -nE 's/.* cov: ([0-9]+).*/\1/p' <<<"$last")
ft=$(sed -nE 's/.* ft: ([0-9]+).*/\1/p' <<<"$last")
runs=$(sed -nE 's/^stat::number_of_executed_units: *([0-9]+)/\1/p' "$log" | tail -1)
eps=$(sed -nE 's/^stat::average_exec_per_sec: *([0-9]+)/\1/p' "$log" | tail -1)
rss=$(sed -nE 's/^stat::peak_rss_mb: *([0-9]+)/\1/p' "$log" | tail -1)
echo "fuzz: $target: ${runs:-?} runs in $elapsed s, ${eps:-?} exec/s, cov: ${cov:-?} ft: ${ft:-?}," \
  "peak RSS ${rss:-?} MB, scratch corpus $(find "$work/corpus" -type f | wc -l) inputs"

if [ "$rc" -ne 0 ]; then
  finding=$(sed -nE 's/.*Test unit written to (.*)$/\1/p' "$log" | tail -1)
  echo "fuzz: FINDING in $target (libFuzzer exit status $rc): ${finding:-see $log}" >&2
  echo "fuzz: reproduce with $build/tests/fuzz/fuzz_$target ${finding:-INPUT}; minimise with -minimize_crash=1" \
    "-runs=10000; once fixed, add it to $seeds" >&2
  exit 1
fi

if [ "$merge" -eq 1 ]; then
  echo "fuzz: merging the inputs that add coverage into $seeds"
  "$build/tests/fuzz/fuzz_$target" -merge=1 -timeout=10 -rss_limit_mb=2048 "$seeds" "$work/corpus" </dev/null \
    >"$work/merge.log" 2>&1 || { cat "$work/merge.log"; exit 1; }
  tail -1 "$work/merge.log"
fi
echo "fuzz: $target: no findings"
