#!/bin/bash
# glb_validate.sh VALIDATOR_DIR [--corpus] FILE... - the Khronos
# glTF-Validator (npm gltf-validator, installed under VALIDATOR_DIR by
# `setup.sh test` where npm is present) on every .glb or .gltf given: 0 errors and 0
# warnings, or the test fails. Without node or the validator it is skipped
# (exit status 77). A missing .glb fails, except with --corpus, where the
# main jobs that write them skip without the corpus (then so does this).
set -u
dir=$1
shift
corpus=0
if [ "${1:-}" = --corpus ]; then corpus=1; shift; fi
root=$(cd "$(dirname "$0")/.." && pwd)
if ! command -v node >/dev/null || [ ! -d "$dir/node_modules/gltf-validator" ]; then
  echo "gltf-validator not installed under $dir (setup.sh test installs it where npm is present): skipped"
  exit 77
fi
files=()
for f in "$@"; do
  if [ -f "$f" ]; then files+=("$f")
  elif [ $corpus = 0 ]; then echo "$f: no such file"; exit 1
  else echo "$f: not written (corpus absent?)"
  fi
done
[ ${#files[@]} -gt 0 ] || { echo "no .glb to validate: skipped"; exit 77; }
exec env NODE_PATH="$dir/node_modules" node "$root/tests/glb_validate.cjs" "${files[@]}"
