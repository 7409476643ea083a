#!/usr/bin/env bash
# leases.sh SEAMCOOK WORKDIR - processes sharing a cache cook each action once.
#
# 1. Two processes start the same cook on one cache at once: between them
#    every node cooks exactly once (the sum of their "ran" totals is the node
#    count), and the one that waited says so.
# 2. A process cooking a slow node is killed (-9) while a second one waits
#    for it: the second takes the lease over (the holder's pid is gone) and
#    finishes the cook.
source "$(dirname "$0")/common.sh"
graph=$data/graphs/slow.lua

# 1. two at once
"$bin" run "$graph" --cache "$work/cache" --out "$work/o1" --set texture_size=2048 -j1 2> "$work/e1" &
p1=$!
"$bin" run "$graph" --cache "$work/cache" --out "$work/o2" --set texture_size=2048 -j1 2> "$work/e2" &
p2=$!
wait $p1 $p2
r1=$(ran_of "$work/o1/report.json")
r2=$(ran_of "$work/o2/report.json")
if [ $((r1 + r2)) -ne 2 ]; then
  echo "FAIL: two processes cooked $r1 + $r2 actions of 2"
  cat "$work/e1" "$work/e2"
  exit 1
fi
grep -q "^waiting for" "$work/e1" "$work/e2" || { echo "FAIL: neither process waited"; cat "$work/e1" "$work/e2"; exit 1; }
cmp "$work/o1/big.obj" "$work/o2/big.obj"
echo "two processes at once: $r1 + $r2 cooks of 2 actions"

# 2. the holder dies
"$bin" run "$graph" --cache "$work/cache2" --out "$work/o3" -j1 2> "$work/e3" &
holder=$!
for _ in $(seq 200); do grep -q "^cooked asset" "$work/e3" && break; sleep 0.05; done
grep -q "^cooked asset" "$work/e3" || { echo "FAIL: the holder never cooked its first node"; cat "$work/e3"; exit 1; }
"$bin" run "$graph" --cache "$work/cache2" --out "$work/o4" -j1 2> "$work/e4" &
waiter=$!
for _ in $(seq 100); do grep -q "^waiting for save" "$work/e4" && break; sleep 0.05; done
grep -q "^waiting for save" "$work/e4" || { echo "FAIL: the second process did not wait for save"; cat "$work/e4"; exit 1; }
kill -9 $holder
wait $holder 2>/dev/null || true
wait $waiter || { echo "FAIL: the waiter did not finish"; cat "$work/e4"; exit 1; }
grep -q "^taking over save" "$work/e4" || { echo "FAIL: no take-over"; cat "$work/e4"; exit 1; }
[ "$(ran_of "$work/o4/report.json")" = 1 ] || { echo "FAIL: the waiter should cook save alone"; cat "$work/e4"; exit 1; }
echo "the holder killed: the waiter took over and cooked"
