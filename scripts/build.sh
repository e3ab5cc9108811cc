#!/usr/bin/env bash
# Configures and builds relit into build/ (or $RELIT_BUILD_DIR) with the venv's Python.
# Extra arguments go to CMake's configure step, e.g. scripts/build.sh -DRELIT_BUILD_BENCH=ON
# RELIT_UNITY_BUILD=ON compiles the sources in batches (a CMake unity build): a clean build then takes about half
# the CPU time, but a change to one source recompiles its whole batch. On by default in CI (CI=true, where every
# build is a clean one), off otherwise.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${RELIT_BUILD_DIR:-$root/build}"
python="${RELIT_VENV:-$root/.venv}/bin/python"
generator=()
[ -f "$build/CMakeCache.txt" ] || { command -v ninja >/dev/null && generator=(-G Ninja); }
unity="${RELIT_UNITY_BUILD:-$([ "${CI:-}" = true ] && echo ON || echo OFF)}"
mkdir -p "$build"
cmake -S "$root" -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE="${CMAKE_BUILD_TYPE:-Release}" \
  -DPython3_EXECUTABLE="$python" -DCMAKE_UNITY_BUILD="$unity" "$@" >"$build/configure.log" 2>&1 || { cat "$build/configure.log"; exit 1; }
cmake --build "$build" --parallel "$(nproc)"
