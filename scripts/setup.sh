#!/usr/bin/env bash
# Installs, with apt-get, only the Debian packages phongfit needs that are missing.
# A no-op in well under a second when everything is present.
set -euo pipefail

packages=(
  g++ cmake make pkg-config
  libceres-dev libopencv-dev libopenexr-dev libembree-dev libeigen3-dev libtbb-dev
  libcli11-dev libfmt-dev nlohmann-json3-dev libpugixml-dev libtinyobjloader-dev libboost-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  # scripts/fuzz.sh and scripts/sanitize.sh: libFuzzer and the sanitizer runtimes, and
  # llvm-symbolizer for readable reports.
  clang libclang-rt-14-dev llvm
  # tests/CMakeLists.txt: the clang_format test (scripts/check_format.sh).
  clang-format git
)

missing=()
for p in "${packages[@]}"; do
  status=$(dpkg-query -W -f='${Status}' "$p" 2>/dev/null || true)
  [[ "$status" == "install ok installed" ]] || missing+=("$p")
done

if ((${#missing[@]} == 0)); then
  exit 0
fi

echo "setup: installing ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
