#!/usr/bin/env bash
# relit's main job on a fresh machine: installs what is missing, builds, and runs relit on the default
# device. Arguments go to the relit program (default: `demo --out demo`: generate the default cloud dataset,
# train the fast preset, relight the test views, print PSNR/SSIM, write images and contact sheets).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${RELIT_BUILD_DIR:-$root/build}"
"$root/scripts/setup.sh"
"$root/scripts/build.sh" -DRELIT_BUILD_APPS=ON
export POCL_CACHE_DIR="${POCL_CACHE_DIR:-$build/pocl-cache}"
if [ $# -eq 0 ]; then set -- demo --out "$root/demo"; fi
exec "$build/apps/relit" "$@"
