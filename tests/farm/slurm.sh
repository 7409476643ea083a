#!/usr/bin/env bash
# slurm.sh SEAMCOOK WORKDIR - `seamcook farm submit` and `farm status` on a
# single-node Slurm cluster that this test starts on localhost (munged,
# slurmctld and slurmd in a folder of their own, on random ports, stopped at
# the end). Skipped (77) without slurm-wlm and munge, or when not root
# (slurmd runs the tasks as their user); `./setup.sh farm-test` installs them.
#
#  1. three assets (two with the same bytes in other folders): every task
#     done, each task's folder holds the saved asset, and the tasks share
#     one cache (the same bytes cook once: 2 of 3 erase_seams are hits)
#  2. an asset that does not load: its task fails, status names it and exits 1
#  3. a list naming a file that is not there: submit refuses, naming list:line
source "$(dirname "$0")/common.sh"
for tool in slurmctld slurmd sbatch squeue munged mungekey; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool is not installed (./setup.sh farm-test installs it)"; exit 77; }
done
[ "$(id -u)" = 0 ] || { echo "SKIP: the test cluster's slurmd runs as root"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }

# ------------------------------------------------------------------ the cluster
source "$(dirname "$0")/cluster.sh"
trap stop_cluster EXIT
start_cluster "$work/cluster" "$(nproc)" || fail "the test cluster did not come up"

# wait_done OUT: until no task is pending or running (at most 3 minutes)
wait_done() {
  for _ in $(seq 360); do
    "$bin" farm status --out "$1" > "$work/status" || true
    grep -q " 0 pending or running" "$work/status" && return 0
    sleep 0.5
  done
  cat "$work/status"
  fail "the job did not finish"
}

# ------------------------------------------------------------------ 1. three assets
cd "$work"
"$bin" run "$data/graphs/proc_save.lua" --cache made-cache --out made -q
for name in one two three; do
  mkdir -p "assets/$name"
  cp made/asset.obj made/asset.mtl made/asset_*.png "assets/$name/"
done
printf '%s\n' '# the farm' assets/one/asset.obj '' assets/two/asset.obj assets/three/asset.obj > list.txt
cat > graph.lua <<'LUA'
local asset = load_atlas{ name = "load", path = param("mesh", "") }
local erased = erase_seams{ name = "erased", atlas = asset }
save{ name = "save", atlas = erased.atlas, file = "asset" }
LUA
id=$("$bin" farm submit graph.lua --assets list.txt --cache farm-cache -j1 --out out -q)
[ -n "$id" ] || fail "no job id"
wait_done out
cat "$work/status"
"$bin" farm status --out out > /dev/null || fail "status exits 1 after a good job"
grep -q "3 tasks, 3 done" "$work/status" || fail "not every task is done"
for i in 0 1 2; do
  [ -f out/${i}_asset/asset.obj ] || fail "task $i saved nothing"
  cmp out/${i}_asset/asset.obj out/0_asset/asset.obj || fail "task $i saved other bytes"
done
erase_hits=$(grep -ho '"cached":[[:space:]]*true' out/*_asset/report.json | wc -l)
[ "$erase_hits" -ge 4 ] || fail "the tasks did not share the cache ($erase_hits hits)"
echo "1. job $id: 3 tasks done on one cache ($erase_hits of 9 nodes hits: the same bytes cook once)"

# ------------------------------------------------------------------ 2. a failing task
mkdir -p assets/bad
printf 'v 0 0 0\nf 1 2 3\n' > assets/bad/asset.obj
printf 'assets/one/asset.obj\nassets/bad/asset.obj\n' > list2.txt
"$bin" farm submit graph.lua --assets list2.txt --cache farm-cache --out out2 -q > /dev/null
wait_done out2
cat "$work/status"
if "$bin" farm status --out out2 > /dev/null; then fail "status exits 0 with a failed task"; fi
grep -q "task 1  failed" "$work/status" || fail "the bad asset's task is not failed"
grep -q "task 0  done" "$work/status" || fail "the good asset's task did not finish"
echo "2. a bad asset: its task failed, named by status (exit 1); the other done"

# ------------------------------------------------------------------ 3. a bad list
printf 'assets/one/asset.obj\nassets/none.obj\n' > list3.txt
if "$bin" farm submit graph.lua --assets list3.txt --out out3 2> err3; then fail "a bad list was submitted"; fi
grep -q "list3.txt:2: 'assets/none.obj' is not a file" err3 || fail "bad list: $(cat err3)"
echo "3. a list naming a missing file: refused, naming list3.txt:2"
