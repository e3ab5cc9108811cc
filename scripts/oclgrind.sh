#!/usr/bin/env bash
# Every kernel test of relit on Oclgrind, the OpenCL device simulator (docs/reliability.md, "Work-group
# semantics: Oclgrind"): CI runs a two-minute subset (ctest -L oclgrind); this runs all of them, the wider MLPs,
# the path tracer's statistical tests and a hash-grid fit included (more than 45 minutes on 2 cores).
#
#   scripts/oclgrind.sh                    # data races, out-of-bounds accesses, barrier divergence, API errors
#   scripts/oclgrind.sh --uninitialized    # also Oclgrind's uninitialised-value check (see the docs first)
#   scripts/oclgrind.sh -- 'Visibility.*'  # another GoogleTest filter
#
# Builds the tests first (scripts/build.sh into $RELIT_BUILD_DIR, default build/). Exits non-zero on any
# failing test or any report; the report is in BUILD/tests/oclgrind-all.log.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${RELIT_BUILD_DIR:-$root/build}"
filter="FullyFusedMLP*:Enc*:SphericalHarmonics.*:VolumeRenderer*:Visibility.*:Loss.*:Adam.*:Columns.*:Rays.*"
filter+=":Metrics.*:Flip.*:Environment*:PathTrace*:Peak.*"
extra=()
while [ $# -gt 0 ]; do
  case "$1" in
    --uninitialized) extra+=(--uninitialized); shift ;;
    --) filter="$2"; shift 2 ;;
    *) echo "usage: scripts/oclgrind.sh [--uninitialized] [-- GTEST_FILTER]" >&2; exit 2 ;;
  esac
done
command -v oclgrind >/dev/null || { echo "oclgrind is missing: scripts/setup.sh installs it" >&2; exit 1; }
"$root/scripts/build.sh" -DRELIT_BUILD_TESTS=ON >/dev/null
start=$(date +%s)
cmake -DOCLGRIND="$(command -v oclgrind)" -DTEST_BINARY="$build/tests/relit_tests" -DFILTER="$filter" \
  -DEXTRA="${extra[*]:-}" -DLOG="$build/tests/oclgrind-all.log" -DWORK_DIR="$build/tests/oclgrind-work" \
  -P "$root/tests/check_oclgrind.cmake"
echo "oclgrind: every kernel test clean in $(($(date +%s) - start)) s"
