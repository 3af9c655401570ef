#!/usr/bin/env bash
# Command 2: install what is missing, build, run the whole test suite.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
build=${PHONGFIT_BUILD_DIR:-$root/build}
cd "$build"
ctest --output-on-failure -j "$(nproc)" "$@"
# The Slurm cluster test installs and starts its own cluster; where it cannot, it is skipped: say why.
if ! why=$("$root/scripts/slurm_cluster.sh" available 2>&1); then
  echo "test: the Slurm cluster test (slurm_cluster) was skipped: $why"
fi
