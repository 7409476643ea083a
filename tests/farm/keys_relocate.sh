#!/usr/bin/env bash
# keys_relocate.sh SEAMCOOK WORKDIR - node keys do not depend on where a
# checkout lies or on the environment it cooks in.
#
# One graph and one asset (an OBJ with its MTL and PNG, made by a first cook)
# are copied into two checkouts at different depths. Each is cooked with its
# own cache, under a different HOME, TMPDIR, PATH, working folder and locale,
# and every node's key in the two report.json files must be the same. Then a
# third checkout cooks with a copy of the first one's cache: every node is a
# hit (its recorded source files are found relative to the graph's folder),
# and after one texture byte changes, the loader and what follows it cook.
source "$(dirname "$0")/common.sh"

"$bin" run "$data/graphs/proc_save.lua" --cache "$work/make-cache" --out "$work/made" -q
for co in "$work/a/project" "$work/b/deeper/checkout/project"; do
  mkdir -p "$co/assets"
  cp "$work"/made/asset.obj "$work"/made/asset.mtl "$work"/made/asset_*.png "$co/assets/"
  cat > "$co/graph.lua" <<'LUA'
local asset = load_atlas{ name = "load", path = param("mesh", "assets/asset.obj") }
local erased = erase_seams{ name = "erased", atlas = asset }
local lods = decimate{ name = "lods", mesh = erased.atlas, ratio = {0.5}, hausdorff_samples = 0 }
local chain = share_textures{ name = "chain", lods = lods, atlas = erased.atlas }
render{ name = "check", lods = chain, reference = erased.atlas, size = 64, views = 2, modes = "textured",
        folder = "render" }
save{ name = "save", atlas = erased.atlas, file = "out" }
LUA
done


mkdir -p "$work/homeA" "$work/tmpA" "$work/homeB/x" "$work/tmpB/y" "$work/bin"
# OpenBLAS's variables stay: OPENBLAS_CORETYPE picks the BLAS kernels, which
# the keys rightly follow (the sparse kernel's platform text), and the runs
# below outside `env -i` see them too
mapfile -t blas_env < <(env | grep '^OPENBLAS_' || true)
(cd "$work/a/project" &&
  env -i "${blas_env[@]}" HOME="$work/homeA" TMPDIR="$work/tmpA" PATH=/usr/bin:/bin LC_ALL=C \
    "$bin" run graph.lua --cache "$work/cache-a" --out "$work/out-a" -q -j2)
(cd "$work/b/deeper" &&
  env -i "${blas_env[@]}" HOME="$work/homeB/x" TMPDIR="$work/tmpB/y" PATH="$work/bin:/usr/local/bin:/usr/bin:/bin" LANG=C.UTF-8 LC_ALL=C.UTF-8 \
    "$bin" run checkout/project/graph.lua --set mesh=checkout/project/assets/asset.obj \
    --cache "$work/cache-b" --out "$work/out-b" -q -j1)
keys_of "$work/out-a/report.json" > "$work/keys-a"
keys_of "$work/out-b/report.json" > "$work/keys-b"
n=$(wc -l < "$work/keys-a")
[ "$n" -eq 6 ] || { echo "expected 6 node keys, found $n"; cat "$work/keys-a"; exit 1; }
if ! diff "$work/keys-a" "$work/keys-b"; then
  echo "FAIL: node keys differ between the two checkouts"
  exit 1
fi
echo "6 node keys equal in both checkouts"

# --base-dir: the graph's folder named explicitly gives the same keys
cd "$work/b/deeper/checkout/project"
"$bin" run "$work/b/deeper/checkout/project/graph.lua" --base-dir "$work/b/deeper/checkout/project" \
  --cache "$work/cache-b" --out "$work/out-b2" -q
keys_of "$work/out-b2/report.json" | diff "$work/keys-a" - || { echo "FAIL: --base-dir changed the keys"; exit 1; }
# another base folder moves the path in the loader's key
cd "$work/b/deeper/checkout/project"
"$bin" run "$work/b/deeper/checkout/project/graph.lua" --base-dir "$work/b" --cache "$work/cache-b" --out "$work/out-b3" -q
[ "$(keys_of "$work/out-b3/report.json" | grep '^load ')" != "$(grep '^load ' "$work/keys-a")" ] ||
  { echo "FAIL: the loader's key ignores the base folder"; exit 1; }

# a cache filled by checkout a serves a third checkout: nothing cooks
mkdir -p "$work/c/project"
cp -r "$work/a/project/." "$work/c/project/"
cp -r "$work/cache-a" "$work/cache-c"
cd "$work/c/project"
"$bin" run "$work/c/project/graph.lua" --cache "$work/cache-c" --out "$work/out-c" -q --json > "$work/c.json"
[ "$(ran_of "$work/c.json")" = 0 ] ||
  { echo "FAIL: the copied cache did not serve the moved checkout"; cat "$work/c.json"; exit 1; }
# a texture changes in the moved checkout: the loader cooks again
printf 'x' >> "$work/c/project/assets/asset_default_color.png"
"$bin" run "$work/c/project/graph.lua" --cache "$work/cache-c" --out "$work/out-c2" -q --json > "$work/c2.json" 2>&1 || true
[ "$(ran_of "$work/c2.json")" -ge 1 ] || { echo "FAIL: a changed texture went unnoticed"; cat "$work/c2.json"; exit 1; }
echo "a moved checkout hits a copied cache; a changed texture re-cooks"
