#!/usr/bin/env bash
# The prepared check of relit on a GPU machine (docs/benchmarks.md, "On a GPU"). Two steps:
#
#   scripts/device-check.sh bundle [BUNDLE]        # here: pack the built relit, its tests and every shared library
#                                                  # they need that is not the C runtime into BUNDLE
#                                                  # (default build/device-bundle; needs a build with tests)
#   scripts/device-check.sh run [BUNDLE] [OUT]     # on the GPU machine: everything under OUT (default
#                                                  # device-check-out/)
#
# `run` finds the NVIDIA OpenCL library (libnvidia-opencl.so.1) and, when the ICD loader has no entry for it,
# writes one into OUT/icd and points OCL_ICD_VENDORS there; then it runs `relit devices`, the kernel tests on the
# GPU (RELIT_TEST_DEVICES=gpu) and `relit bench --suite all --device gpu --json`, each with a time limit, so the
# whole check takes a few minutes. It uses only the bundle's libraries (LD_LIBRARY_PATH), so the GPU machine needs
# nothing but its driver. RELIT_CHECK_DEVICE (default gpu) and RELIT_CHECK_QUICK=1 (relit bench --quick) let the
# same script run on a machine without a GPU, to check the script itself.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode="${1:-}"

bundle_step() {
  local build="${RELIT_BUILD_DIR:-$root/build}" dest="${1:-$root/build/device-bundle}"
  for f in "$build/apps/relit" "$build/tests/relit_tests"; do
    [ -x "$f" ] || { echo "device-check: $f is missing: build with scripts/build.sh -DRELIT_BUILD_TESTS=ON" >&2; exit 1; }
  done
  rm -rf "$dest.partial"
  mkdir -p "$dest.partial/bin" "$dest.partial/lib"
  cp "$build/apps/relit" "$build/tests/relit_tests" "$dest.partial/bin/"
  # Every library the programs load, but the C/C++ runtime and the dynamic loader, which the GPU machine has
  # (and which must match its kernel and driver).
  local libs
  libs=$(ldd "$build/apps/relit" "$build/tests/relit_tests" | awk '/=> \// {print $3}' | sort -u |
    grep -Ev '/(libc|libm|libdl|librt|libpthread|libstdc\+\+|libgcc_s|ld-linux[^/]*)\.so')
  for lib in $libs; do cp -L "$lib" "$dest.partial/lib/"; done
  rm -rf "$dest"
  mv "$dest.partial" "$dest"
  echo "device-check: bundle in $dest: $(du -sh "$dest" | cut -f1), $(ls "$dest/lib" | wc -l) libraries"
}

find_nvidia_opencl() {
  local dirs=(/usr/lib/x86_64-linux-gnu /usr/lib64 /usr/lib /usr/local/nvidia/lib64 /usr/local/nvidia/lib
    /usr/local/cuda/lib64 /usr/lib/wsl/lib)
  local found
  found=$(ldconfig -p 2>/dev/null | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}')
  if [ -z "$found" ]; then
    for d in "${dirs[@]}"; do
      [ -e "$d/libnvidia-opencl.so.1" ] && { found="$d/libnvidia-opencl.so.1"; break; }
    done
  fi
  echo "$found"
}

run_step() {
  local bundle="${1:-$root/build/device-bundle}" out="${2:-$root/device-check-out}"
  local device="${RELIT_CHECK_DEVICE:-gpu}"
  [ -x "$bundle/bin/relit" ] || { echo "device-check: no bundle at $bundle (scripts/device-check.sh bundle)" >&2; exit 1; }
  mkdir -p "$out"
  export LD_LIBRARY_PATH="$bundle/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export POCL_CACHE_DIR="$out/pocl-cache" RELIT_LOG="${RELIT_LOG:-warning}"
  {
    echo "date: $(date -u +%FT%TZ)"
    echo "host: $(uname -a)"
    command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv
    grep -m1 "model name" /proc/cpuinfo || true
  } >"$out/machine.txt" 2>&1
  local nvidia
  nvidia=$(find_nvidia_opencl)
  if [ -n "$nvidia" ]; then
    if ! grep -qs "libnvidia-opencl" /etc/OpenCL/vendors/*.icd; then
      mkdir -p "$out/icd"
      echo "$nvidia" >"$out/icd/nvidia.icd"
      export OCL_ICD_VENDORS="$out/icd"
      echo "device-check: wrote an ICD entry for $nvidia ($out/icd/nvidia.icd)"
    fi
  else
    echo "device-check: no libnvidia-opencl.so.1 found; using the ICD loader's own entries" | tee -a "$out/machine.txt"
  fi
  local status=0
  echo "device-check: relit devices"
  timeout 120 "$bundle/bin/relit" devices >"$out/devices.txt" 2>&1 || status=1
  cat "$out/devices.txt"
  # The kernel tests: every kernel family against its double-precision reference, on the chosen device.
  local filter="KernelsBuild.*:FullyFusedMLP*:MlpCase*:Enc*:SphericalHarmonics.*:Loss.*:Adam.*"
  filter+=":Columns.*:Metrics.*:Flip.*:VolumeRenderer*:Visibility.*:Rays.*:PathTrace*:Environment*"
  echo "device-check: kernel tests on '$device'"
  RELIT_TEST_DEVICES="$device" timeout 360 "$bundle/bin/relit_tests" --gtest_filter="$filter" \
    --gtest_output="xml:$out/tests.xml" >"$out/tests.txt" 2>&1 || status=1
  tail -3 "$out/tests.txt"
  echo "device-check: relit bench --suite all --device $device"
  local quick=()
  [ "${RELIT_CHECK_QUICK:-0}" = 1 ] && quick=(--quick)
  timeout 420 "$bundle/bin/relit" bench --suite all --device "$device" --repeats 3 "${quick[@]}" \
    --json "$out/bench.json" >"$out/bench.txt" 2>&1 || status=1
  tail -5 "$out/bench.txt"
  echo "device-check: everything is in $out (status $status)"
  return "$status"
}

case "$mode" in
  bundle) shift; bundle_step "$@" ;;
  run) shift; run_step "$@" ;;
  *)
    echo "usage: scripts/device-check.sh bundle [BUNDLE] | run [BUNDLE] [OUT]" >&2
    exit 2
    ;;
esac
