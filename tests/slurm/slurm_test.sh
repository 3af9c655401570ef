#!/usr/bin/env bash
# phongfit on a real one-node Slurm cluster (scripts/slurm_cluster.sh): a 4-task array of synth and
# of bench fit gives the files and numbers of a run on one machine, and an array with a task
# cancelled mid-run, submitted again, completes without redoing finished samples.
# Usage: slurm_test.sh PHONGFIT CONFIGS_DIR. Exits 77 (ctest: skipped) where Slurm cannot run.
set -euo pipefail
phongfit=$1
configs=$2
root=$(cd "$(dirname "$0")/../.." && pwd)
cluster_script=$root/scripts/slurm_cluster.sh

if ! why=$("$cluster_script" available 2>&1); then
  echo "slurm_test: SKIPPED: Slurm cannot run here: $why"
  exit 77
fi
"$cluster_script" install

work=$(mktemp -d /tmp/phongfit_slurm.XXXXXX)
cluster=$work/cluster
cleanup() {
  "$cluster_script" stop "$cluster" >/dev/null 2>&1 || true
  rm -rf "$work"
}
trap cleanup EXIT
"$cluster_script" start "$cluster" >/dev/null
# shellcheck disable=SC1091
source "$cluster/env.sh"

fail() {
  echo "slurm_test: FAILED: $*" >&2
  exit 1
}

# The numbers of a bench fit's CSV, without its time columns.
numbers() {
  awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "time_s") t[i] = 1 }
           { for (i = 1; i <= NF; i++) if (!(i in t)) printf "%s,", $i; print "" }' "$1"
}

cd "$work"
echo "slurm_test: synth, 4 tasks"
"$phongfit" synth "$configs/small.json" -o local --quiet >/dev/null
"$phongfit" slurm synth --tasks 4 --wait "$configs/small.json" -o cluster-ds --quiet
diff -r local cluster-ds || fail "the dataset made through Slurm differs from the local one"
[[ -f cluster-ds.slurm/synth.sbatch ]] || fail "no sbatch script beside the output"

echo "slurm_test: bench fit, 4 tasks"
settings=(--spp-per-round "4,8" --rounds 3 --quiet)
"$phongfit" bench fit local -o bench-local "${settings[@]}" >/dev/null
"$phongfit" slurm bench-fit --tasks 4 --wait cluster-ds -o bench-cluster "${settings[@]}" >/dev/null
for csv in recovery.csv rounds.csv; do
  diff <(numbers "bench-local/$csv") <(numbers "bench-cluster/$csv") ||
    fail "bench fit's $csv through Slurm differs from the local one"
done

echo "slurm_test: a task cancelled mid-run, then the array submitted again"
cat >slow.json <<JSON
{"scenes": ["$root/datasets_synth/scenes/sphere_point.xml"], "material": "sphere", "samples": 8,
 "seed": 3, "spp": 2048, "albedo": [0.4, 0.95], "ks_share": [0.1, 0.6], "n": [5, 500],
 "defines": {"width": 64, "height": 64}}
JSON
"$phongfit" synth slow.json -o slow-local --quiet >/dev/null
out=$("$phongfit" slurm synth --tasks 2 slow.json -o slow --quiet)
job=$(sed -n 's/^slurm: submitted job \([0-9]*\) .*/\1/p' <<<"$out")
[[ -n $job ]] || fail "no job id in: $out"
# Cancel task 1 once it has finished a sample and is rendering the next.
for _ in $(seq 600); do
  [[ -f slow/sample_0001/truth.json ]] && break
  sleep 0.1
done
[[ -f slow/sample_0001/truth.json ]] || fail "task 1 finished no sample in 60 s"
scancel "${job}_1"
while squeue -h -j "$job" 2>/dev/null | grep -q .; do sleep 0.2; done
[[ ! -f slow/index.json ]] || fail "index.json written although task 1 was cancelled"
complete=$(find slow -name truth.json | wc -l)
((complete < 8)) || fail "every sample finished before the cancel: make the samples slower"
declare -A stamp
for f in slow/*/truth.json slow/*/image.exr; do stamp[$f]=$(stat -c %Y.%i "$f"); done
log=$(sbatch --wait --parsable slow.slurm/synth.sbatch) || fail "the resubmitted array failed"
for f in "${!stamp[@]}"; do
  [[ $(stat -c %Y.%i "$f") == "${stamp[$f]}" ]] || fail "$f was redone on resubmission"
done
[[ -f slow/index.json ]] || fail "no index.json after the resubmitted array"
diff -r slow-local slow || fail "the resumed dataset differs from the local one"
grep -h "already complete" slow.slurm/logs/"${log%%;*}"_*.out
echo "slurm_test: passed ($complete of 8 samples were kept after the cancel)"
