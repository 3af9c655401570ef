#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang, ASan and UBSan in build-fuzz/ (or
# $PHONGFIT_FUZZ_DIR) and runs each for a bounded time: $FUZZ_SECONDS (default 60) per target, as
# many targets at once as there are cores. Fails on any crash, leak, hang (an input taking over
# 10 s), out-of-memory or sanitizer report, and prints the input that caused it: make that input a
# regression test (a gtest case) once fixed. Arguments: target names (default: all), e.g.
#   FUZZ_SECONDS=600 scripts/fuzz.sh scene_parser
# Long exploratory runs that go on past a finding and keep every one:
#   FUZZ_SECONDS=3600 FUZZ_FLAGS="-fork=1 -ignore_crashes=1 -ignore_timeouts=1 -ignore_ooms=1" \
#     scripts/fuzz.sh exr png
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${PHONGFIT_FUZZ_DIR:-$root/build-fuzz}
seconds=${FUZZ_SECONDS:-60}
jobs=$(nproc)
all_targets=(scene_parser scene_render obj_mesh exr pfm png capture)
targets=("$@")
((${#targets[@]} > 0)) || targets=("${all_targets[@]}")

"$root/scripts/setup.sh"
flags="-O1 -g -fno-omit-frame-pointer -fsanitize=fuzzer-no-link,address,undefined"
flags+=" -fno-sanitize-recover=all"
CXX=clang++ cmake -S "$root" -B "$build" -G "Unix Makefiles" -DCMAKE_BUILD_TYPE=Fuzz \
  -DPHONGFIT_FUZZ=ON -DCMAKE_UNITY_BUILD=ON -DCMAKE_CXX_FLAGS="$flags" \
  -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" >/dev/null
make -C "$build" -j "$jobs" --no-print-directory "${targets[@]/%/_fuzz}"

export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:check_initialization_order=1"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
logs="$build/logs"
mkdir -p "$logs" "$build/artifacts"

# Seeds: fuzz/corpus/<seeds> (read only) and, for scenes, the shipped scenes. New inputs go to
# build-fuzz/corpus/<target>, so a local rerun continues where the last one stopped.
run_target() {
  local target=$1 seeds=$1 extra=()
  case $target in
    scene_parser|scene_render) seeds=scene
                               extra=(-dict="$root/fuzz/scene.dict" "$root/datasets_synth/scenes") ;;
    obj_mesh) seeds=obj ;;
  esac
  mkdir -p "$build/corpus/$target"
  "$build/fuzz/${target}_fuzz" -max_total_time="$seconds" -timeout=10 -rss_limit_mb=2560 \
    -malloc_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$build/artifacts/$target-" \
    ${FUZZ_FLAGS:-} \
    "$build/corpus/$target" "$root/fuzz/corpus/$seeds" "${extra[@]}" >"$logs/$target.log" 2>&1
}

start=$SECONDS
declare -A pids
for target in "${targets[@]}"; do
  while (($(jobs -rp | wc -l) >= jobs)); do wait -n || true; done
  run_target "$target" &
  pids[$target]=$!
done

failed=()
for target in "${targets[@]}"; do
  if wait "${pids[$target]}"; then
    # One run states its inputs in its final stats; -fork=1 runs in their last status line
    # ("#N: cov: ... oom/timeout/crash: O/T/C"), with what they went on past.
    log=$logs/$target.log
    runs=$(grep -m1 -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' ||
           grep -o '^#[0-9]*' "$log" | tail -n 1 | tr -d '#' || true)
    kept=$(grep -o 'oom/timeout/crash: [0-9/]*' "$log" | tail -n 1 | cut -d' ' -f2 || true)
    if [[ -n $kept && $kept != 0/0/0 ]]; then
      echo "fuzz: $target: ${runs:-?} inputs in ${seconds} s, went on past oom/timeout/crash" \
        "$kept: inputs in $build/artifacts/$target-*"
    else
      echo "fuzz: $target: ${runs:-?} inputs in ${seconds} s, no finding"
    fi
  else
    failed+=("$target")
    echo "fuzz: $target FAILED; end of $logs/$target.log:" >&2
    grep -v '^"\|Uses:' "$logs/$target.log" | tail -n 60 >&2
    echo "fuzz: reproduce with: $build/fuzz/${target}_fuzz $(grep -o "Test unit written to [^ ]*" "$logs/$target.log" | tail -n 1 | cut -d' ' -f5)" >&2
  fi
done
echo "fuzz: ${#targets[@]} targets in $((SECONDS - start)) s"
if ((${#failed[@]} > 0)); then
  echo "fuzz: FAILED: ${failed[*]} (turn each input into a regression test once fixed)" >&2
  exit 1
fi
