#!/usr/bin/env bash
# Command 1: install what is missing, build, and run the main job on the built-in scene: render the
# Cornell box with its Phong sphere, fit the sphere's kd, ks and n back, print them with the error.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
"$root/scripts/setup.sh"
"$root/scripts/build.sh"
build=${PHONGFIT_BUILD_DIR:-$root/build}
"$build/phongfit" demo -o "${1:-$root/out/demo}"
