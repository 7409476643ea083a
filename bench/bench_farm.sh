#!/usr/bin/env bash
# bench_farm.sh - a cold cook of four corpus assets on one Slurm worker
# against two.
#
#   bench/bench_farm.sh [SEAMCOOK [WORKDIR]]
#
# The main job (graphs/lod_chain.lua, -j1 per task; settings below) over four
# corpus assets, each time on a fresh cache:
#
# 1. no scheduler: four `seamcook run` one after the other (what one worker
#    does, without Slurm's own costs);
# 2. `seamcook farm submit` on a single-node Slurm cluster started here the
#    way tests/farm/slurm.sh starts it (munged, slurmctld and slurmd in a
#    folder of their own, random ports), its node declaring CPUs=1: one task
#    at a time, one worker;
# 3. the same with CPUs=2: two tasks at a time, two workers.
#
# Farm times run from submit until every task has left its --json summary
# (looked for every 0.2 s); `farm status` must then show every task done.
# Prints the wall time of each, the cooks' own seconds summed (from their
# reports and --json summaries), and the speedup of two workers over one.
# Needs root, slurm-wlm and munge (./setup.sh farm-test installs them) and
# the corpus (../shared/corpus or $SC_CORPUS). Not run by ctest: it takes
# minutes (4.5 on 2 cores).
#
# Settings, so that every task cooks the whole graph and ends done: mip_min=
# 1024, the maps' mip chains stop at 1024^2, where these assets' crack checks
# pass (lod_chain.lua names the first crack pixel per asset); and
# check.max_fold_pixels=2000 in place of the limit taken from the reference
# (2 times its back-face pixels), the setting the timings in
# docs/notes/farm.md were measured with. Both change what is checked, not
# what is cooked.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=$(realpath "${1:-$root/build/seamcook}")
work=${2:-$root/build/bench-farm}
corpus=${SC_CORPUS:-$root/../shared/corpus}
assets=(Duck/Duck.gltf MuruCat/scene.gltf Lantern/Lantern_welded.obj Avocado/Avocado.gltf)
for tool in slurmctld slurmd sbatch squeue munged mungekey; do
  command -v "$tool" >/dev/null || { echo "bench_farm: $tool is not installed (./setup.sh farm-test installs it)"; exit 1; }
done
[ "$(id -u)" = 0 ] || { echo "bench_farm: the cluster's slurmd runs as root"; exit 1; }
for a in "${assets[@]}"; do
  [ -f "$corpus/$a" ] || { echo "bench_farm: corpus asset $corpus/$a not found"; exit 1; }
done
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")
printf '%s\n' "${assets[@]/#/$corpus/}" > "$work/assets.txt"
run_args=(--set mip_min=1024 --set check.max_fold_pixels=2000 -j1)

# ------------------------------------------------------------------ the cluster
source "$root/tests/farm/cluster.sh"
trap stop_cluster EXIT

# the cooks' own seconds, summed, from report.json or --json summaries
cook_seconds() {
  cat "$@" |
    awk -F'[:,]' '/^\t"seconds":/ {gsub(/[[:space:]]/, "", $2); s += $2} END {printf "%.1f", s}'
}

# farm CPUS LABEL: the four assets on a cluster whose node declares CPUS;
# prints LABEL and the wall time (also left in `took`), then what status said
farm() {
  start_cluster "$work/cluster$1" "$1" || { echo "bench_farm: no cluster"; exit 1; }
  cd "$work"
  local t0 t1 id out=$work/farm$1
  t0=$(date +%s.%N)
  id=$("$bin" farm submit "$root/graphs/lod_chain.lua" --assets assets.txt --cache "$work/cache-farm$1" \
    --out "$out" -q "${run_args[@]}")
  # every task leaves its summary last; looking for the files costs the
  # cooks nothing (a `farm status` a poll would run squeue each time)
  local n
  for _ in $(seq 18000); do
    n=0
    for i in 0 1 2 3; do [ -f "$out/.seamcook-farm/task_$i.json" ] && n=$((n + 1)); done
    [ $n = 4 ] && break
    sleep 0.2
  done
  t1=$(date +%s.%N)
  for _ in $(seq 100); do   # the tasks leave the queue
    "$bin" farm status --out "$out" > "$work/status$1" || true
    grep -q " 0 pending or running" "$work/status$1" && break
    sleep 0.2
  done
  stop_cluster
  grep -q "4 tasks, 4 done" "$work/status$1" || { cat "$work/status$1"; echo "bench_farm: not every task is done"; exit 1; }
  took=$(awk "BEGIN {printf \"%.1f\", $t1 - $t0}")
  echo "$2 $took s"
  sed 's/^/   /' "$work/status$1"
  echo "   the cooks' own seconds, summed: $(cook_seconds "$out"/.seamcook-farm/task_*.json)"
}

echo "bench_farm: lod_chain.lua (${run_args[*]}) over ${assets[*]}; $(nproc) CPUs here"
t0=$(date +%s.%N)
for i in "${!assets[@]}"; do
  "$bin" run "$root/graphs/lod_chain.lua" --set mesh="$corpus/${assets[$i]}" "${run_args[@]}" \
    --cache "$work/cache-plain" --out "$work/plain/$i" -q 2> "$work/plain-$i.err" ||
    { cat "$work/plain-$i.err"; echo "bench_farm: ${assets[$i]} failed"; exit 1; }
done
t1=$(date +%s.%N)
plain=$(awk "BEGIN {printf \"%.1f\", $t1 - $t0}")
echo "1. no scheduler, four runs in a row: $plain s"
echo "   the cooks' own seconds, summed: $(cook_seconds "$work"/plain/*/report.json)"
farm 1 "2. Slurm, one worker (CPUs=1):      "
one=$took
farm 2 "3. Slurm, two workers (CPUs=2):     "
two=$took
awk "BEGIN {printf \"two workers over one: %.2fx (over no scheduler: %.2fx)\n\", $one / $two, $plain / $two}"
