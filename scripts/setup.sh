#!/usr/bin/env bash
# Installs everything relit needs to build, test and run on Debian 12 (bookworm) or newer:
# system libraries from Debian's packages and Python tools from PyPI into a virtual environment.
# Idempotent: when everything is present it only checks, which takes about a second.
#
#   scripts/setup.sh            # packages + .venv in the repository root
#   RELIT_VENV=/path scripts/setup.sh
#   scripts/setup.sh --peers    # also .venv-peers: PyTorch from PyPI for bench/peers (about 5 GB; not for tests)
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
venv="${RELIT_VENV:-$root/.venv}"

# One line per job; --no-install-recommends keeps the set to ~0.7 GB instead of ~1.2 GB (Qt, gstreamer...).
debian_packages=(
  build-essential cmake ninja-build pkg-config git clang-format  # clang-format: the format test
  ocl-icd-opencl-dev opencl-headers opencl-clhpp-headers clinfo   # OpenCL ICD loader, C and C++ headers
  pocl-opencl-icd                                                 # the portable CPU OpenCL driver
  oclgrind                                                        # OpenCL simulator: races, bounds, barriers
  libclblast-dev                                                  # bench_mlp's GEMM peer (RELIT_WITH_CLBLAST)
  libopenimageio-dev openimageio-tools                            # EXR/PNG/HDR images
  libeigen3-dev libopenblas-dev                                   # host math, references, BLAS peer
  libgtest-dev libgmock-dev                                       # tests
  clang libclang-rt-dev                                           # fuzz build: clang, libFuzzer + sanitizer runtimes
  pybind11-dev nlohmann-json3-dev libcli11-dev                    # binding, JSON, command line
  libopenvdb-dev libboost-iostreams-dev                           # OpenVDB volume import (its CMake module needs Boost.Iostreams)
  libopenvdb-tools                                                # vdb_print: the export test reads relit's .vdb files with it
  ffmpeg                                                          # relighting videos (MP4) and ffprobe for their test
  fonts-dejavu-core                                               # the contact sheets' titles and captions (OpenImageIO draws them)
  libopenmpi-dev openmpi-bin                                      # data parallelism over MPI ranks (mpirun)
  python3-dev python3-venv python3-pip                            # Python headers and venv
)

missing=()
for p in "${debian_packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  sudo_cmd=()
  [ "$(id -u)" -eq 0 ] || sudo_cmd=(sudo)
  export DEBIAN_FRONTEND=noninteractive
  "${sudo_cmd[@]}" apt-get update -qq
  "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# A virtual environment keeps the Python tools away from the system's packages (PEP 668).
python_tools=(numpy pytest scikit-build-core pybind11 scikit-image matplotlib mitsuba flip-evaluator)
if [ ! -x "$venv/bin/python" ]; then
  echo "setup: creating Python virtual environment $venv"
  python3 -m venv "$venv"
fi
if ! "$venv/bin/python" - "${python_tools[@]}" <<'PY' 2>/dev/null
import importlib.util, sys
names = {"scikit-build-core": "scikit_build_core", "scikit-image": "skimage", "flip-evaluator": "flip_evaluator"}
sys.exit(any(importlib.util.find_spec(names.get(n, n)) is None for n in sys.argv[1:]))
PY
then
  echo "setup: installing Python packages: ${python_tools[*]}"
  "$venv/bin/python" -m pip install -q --disable-pip-version-check "${python_tools[@]}"
fi
echo "setup: ok (python: $venv/bin/python)"

# The benchmark peers (bench/peers/compare.py): PyTorch 2.x from PyPI, eager and torch.compile (its inductor
# compiles C++ with the system's g++). A venv of its own, so that the test venv stays small.
if [ "${1:-}" = "--peers" ]; then
  peers="${RELIT_PEERS_VENV:-$root/.venv-peers}"
  [ -x "$peers/bin/python" ] || python3 -m venv "$peers"
  if ! "$peers/bin/python" -c "import torch, numpy" 2>/dev/null; then
    echo "setup: installing PyTorch into $peers"
    "$peers/bin/python" -m pip install -q --disable-pip-version-check torch numpy
  fi
  echo "setup: peers ok (python: $peers/bin/python, torch $("$peers/bin/python" -c 'import torch; print(torch.__version__)'))"
fi
