#!/usr/bin/env bash
# Configures (Release) and builds phongfit into build/ (or $PHONGFIT_BUILD_DIR). The libraries
# and the command are built as unity batches (8 sources a compile): their sources share the Eigen,
# Ceres and JSON templates, which each batch then instantiates once; that saved test.sh 189 s of
# its 874 on 2 cores (session 56). Configure a build directory without it for edit-compile cycles.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${PHONGFIT_BUILD_DIR:-$root/build}
if [[ ! -f "$build/CMakeCache.txt" ]]; then
  cmake -S "$root" -B "$build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_UNITY_BUILD=ON >/dev/null
fi
cmake --build "$build" -j "$(nproc)" -- --no-print-directory
