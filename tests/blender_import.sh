#!/bin/bash
# blender_import.sh OUT - Debian's Blender (headless) imports OUT/asset.glb
# and tests/blender_import.py checks the scene against the OBJ and PNG files
# beside it. Skipped (exit status 77) where Blender is not installed
# (`setup.sh test` installs it).
set -u
command -v blender >/dev/null || { echo "blender not installed: skipped"; exit 77; }
[ -f "$1/asset.glb" ] || { echo "$1/asset.glb: no such file"; exit 1; }
root=$(cd "$(dirname "$0")/.." && pwd)
exec blender -b --factory-startup --python-exit-code 1 --python "$root/tests/blender_import.py" -- "$1"
