# common.sh - sourced by the farm tests: `bin` (the seamcook command, absolute)
# and `work` (a fresh folder, absolute) from the test's two arguments, and
# helpers that read a run's report.
set -eEuo pipefail
# a command that fails outside a check says where
trap 'echo "FAIL: ${BASH_SOURCE[0]##*/}:$LINENO: $BASH_COMMAND exited $?"' ERR
bin=$(realpath "$1")
work=$2
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")
data=$(realpath "$(dirname "${BASH_SOURCE[0]}")/../data")

# how many nodes cooked, from a report.json (or --json output)
ran_of() { sed -n 's/^[[:space:]]*"ran":[[:space:]]*\([0-9]*\).*/\1/p' "$1" | head -n 1; }
# "name key" per node, from a report.json
keys_of() { awk -F'"' '/^\t\t\t"name":/ {n=$4} /^\t\t\t"key":/ {print n, $4}' "$1"; }
