#!/usr/bin/env bash
# seamcook setup: installs what is missing (Debian 12, as root), builds, and then
#   ./setup.sh          cooks graphs/lod_chain.lua on the procedural asset and says where the results are
#   ./setup.sh test     runs the whole test suite (unit tests, graph tests, sanitizers, a short fuzz run)
#   ./setup.sh farm-test  installs Slurm and munge and runs the farm tests (tests/farm) on a
#                       single-node cluster that the Slurm test starts on localhost
set -euo pipefail
cd "$(dirname "$0")"
mode=${1:-demo}
jobs=$(nproc 2>/dev/null || echo 2)

packages=(build-essential cmake pkg-config libuv1-dev libsqlite3-dev liblua5.4-dev
  libsuitesparse-dev libopenblas0-pthread libopenimageio-dev libopencv-core-dev
  libopenexr-dev libdeflate-dev libegl-dev libgles-dev libgl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri libgbm-dev
  libssl-dev libcjson-dev libcurl4-openssl-dev libmeshoptimizer-dev openimageio-tools clang libclang-rt-14-dev chromium)

# what the tests add: nginx and lighttpd (WebDAV) and protoc for the remote-cache tests, openssl for
# their password file; Blender (with numpy, its glTF importer's) to import the main job's .glb
if [ "$mode" = test ] || [ "$mode" = farm-test ]; then
  packages+=(nginx-light lighttpd lighttpd-mod-webdav protobuf-compiler openssl blender python3-numpy)
fi
if [ "$mode" = farm-test ]; then
  packages+=(slurm-wlm munge)
fi

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "installing: ${missing[*]}"
  if [ "$(id -u)" != 0 ]; then
    echo "setup.sh: these Debian packages are missing and installing them needs root: ${missing[*]}" >&2
    exit 1
  fi
  apt-get update -q
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

cmake -S . -B build -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSC_WERROR=ON >/dev/null
cmake --build build -j"$jobs"

case "$mode" in
demo)
  out=out/lod_chain
  ./build/seamcook run graphs/lod_chain.lua --cache build/cache --out "$out"
  echo
  echo "results: $PWD/$out"
  echo "report:  $PWD/$out/report.json"
  ;;
test)
  # 0. the Khronos glTF-Validator for the .glb test, where npm is present (else that test is skipped)
  if command -v npm >/dev/null && [ ! -d build/gltf-validator/node_modules/gltf-validator ]; then
    npm install --prefix build/gltf-validator --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 >/dev/null 2>&1 ||
      echo "gltf-validator could not be installed: the .glb validation test is skipped"
  fi
  # 1. every unit test and graph test, optimised build
  ctest --test-dir build -j"$jobs" --output-on-failure
  # 2. the unit tests again under AddressSanitizer and UndefinedBehaviorSanitizer
  cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=Debug -DSC_WERROR=ON -DSC_SANITIZE=ON >/dev/null
  cmake --build build-asan -j"$jobs"
  # On some machines LeakSanitizer's stop-the-world tracer crashes at exit while it
  # scans threads that libraries start and keep (OpenBLAS's worker for CHOLMOD's
  # BLAS, llvmpipe's rasteriser threads; docs/notes/build.md). Our own threads are
  # what this run checks; those libraries run on the calling thread. (Its scan of
  # dynamic TLS: CMakeLists.txt's LSAN_OPTIONS.)
  asan_ctest() {
    OPENBLAS_NUM_THREADS=1 LP_NUM_THREADS=0 ASAN_OPTIONS=detect_leaks=1:abort_on_error=0 UBSAN_OPTIONS=print_stacktrace=1 \
      ctest --test-dir build-asan -j"$jobs" --output-on-failure "$@"
  }
  if ! asan_ctest -R '^test_' > build-asan/ctest.log 2>&1; then
    cat build-asan/ctest.log
    # LeakSanitizer's own stop-the-world tracer now and then crashes at exit after
    # every check passed (google/sanitizers#1353): that, and only that, earns one rerun
    # of the failed tests; a real failure fails again
    grep -q "LeakSanitizer has encountered a fatal error" build-asan/ctest.log || exit 1
    echo "LeakSanitizer's tracer crashed at exit: rerunning the failed tests once"
    asan_ctest --rerun-failed
  else
    cat build-asan/ctest.log
  fi
  # 3. a short run of each parser fuzzer over the checked-in seeds
  if ls tests/fuzz/fuzz_*.c >/dev/null 2>&1; then
    CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSC_FUZZ=ON >/dev/null
    cmake --build build-fuzz -j"$jobs" --target $(cd tests/fuzz && ls fuzz_*.c | sed 's/\.c$//')
    for f in tests/fuzz/fuzz_*.c; do
      name=$(basename "$f" .c)
      seeds=tests/data/${name#fuzz_}
      mkdir -p build-fuzz/corpus-$name
      ./build-fuzz/$name -max_total_time="${SC_FUZZ_SECONDS:-20}" -timeout=10 \
        build-fuzz/corpus-$name $( [ -d "$seeds" ] && echo "$seeds" ) 2>&1 | tail -n 3
    done
  fi
  echo "all tests passed"
  ;;
farm-test)
  # keys across checkouts, leases, the remote cache on nginx and lighttpd, and
  # farm submit/status on a Slurm cluster of one node (started by the test)
  ctest --test-dir build --output-on-failure -R '^farm_'
  echo "farm tests passed"
  ;;
*)
  echo "usage: ./setup.sh [test|farm-test]" >&2
  exit 2
  ;;
esac
