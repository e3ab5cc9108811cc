#!/usr/bin/env bash
# The prepared check of relit on a GPU machine (docs/benchmarks.md, "On a GPU"). Two steps:
#
#   scripts/device-check.sh bundle [BUNDLE]        # here: pack relit, its tests, bench_mlp and every shared library
#                                                  # they need that is not the C runtime into BUNDLE
#                                                  # (default build-device/device-bundle)
#   scripts/device-check.sh run [BUNDLE] [OUT]     # on the GPU machine: everything under OUT (default
#                                                  # device-check-out/)
#
# `bundle` packs the build in $RELIT_BUILD_DIR (default build-device/), building it first when it is missing: a
# build without OpenImageIO, OpenVDB and MPI (their shared libraries come to ~400 MB; the kernels, their tests and
# the benchmarks need none of them), with tests and benchmarks, whose native peers are compiled for x86-64-v3
# rather than for this machine's processor.
#
# `run` finds the NVIDIA OpenCL library (libnvidia-opencl.so.1) and, when the ICD loader has no entry for it,
# writes one into a temporary folder and points OCL_ICD_VENDORS there; then it runs `relit devices`, the kernel
# tests on the GPU (RELIT_TEST_DEVICES=gpu), bench_mlp (the fused MLP against the CLBlast GEMM chain) and
# `relit bench --suite kernels` and `--suite e2e --device gpu --json` (kernels only in a build without images), each
# with a time limit (30 s, 3 min, 4 min, 45 s, 90 s, 60 s: about 7 minutes on an H200). OUT receives devices.txt,
# tests.txt, tests.xml, tests_mlp.xml, bench_mlp.txt, bench_mlp.json, bench.txt, bench_kernels.json (and
# bench_e2e.json). It uses only the bundle's libraries (LD_LIBRARY_PATH), so the GPU machine needs nothing but its
# driver. RELIT_CHECK_DEVICE (default gpu) and RELIT_CHECK_QUICK=1 (--quick / --smoke) let the same script run on a
# machine without a GPU, to check the script itself.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
mode="${1:-}"

bundle_step() {
  local build="${RELIT_BUILD_DIR:-$root/build-device}" dest="${1:-${RELIT_BUILD_DIR:-$root/build-device}/device-bundle}"
  if [ ! -x "$build/apps/relit" ] || [ ! -x "$build/tests/relit_tests" ]; then
    echo "device-check: building the bundle's configuration in $build"
    RELIT_BUILD_DIR="$build" "$root/scripts/build.sh" -DRELIT_BUILD_TESTS=ON -DRELIT_BUILD_BENCH=ON \
      -DRELIT_WITH_OPENIMAGEIO=OFF -DRELIT_WITH_OPENVDB=OFF -DRELIT_WITH_MPI=OFF -DRELIT_BENCH_ARCH=x86-64-v3
  fi
  local programs=("$build/apps/relit" "$build/tests/relit_tests")
  [ -x "$build/bench/bench_mlp" ] && programs+=("$build/bench/bench_mlp")
  rm -rf "$dest.partial"
  mkdir -p "$dest.partial/bin" "$dest.partial/lib"
  cp "${programs[@]}" "$dest.partial/bin/"
  # Every library the programs load, but the C/C++ runtime and the dynamic loader, which the GPU machine has
  # (and which must match its kernel and driver).
  local libs
  libs=$(ldd "${programs[@]}" | awk '/=> \// {print $3}' | sort -u |
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
  local bundle="${1:-$root/build-device/device-bundle}" out="${2:-$root/device-check-out}"
  local device="${RELIT_CHECK_DEVICE:-gpu}" quick="${RELIT_CHECK_QUICK:-0}"
  [ -x "$bundle/bin/relit" ] || { echo "device-check: no bundle at $bundle (scripts/device-check.sh bundle)" >&2; exit 1; }
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
  local work
  work=$(mktemp -d "${TMPDIR:-/tmp}/relit-device-check.XXXXXX")
  export LD_LIBRARY_PATH="$bundle/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
  export POCL_CACHE_DIR="$work/pocl-cache" RELIT_LOG="${RELIT_LOG:-warning}"
  {
    echo "date: $(date -u +%FT%TZ)"
    echo "host: $(uname -a)"
    command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm \
      --format=csv
    grep -m1 "model name" /proc/cpuinfo || true
    echo "cores: $(nproc)"
  } >"$out/devices.txt" 2>&1
  local nvidia
  nvidia=$(find_nvidia_opencl)
  if [ -n "$nvidia" ]; then
    if ! grep -qs "libnvidia-opencl" /etc/OpenCL/vendors/*.icd; then
      mkdir -p "$work/icd"
      echo "$nvidia" >"$work/icd/nvidia.icd"
      export OCL_ICD_VENDORS="$work/icd"
      echo "device-check: wrote an ICD entry for $nvidia" | tee -a "$out/devices.txt"
    fi
  else
    echo "device-check: no libnvidia-opencl.so.1 found; using the ICD loader's own entries" | tee -a "$out/devices.txt"
  fi
  local status=0 t0=$SECONDS
  step() { echo "device-check: $1 ($((SECONDS - t0)) s so far)"; }
  step "relit devices"
  local features
  features=$("$bundle/bin/relit" --version 2>&1) || status=1
  echo "$features" >>"$out/devices.txt"
  timeout 30 "$bundle/bin/relit" devices >>"$out/devices.txt" 2>&1 || status=1
  cat "$out/devices.txt"
  # The kernel tests: every kernel family against its double-precision reference, on the chosen device. The MLP
  # cases run last and apart: each builds many kernel variants (13-57 s a test on an H200), and a time limit there
  # must not cost the other families' results.
  local filter="KernelsBuild.*:FullyFusedMLP*:MlpCase*:Enc*:SphericalHarmonics.*:Loss.*:Adam.*"
  filter+=":Columns.*:Metrics.*:Flip.*:VolumeRenderer*:Visibility.*:Rays.*:PathTrace*:Environment*"
  local mlp_cases="FullyFusedMLP/MlpCase.*" skip="FullyFusedMLP/MlpCase.*"
  [[ "$features" == *"no OpenImageIO"* ]] && skip+=":PathTraceSampling.EnvironmentSampler*"  # an EXR fixture
  step "kernel tests on '$device'"
  RELIT_TEST_DEVICES="$device" timeout 180 "$bundle/bin/relit_tests" --gtest_filter="$filter:-$skip" \
    --gtest_output="xml:$out/tests.xml" >"$out/tests.txt" 2>&1 || status=1
  step "the MLP cases on '$device'"
  RELIT_TEST_DEVICES="$device" timeout 240 "$bundle/bin/relit_tests" --gtest_filter="$mlp_cases" \
    --gtest_output="xml:$out/tests_mlp.xml" >>"$out/tests.txt" 2>&1 || status=1
  grep -E "^\[  (FAILED|PASSED) |tests? ran" "$out/tests.txt" | tail -12 || true
  if [ -x "$bundle/bin/bench_mlp" ]; then
    step "bench_mlp --device $device (the fused MLP against the CLBlast chain)"
    local smoke=()
    [ "$quick" = 1 ] && smoke=(--smoke)
    timeout 45 "$bundle/bin/bench_mlp" --device "$device" --variants fused,clblast --reps 5 "${smoke[@]}" \
      --json "$out/bench_mlp.json" >"$out/bench_mlp.txt" 2>&1 || status=1
    tail -12 "$out/bench_mlp.txt"
  fi
  local quick_flag=()
  [ "$quick" = 1 ] && quick_flag=(--quick)
  : >"$out/bench.txt"
  local suites=(kernels e2e)
  if [[ "$features" == *"no OpenImageIO"* ]]; then
    suites=(kernels)  # the end-to-end cases generate a dataset, written as EXR images
    echo "device-check: no end-to-end cases: this build reads and writes no images" | tee -a "$out/bench.txt"
  fi
  for suite in "${suites[@]}"; do  # one run each, so that a slow second suite cannot cost the first one's results
    step "relit bench --suite $suite --device $device"
    local limit=60
    [ "$suite" = kernels ] && limit=90
    timeout "$limit" "$bundle/bin/relit" bench --suite "$suite" --device "$device" --repeats 3 "${quick_flag[@]}" \
      --json "$out/bench_$suite.json" >>"$out/bench.txt" 2>&1 || status=1
  done
  tail -45 "$out/bench.txt"
  rm -rf "$work"
  step "everything is in $out (status $status)"
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
