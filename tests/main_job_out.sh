#!/bin/bash
# main_job_out.sh SEAMCOOK CACHE OUT MAX_FILES MAX_MB [--corpus ASSET] [--set ...] - the main
# job (graphs/lod_chain.lua) with its default outputs, from the cache another
# test filled, and what --out then holds (issue 34: the assets and one
# report): asset.glb with every texture embedded, report.json, report.html,
# the pictures and mip levels 1 and down of each texture; no OBJ, MTL or EXR
# and no texture file beside the .glb (obj=1 and mip_files=all add them); at
# most MAX_FILES files and MAX_MB megabytes. ASSET: a corpus asset (under
# ../shared/corpus beside the project, or $SC_CORPUS) as the mesh. Exit 77
# when the cache is absent (the corpus job that fills it skipped).
set -u
bin=$1 cache=$2 out=$3 max_files=$4 max_mb=$5
shift 5
root=$(cd "$(dirname "$0")/.." && pwd)
mesh=()
if [ "${1:-}" = --corpus ]; then
  mesh=(--set mesh="${SC_CORPUS:-$root/../shared/corpus}/$2")
  shift 2
fi
[ -d "$cache" ] || { echo "$cache: no cache (its job skipped): skipped"; exit 77; }
rm -rf "$out"
"$bin" run "$root/graphs/lod_chain.lua" "${mesh[@]}" "$@" --cache "$cache" --out "$out" -q || exit $?
fail=0
bad() { echo "FAIL: $*" >&2; fail=1; }
for f in asset.glb report.json report.html; do [ -f "$out/$f" ] || bad "$f not written"; done
extra=$(cd "$out" && find . -type f \( -name '*.obj' -o -name '*.mtl' -o -name '*.exr' -o -name 'asset_*' \) | sort)
[ -z "$extra" ] || bad "files the default does not write: $extra"
level0=$(cd "$out" && find mip -name '*_level0.png' 2>/dev/null)
[ -z "$level0" ] || bad "mip level 0 files (the .glb holds level 0): $level0"
# every image the .glb holds (by the name save measured it under) has its mip chain beside it
images=$(/usr/bin/python3 - "$out/asset.glb" <<'PY'
import json, struct, sys
data = open(sys.argv[1], "rb").read()
n = struct.unpack_from("<I", data, 12)[0]
doc = json.loads(data[20:20 + n])
for im in doc.get("images", []):
    print(im.get("name", "?"))
PY
)
[ -n "$images" ] || bad "asset.glb holds no image"
for im in $images; do
  stem=${im#asset_}
  stem=${stem%.png}
  [ -f "$out/mip/${stem}_level1.png" ] || bad "asset.glb's image $im has no mip/${stem}_level1.png"
done
files=$(cd "$out" && find . -type f ! -name .seamcook-manifest | wc -l)
bytes=$(cd "$out" && find . -type f ! -name .seamcook-manifest -printf '%s\n' | awk '{s += $1} END {print s + 0}')
glb=$(stat -c %s "$out/asset.glb")
echo "$out: $files files, $bytes bytes ($glb in asset.glb)"
[ "$files" -le "$max_files" ] || bad "$files files, over $max_files"
[ "$bytes" -le $((max_mb * 1000000)) ] || bad "$bytes bytes, over $max_mb MB"
exit $fail
