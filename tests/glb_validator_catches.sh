#!/bin/bash
# glb_validator_catches.sh VALIDATOR_DIR GLB TMPDIR - the .glb validation can
# fail: GLB cut 1,000 bytes short must be refused (this test then passes).
# Skipped (77) where glb_validate.sh is.
set -u
mkdir -p "$3"
bad=$3/cut_short.glb
head -c -1000 "$2" > "$bad"
bash "$(dirname "$0")/glb_validate.sh" "$1" "$bad"
case $? in
  77) exit 77 ;;
  1) echo "the cut .glb is refused, as it must be"; exit 0 ;;
  *) echo "the validator accepted a .glb cut short"; exit 1 ;;
esac
