#!/usr/bin/env bash
# bench_main_job.sh - the main job's wall time on corpus assets, cold, with
# where it goes, beside gltfpack on the same asset.
#
#   bench/bench_main_job.sh [SEAMCOOK [ASSET ...]]
#
# SEAMCOOK defaults to build/seamcook; ASSETs are paths under the corpus
# (../shared/corpus or $SC_CORPUS), each optionally followed by
# ",texture=PATH" (also under the corpus) for a model that names no texture
# of its own. By default: Avocado/Avocado.gltf (682 faces),
# WaterBottle/WaterBottle.gltf, and blub/blub.obj with its 2048^2
# blub_texture.png (14,208 faces: the size class of an 18k-face asset at
# 2048^2). For each asset:
#
# 1. `seamcook run graphs/lod_chain.lua --set mesh=ASSET` with the defaults,
#    each time into a fresh cache and output folder, RUNS times (3; $RUNS):
#    the wall time of every run, the best, and for the best run each node's
#    seconds and each decimated level's faces against its target (with the
#    level's Hausdorff distance) from report.json;
# 2. gltfpack (npm gltfpack 1.3.0, a WebAssembly build of meshoptimizer's
#    gltfpack; installed under build/gltfpack when npm is present, or
#    $GLTFPACK) on the same asset with -si 0.1 (one level at 10% of the
#    triangles), best of RUNS. It is a peer for speed only: it simplifies
#    and packs, and erases no seam, keeps no seam-free mip chain and checks
#    no crack.
#
# Not run by ctest: a run takes 10-30 s per asset on 2 cores. The seconds
# vary with the machine's load; compare runs made side by side.
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$root/build/seamcook}
shift || true
corpus=${SC_CORPUS:-$root/../shared/corpus}
runs=${RUNS:-3}
assets=("$@")
[ ${#assets[@]} -gt 0 ] ||
  assets=(Avocado/Avocado.gltf WaterBottle/WaterBottle.gltf blub/blub.obj,texture=blub/blub_texture.png)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

gltfpack=${GLTFPACK:-$root/build/gltfpack/node_modules/.bin/gltfpack}
if [ ! -x "$gltfpack" ] && command -v npm >/dev/null; then
  npm install --prefix "$root/build/gltfpack" --no-audit --no-fund gltfpack@1.3.0 >/dev/null 2>&1
fi
[ -x "$gltfpack" ] || gltfpack=""

now() { date +%s.%N; }

for spec in "${assets[@]}"; do
  asset=${spec%%,*}
  texture=()
  case $spec in *,texture=*) texture=(--set texture="$corpus/${spec#*,texture=}") ;; esac
  if [ ! -e "$corpus/$asset" ]; then
    echo "$asset: not found under $corpus: skipped"
    continue
  fi
  echo "== $spec"
  best="" best_dir=""
  for r in $(seq 1 "$runs"); do
    dir=$work/run$r
    rm -rf "$dir"
    t0=$(now)
    "$bin" run "$root/graphs/lod_chain.lua" --set mesh="$corpus/$asset" "${texture[@]}" --cache "$dir/cache" --out "$dir/out" -q \
      2>"$dir.err"
    rc=$?
    t=$(echo "$(now) - $t0" | bc)
    printf '  seamcook run %d: %.2f s (exit %d)\n' "$r" "$t" "$rc"
    if [ -z "$best" ] || [ "$(echo "$t < $best" | bc)" = 1 ]; then
      best=$t best_dir=$dir
    fi
  done
  printf '  seamcook best: %.2f s\n' "$best"
  /usr/bin/python3 - "$best_dir/out/report.json" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
print("  nodes of the best run (seconds; nodes without a path between them cook side by side):")
for n in r["nodes"]:
    print("    %-12s %-18s %7.3f" % (n["name"], n["type"], n.get("seconds") or 0.0))
for n in r["nodes"]:
    if n["type"] != "decimate":
        continue
    m = n.get("metrics", {})
    print("  levels of %s (faces against the target; issue 32 asks for 1.2x at most):" % n["name"])
    k = 0
    while "lod%d.faces" % k in m:
        faces, target = m["lod%d.faces" % k], m.get("lod%d.target_faces" % k, 0)
        print("    lod%d  %7d faces for %7d  %5.2fx  Hausdorff %.2f%%" % (
            k, faces, target, faces / target if target else 0, 100 * m.get("lod%d.hausdorff" % k, 0)))
        k += 1
EOF
  if [ -n "$gltfpack" ]; then
    gbest=""
    for r in $(seq 1 "$runs"); do
      t0=$(now)
      "$gltfpack" -i "$corpus/$asset" -o "$work/pack.glb" -si 0.1 >/dev/null 2>&1
      t=$(echo "$(now) - $t0" | bc)
      if [ -z "$gbest" ] || [ "$(echo "$t < $gbest" | bc)" = 1 ]; then gbest=$t; fi
    done
    printf '  gltfpack -si 0.1 best: %.3f s (%s bytes)\n' "$gbest" "$(stat -c %s "$work/pack.glb" 2>/dev/null)"
  else
    echo "  gltfpack: not installed (npm absent): no peer"
  fi
done
