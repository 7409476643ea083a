#!/usr/bin/env bash
# remote_server.sh SEAMCOOK WORKDIR nginx|lighttpd - the remote cache against
# a real HTTP server with WebDAV PUT (nginx, or lighttpd's mod_webdav),
# started here on a random loopback port with its own prefix and stopped at
# the end. Skipped (77) when the server, protoc or openssl is missing.
#
#  1. a checkout cooks and uploads; another checkout with a fresh local cache
#     cooks nothing: every lookup hits the remote
#  2. every action-cache entry decodes with protoc as a REAPI ActionResult,
#     and every output file it names is on the server with its digest and size
#  3. a blob changed on the server is caught, its action cooked again, and
#     the blob uploaded again over the bad copy
#  4. a blob removed from the server (evicted): its action cooks again
#  5. (nginx) credentials: a header (--remote-header), Basic (user:password
#     in the URL) and ~/.netrc; without them a clear 401, and a 403 for
#     uploads, the cook done
#  6. the server down: the cook completes with exactly one warning
#  7. two writers at once fill one prefix, then a fresh cache hits all
#  8. the project file (seamcook.conf) and SEAMCOOK_REMOTE_CACHE name the
#     remote; --remote-read-only uploads nothing
#  9. a 200 MB blob goes up and comes down whole
# 10. a client killed -9 while a 50 MB blob is part way onto the server
#     leaves nothing that serves: the entries finished before stay whole,
#     the cut action has none, and a fresh cache hits only those, cooks the
#     rest and gets the killed client's outputs
kind=${3:-nginx}
source "$(dirname "$0")/common.sh"
for tool in "$kind" protoc openssl sha256sum; do
  command -v "$tool" >/dev/null || { echo "SKIP: $tool is not installed (setup.sh test installs it)"; exit 77; }
done
proto=$data/reapi/action_result.proto

# ------------------------------------------------------------------ the server
srv=$work/server
prefixes="open token basic ro shared conf readonly big kill1 kill2 kill3"
for p in $prefixes; do mkdir -p "$srv/store/$p/cas" "$srv/store/$p/ac"; done   # lighttpd makes no folders on PUT
mkdir -p "$srv/body"
printf 'farm:%s\n' "$(openssl passwd -apr1 s3cret)" > "$srv/htpasswd"
write_nginx_conf() {
  cat > "$srv/server.conf" <<CONF
daemon off;
master_process off;
worker_processes 1;
pid $srv/server.pid;
error_log $srv/error.log;
events { worker_connections 64; }
http {
  access_log $srv/access.log;
  client_body_temp_path $srv/body;
  client_max_body_size 0;
  server {
    listen 127.0.0.1:$port;
    root $srv/store;
    dav_methods PUT;
    create_full_put_path on;
    location /token/ {
      if (\$http_authorization != "Bearer farm-token") { return 401; }
      dav_methods PUT;
      create_full_put_path on;
    }
    location /basic/ {
      auth_basic "cache";
      auth_basic_user_file $srv/htpasswd;
      dav_methods PUT;
      create_full_put_path on;
    }
    location /ro/ {
      limit_except GET HEAD { deny all; }
    }
  }
}
CONF
}
write_lighttpd_conf() {
  cat > "$srv/server.conf" <<CONF
server.document-root = "$srv/store"
server.bind = "127.0.0.1"
server.port = $port
server.errorlog = "$srv/error.log"
server.upload-dirs = ( "$srv/body" )
server.modules = ( "mod_webdav" )
webdav.activate = "enable"
webdav.is-readonly = "disable"
CONF
}
start_server() {
  for _ in 1 2 3 4 5 6 7 8; do
    port=$((20000 + RANDOM % 40000))
    if [ "$kind" = nginx ]; then
      write_nginx_conf
      nginx -p "$srv" -c "$srv/server.conf" -e "$srv/error.log" &
    else
      write_lighttpd_conf
      lighttpd -D -f "$srv/server.conf" &
    fi
    server_pid=$!
    for _ in $(seq 50); do
      if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then return 0; fi
      kill -0 $server_pid 2>/dev/null || break
      sleep 0.1
    done
    kill $server_pid 2>/dev/null || true
    wait $server_pid 2>/dev/null || true
  done
  echo "FAIL: $kind did not start"; cat "$srv/error.log"; exit 1
}
start_server
trap 'kill -CONT $server_pid 2>/dev/null; kill $server_pid 2>/dev/null || true' EXIT   # case 10 stops it
url=http://127.0.0.1:$port

fail() { echo "FAIL: $*"; exit 1; }
# a checkout: a graph and nothing else (its keys hold no absolute path)
checkout() {
  mkdir -p "$1"
  cat > "$1/graph.lua" <<'LUA'
local asset = procedural{ name = "asset", resolution = 8, texture_size = 128 }
local erased = erase_seams{ name = "erased", atlas = asset }
save{ name = "save", atlas = erased.atlas, file = "asset" }
LUA
}
# cook DIR CACHE [options]: a cook of DIR/graph.lua; its stderr in DIR/err
cook() {
  local dir=$1 cache=$2
  shift 2
  "$bin" run "$dir/graph.lua" --cache "$cache" --out "$dir/out" -j2 "$@" 2> "$dir/err"
}
hits_line() { grep '^remote cache:' "$1/err" || true; }

# ------------------------------------------------------------------ 1. a second checkout hits all
checkout "$work/a"
cook "$work/a" "$work/cache-a" --remote-cache "$url/open"
[ "$(ran_of "$work/a/out/report.json")" = 3 ] || fail "checkout a should cook 3 nodes"
grep -q "3 actions uploaded" "$work/a/err" || fail "checkout a should upload 3 actions: $(hits_line "$work/a")"
checkout "$work/b/deeper"
cook "$work/b/deeper" "$work/cache-b" --remote-cache "$url/open"
[ "$(ran_of "$work/b/deeper/out/report.json")" = 0 ] || fail "checkout b cooked: $(cat "$work/b/deeper/err")"
grep -q "3 of 3 lookups hit" "$work/b/deeper/err" || fail "checkout b: $(hits_line "$work/b/deeper")"
cmp "$work/a/out/asset.obj" "$work/b/deeper/out/asset.obj" || fail "the saved files differ"
echo "$kind 1. a fresh local cache: 3 of 3 lookups hit the remote another checkout filled, 0 cooked"

# ------------------------------------------------------------------ 2. ActionResult, decoded by protoc
# entries_whole PREFIX: every action-cache entry under PREFIX decodes as an
# ActionResult naming a record, and every output file it names is on the
# server with its digest and size; sets `entries` to how many there are
entries_whole() {
  local ac hash size f
  entries=0
  for ac in "$srv/store/$1/ac"/*; do
    [ -e "$ac" ] || continue
    protoc -I "$(dirname "$proto")" --decode=build.bazel.remote.execution.v2.ActionResult "$(basename "$proto")" \
      < "$ac" > "$work/decoded" || fail "protoc cannot decode $ac"
    grep -q 'path: "seamcook/action.json"' "$work/decoded" || fail "no record in $(cat "$work/decoded")"
    while read -r hash size; do
      f=$srv/store/$1/cas/$hash
      [ -f "$f" ] || fail "$1/ac/$(basename "$ac") names output $hash, which is not on the server"
      [ "$(sha256sum < "$f" | cut -d' ' -f1)" = "$hash" ] || fail "output $hash has other bytes"
      [ "$(stat -c %s "$f")" = "$size" ] || fail "output $hash: size_bytes $size, file $(stat -c %s "$f")"
    done < <(awk '/hash:/ {h=$2} /size_bytes:/ {gsub(/"/, "", h); print h, $2}' "$work/decoded")
    entries=$((entries + 1))
  done
}
entries_whole open
[ "$entries" = 3 ] || fail "expected 3 action-cache entries, found $entries"
echo "$kind 2. 3 action-cache entries decode as build.bazel.remote.execution.v2.ActionResult; every output file is on the server with its digest and size"

# ------------------------------------------------------------------ 3. a tampered blob
# the largest blob: the erased texture set
big=$(ls -S "$srv"/store/open/cas | head -n 1)
cp "$srv/store/open/cas/$big" "$work/good-blob"
printf '\xff' | dd of="$srv/store/open/cas/$big" bs=1 seek=100 conv=notrunc status=none
checkout "$work/c"
cook "$work/c" "$work/cache-c" --remote-cache "$url/open"
grep -q "; 1 blobs with wrong bytes" "$work/c/err" || fail "the tampered blob went unnoticed: $(cat "$work/c/err")"
[ "$(ran_of "$work/c/out/report.json")" -ge 1 ] || fail "nothing cooked again after the tampered blob"
cmp "$work/c/out/asset.obj" "$work/a/out/asset.obj" || fail "the cook over a tampered blob differs"
[ "$(sha256sum < "$srv/store/open/cas/$big" | cut -d' ' -f1)" = "$big" ] || fail "the tampered blob was not uploaded again"
echo "$kind 3. a tampered blob: caught, its action cooked again ($(ran_of "$work/c/out/report.json") nodes), the blob uploaded again"

# ------------------------------------------------------------------ 4. an evicted blob
rm "$srv/store/open/cas/$big"
checkout "$work/d"
cook "$work/d" "$work/cache-d" --remote-cache "$url/open"
[ "$(ran_of "$work/d/out/report.json")" -ge 1 ] || fail "an evicted blob did not cook again"
[ -f "$srv/store/open/cas/$big" ] || fail "the evicted blob was not uploaded again"
echo "$kind 4. an evicted blob: its action cooked again ($(ran_of "$work/d/out/report.json") nodes), the blob uploaded again"

# ------------------------------------------------------------------ 5. credentials (nginx)
if [ "$kind" = nginx ]; then
  checkout "$work/e"
  cook "$work/e" "$work/cache-e1" --remote-cache "$url/token" || fail "a 401 failed the cook"
  grep -q "401 Unauthorized" "$work/e/err" || fail "no clear 401: $(cat "$work/e/err")"
  [ "$(grep -c warning "$work/e/err")" = 1 ] || fail "more than one warning: $(cat "$work/e/err")"
  cook "$work/e" "$work/cache-e2" --remote-cache "$url/token" --remote-header "Authorization: Bearer farm-token"
  grep -q "3 actions uploaded" "$work/e/err" || fail "the header did not authorise: $(cat "$work/e/err")"
  cook "$work/e" "$work/cache-e3" --remote-cache "$url/token" --remote-header "Authorization: Bearer farm-token"
  grep -q "3 of 3 lookups hit" "$work/e/err" || fail "the header did not authorise lookups: $(cat "$work/e/err")"
  cook "$work/e" "$work/cache-e4" --remote-cache "http://farm:s3cret@127.0.0.1:$port/basic"
  grep -q "3 actions uploaded" "$work/e/err" || fail "Basic did not authorise: $(cat "$work/e/err")"
  cook "$work/e" "$work/cache-e5" --remote-cache "http://farm:wrong@127.0.0.1:$port/basic" || fail "a 401 failed the cook"
  grep -q "401 Unauthorized" "$work/e/err" || fail "no clear 401 for a wrong password: $(cat "$work/e/err")"
  grep -q "farm:wrong" "$work/e/err" && fail "the password is shown in a message"
  mkdir -p "$work/netrc-home"
  printf 'machine 127.0.0.1 login farm password s3cret\n' > "$work/netrc-home/.netrc"
  chmod 600 "$work/netrc-home/.netrc"
  HOME=$work/netrc-home cook "$work/e" "$work/cache-e7" --remote-cache "$url/basic"
  grep -q "3 of 3 lookups hit" "$work/e/err" || fail "~/.netrc did not authorise: $(cat "$work/e/err")"
  cook "$work/e" "$work/cache-e6" --remote-cache "$url/ro" || fail "a 403 failed the cook"
  grep -q "403 Forbidden" "$work/e/err" || fail "no clear 403: $(cat "$work/e/err")"
  echo "$kind 5. a header, Basic and ~/.netrc authorise; without them one clear warning (401 Unauthorized, 403 Forbidden) and the cook completes"
fi

# ------------------------------------------------------------------ 6. the server down
closed=$((port + 1))
checkout "$work/f"
t0=$(date +%s.%N)
cook "$work/f" "$work/cache-f" --remote-cache "http://127.0.0.1:$closed" --remote-timeout 2 --remote-retries 1 ||
  fail "a server down failed the cook"
t1=$(date +%s.%N)
[ "$(grep -c '^seamcook: warning' "$work/f/err")" = 1 ] || fail "expected one warning: $(cat "$work/f/err")"
[ "$(ran_of "$work/f/out/report.json")" = 3 ] || fail "the cook did not complete locally"
echo "$kind 6. the server down: one warning, 3 nodes cooked locally in $(awk "BEGIN {printf \"%.2f\", $t1 - $t0}") s"

# ------------------------------------------------------------------ 7. concurrent writers
checkout "$work/g1"
checkout "$work/g2"
cook "$work/g1" "$work/cache-g1" --remote-cache "$url/shared" & w1=$!
cook "$work/g2" "$work/cache-g2" --remote-cache "$url/shared" & w2=$!
wait $w1 || fail "writer 1 failed"
wait $w2 || fail "writer 2 failed"
checkout "$work/g3"
cook "$work/g3" "$work/cache-g3" --remote-cache "$url/shared"
grep -q "3 of 3 lookups hit" "$work/g3/err" || fail "after two writers: $(cat "$work/g3/err")"
echo "$kind 7. two writers at once, then a fresh cache: 3 of 3 lookups hit"

# ------------------------------------------------------------------ 8. project file, environment, read-only
checkout "$work/h"
printf '# the farm cache\nremote_cache = %s/conf\n' "$url" > "$work/h/seamcook.conf"
cook "$work/h" "$work/cache-h1"
grep -q "3 actions uploaded" "$work/h/err" || fail "seamcook.conf was not read: $(cat "$work/h/err")"
rm "$work/h/seamcook.conf"
SEAMCOOK_REMOTE_CACHE=$url/conf cook "$work/h" "$work/cache-h2"
grep -q "3 of 3 lookups hit" "$work/h/err" || fail "SEAMCOOK_REMOTE_CACHE was not read: $(cat "$work/h/err")"
printf 'remote_cache = %s/conf\nremote_cachee = x\n' "$url" > "$work/h/seamcook.conf"
if cook "$work/h" "$work/cache-h3"; then fail "a bad project file was accepted"; fi
grep -q "seamcook.conf:2: unknown setting 'remote_cachee'" "$work/h/err" || fail "bad project file: $(cat "$work/h/err")"
rm "$work/h/seamcook.conf"
before=$(find "$srv/store" -type f | wc -l)
cook "$work/h" "$work/cache-h4" --remote-cache "$url/readonly" --remote-read-only
[ "$(find "$srv/store" -type f | wc -l)" = "$before" ] || fail "--remote-read-only uploaded"
echo "$kind 8. seamcook.conf and SEAMCOOK_REMOTE_CACHE name the remote; a bad setting names file:line; --remote-read-only uploads nothing"

# ------------------------------------------------------------------ 9. a 200 MB blob
mkdir -p "$work/big1" "$work/big2"
for d in big1 big2; do
  echo 'procedural{ name = "asset", resolution = 16, texture_size = 8192 }' > "$work/$d/graph.lua"
done
cook "$work/big1" "$work/cache-big1" --remote-cache "$url/big"
size=$(ls -S -l "$srv/store/big/cas" | awk 'NR == 2 {print $5}')
[ "$size" -ge 200000000 ] || fail "the largest blob is $size bytes, not 200 MB"
cook "$work/big2" "$work/cache-big2" --remote-cache "$url/big"
grep -q "1 of 1 lookups hit" "$work/big2/err" || fail "the 200 MB blob did not come down: $(cat "$work/big2/err")"
echo "$kind 9. a $((size / 1000000)) MB blob up and down: $(hits_line "$work/big2")"

# ------------------------------------------------------------------ 10. a client killed mid-upload
# The client cooks with -j1 in creation order: small and save (whole on the
# server a few seconds later) and then big, a 4096^2 texture (a 50 MB blob).
# Its uploads go in that order, per action blobs first, then the record,
# then the ActionResult. The kill lands at the worst moment for a partial
# entry: the server, throttled by SIGSTOP and SIGCONT, is caught stopped
# while it writes a request body of more than 1 MB, so big's texture is in
# flight and part of it on the server; then the client is killed -9 and the
# server resumed. What serves
# afterwards must be whole: the two finished entries, and nothing of big.
# (Were the ActionResult put before the blobs, big's entry would name a blob
# the server lacks, and entries_whole fails.) An upload that runs whole
# between two looks tries again on a fresh prefix, three times at most.
kill_graph() {
  mkdir -p "$1"
  cat > "$1/graph.lua" <<'LUA'
local small = procedural{ name = "small", resolution = 8, texture_size = 128 }
save{ name = "save", atlas = small, file = "small" }
procedural{ name = "big", resolution = 16, texture_size = 4096 }
LUA
}
# in_flight: the size of a request body over 1 MB that the server is writing
# for prefix $p: nginx's file under client_body_temp_path, or lighttpd's
# unnamed file in the target folder (linked in when the body is whole). The
# server keeps other files open (lighttpd: blobs it served), hence the names.
in_flight() {
  local fd
  # (fds come and go while find reads them: its complaints are ignored)
  for fd in $(find -L "/proc/$server_pid/fd" -type f -size +1M 2>/dev/null || true); do
    case $(readlink "$fd" || true) in
      "$srv/body/"* | "$srv/store/$p/"*" (deleted)") stat -L -c %s "$fd" 2>/dev/null && return 0 ;;
    esac
  done
  return 0
}
caught=
for try in 1 2 3; do
  p=kill$try
  kill_graph "$work/k$try"
  "$bin" run "$work/k$try/graph.lua" --cache "$work/cache-k$try" --out "$work/k$try/out" -j1 \
    --remote-cache "$url/$p" 2> "$work/k$try/err" & client=$!
  # the server throttled while the client runs: 10 ms running, then stopped
  # while we look (and 30 ms more), so a 50 MB body takes a good part of a
  # second and is seen in flight; a look at a stopped server is a snapshot
  partial=
  while kill -0 $client 2>/dev/null; do
    sleep 0.01
    kill -STOP $server_pid
    partial=$(in_flight)
    [ -n "$partial" ] && break
    sleep 0.03
    kill -CONT $server_pid
  done
  if [ -n "$partial" ]; then
    kill -9 $client
    wait $client 2>/dev/null || true
    kill -CONT $server_pid
    for _ in $(seq 50); do [ -z "$(in_flight)" ] && break; sleep 0.1; done
    [ -z "$(in_flight)" ] || fail "the server still holds the killed upload's body open"
    # a look can catch a body whose last byte is in but not yet linked: the
    # server then stores the whole blob, and the kill was not mid-upload
    if [ -z "$(find "$srv/store/$p/cas" -type f -size +1M 2>/dev/null)" ]; then
      caught=$try
      break
    fi
    echo "$kind 10. try $try: the look caught big's body whole; again on a fresh prefix"
    continue
  fi
  wait $client || fail "the client failed: $(cat "$work/k$try/err")"
  echo "$kind 10. try $try: big's upload ran whole between two looks; again on a fresh prefix"
done
[ -n "$caught" ] || fail "three tries and the kill never landed mid-upload"
p=kill$caught
entries_whole "$p"
[ "$entries" = 2 ] || fail "expected the 2 entries finished before the kill, found $entries"
for f in "$srv/store/$p/cas"/*; do
  [ "$(sha256sum < "$f" | cut -d' ' -f1)" = "$(basename "$f")" ] || fail "$p/cas holds a partial blob $(basename "$f")"
done
# a fresh checkout with an empty local cache: hits the two whole entries,
# never follows an entry to a blob the server lacks, and cooks big
kill_graph "$work/k-fresh"
[ "$kind" = nginx ] && : > "$srv/access.log"
cook "$work/k-fresh" "$work/cache-k-fresh" --remote-cache "$url/$p"
grep -q "2 of 3 lookups hit" "$work/k-fresh/err" || fail "after the kill: $(hits_line "$work/k-fresh")"
[ "$(ran_of "$work/k-fresh/out/report.json")" = 1 ] || fail "after the kill, expected big alone to cook"
if [ "$kind" = nginx ] && grep -q "GET /$p/cas/[0-9a-f]* [^ ]* 404" "$srv/access.log"; then
  fail "a lookup followed an entry to a missing blob: $(grep " 404 " "$srv/access.log")"
fi
# correct results: the outputs the killed client had cooked (read back from
# its local cache, no remote), digest for digest
"$bin" run "$work/k$caught/graph.lua" --cache "$work/cache-k$caught" --out "$work/k$caught/again" -j1 2> /dev/null
[ "$(ran_of "$work/k$caught/again/report.json")" = 0 ] || fail "the killed client's local cache lost its results"
digests_of() { grep -o '"digest":[[:space:]]*"[0-9a-f]*"' "$1" | tr -d '[:space:]'; }
[ "$(digests_of "$work/k-fresh/out/report.json")" = "$(digests_of "$work/k$caught/again/report.json")" ] ||
  fail "the outputs after the kill differ from the killed client's"
cmp "$work/k-fresh/out/small.obj" "$work/k$caught/again/small.obj" || fail "the saved files differ"
entries_whole "$p"
[ "$entries" = 3 ] || fail "after the fresh cook's upload, expected 3 whole entries, found $entries"
whole=$(ls -S -l "$srv/store/$p/cas" | awk 'NR == 2 {print $5}')
[ "$partial" -lt "$whole" ] || fail "the stopped body ($partial bytes) was not partial (the blob: $whole bytes)"
echo "$kind 10. a client killed -9 with $((partial / 1000000)) of $((whole / 1000000)) MB of a blob on the server (try $caught): 2 whole entries serve, nothing of the third; a fresh cache: $(hits_line "$work/k-fresh" | cut -d';' -f1), big cooked, outputs equal the killed client's"
