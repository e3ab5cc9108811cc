#!/usr/bin/env bash
# The whole test suite on a fresh machine: installs what is missing, builds everything, runs CTest
# (GoogleTest, pytest, the find_package example, the pip build). Arguments go to ctest, e.g. -L cpp.
# The tests run RELIT_TEST_JOBS at a time (default: one per core; the long ones first, see tests/CMakeLists.txt).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${RELIT_BUILD_DIR:-$root/build}"
"$root/scripts/setup.sh"
"$root/scripts/build.sh" -DRELIT_BUILD_TESTS=ON -DRELIT_BUILD_PYTHON=ON -DRELIT_BUILD_APPS=ON -DRELIT_BUILD_BENCH=ON
export POCL_CACHE_DIR="$build/pocl-cache"   # kernel binaries cached between runs, inside the build tree
ctest --test-dir "$build" --output-on-failure --timeout 1500 --parallel "${RELIT_TEST_JOBS:-$(nproc)}" "$@"
