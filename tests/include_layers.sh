#!/usr/bin/env bash
# include_layers.sh ROOT - checks the include graph of the sources against the
# layers of docs/design.md: each folder includes only headers of the folders
# it may see, and no chain of includes comes back to where it started.
#
#   base/       base
#   cache/      base cache
#   nodes/lib/  base nodes/lib
#   runtime/    base cache runtime
#   nodes/      base nodes/lib nodes, and of runtime/ the node API sc_node.h alone
#   app/        everything
#
# Headers are found by name in those folders (every header name is unique).
# Prints each upward arrow or cycle and exits 1 when there is one.
set -euo pipefail
root=${1:-.}
cd "$root"
folders="base cache nodes/lib runtime nodes app"

# "file header" for every quoted include of the project's own headers
edges=$(for d in $folders; do
  for f in "$d"/*.c "$d"/*.h "$d"/*.cpp; do
    [ -f "$f" ] || continue
    sed -n 's/^[[:space:]]*#[[:space:]]*include[[:space:]]*"\([^"]*\)".*/\1/p' "$f" | while read -r h; do
      echo "$f $h"
    done
  done
done)

awk -v folders="$folders" '
function folder_of(path,   n, parts) {
  n = split(path, parts, "/")
  return n > 2 ? parts[1] "/" parts[2] : parts[1]
}
BEGIN {
  allowed["base"] = " base "
  allowed["cache"] = " base cache "
  allowed["nodes/lib"] = " base nodes/lib "
  allowed["runtime"] = " base cache runtime "
  allowed["nodes"] = " base nodes/lib nodes "
  allowed["app"] = " base cache nodes/lib runtime nodes app "
  nf = split(folders, fl, " ")
  for (i = 1; i <= nf; i++) {
    cmd = "ls " fl[i] " 2>/dev/null"
    while ((cmd | getline name) > 0) if (name ~ /\.h$/) home[name] = fl[i]
    close(cmd)
  }
  bad = 0
}
{
  from = $1; h = $2
  sub(/^.*\//, "", h)
  if (!(h in home)) next            # generated (sc_shaders) or system-like headers
  f = folder_of(from)
  to = home[h]
  ok = index(allowed[f], " " to " ") > 0
  if (f == "nodes" && to == "runtime") ok = (h == "sc_node.h")
  if (!ok) { print "upward or sideways include: " from " -> " to "/" h; bad = 1 }
  base = from; sub(/^.*\//, "", base)
  if (base ~ /\.h$/) { adj[base] = adj[base] " " h }
}
function visit(node,   n, parts, i) {
  state[node] = 1; stack[++depth] = node
  n = split(adj[node], parts, " ")
  for (i = 1; i <= n; i++) {
    if (state[parts[i]] == 1) { print "include cycle through " node " -> " parts[i]; bad = 1 }
    else if (state[parts[i]] == 0) visit(parts[i])
  }
  state[node] = 2; depth--
}
END {
  for (node in adj) if (!state[node]) visit(node)
  if (bad) exit 1
  print "include graph: no upward arrow, no cycle"
}' <<<"$edges"
