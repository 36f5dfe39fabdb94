#!/usr/bin/env bash
# Builds the fuzzers (fuzz_obj, fuzz_off, fuzz_ply, fuzz_rig, fuzz_vdb, fuzz_archive) with clang
# in build-fuzz/ and runs each one for a number of seconds on a copy of the seed corpus in
# tests/fuzz/corpus/.
#
#   tests/fuzz/run.sh [SECONDS]        (default: $FUZZ_SECONDS, else 60)
#
# Environment: FUZZ_SECONDS, FUZZ_BUILD_DIR (default <repo>/build-fuzz), FUZZ_JOBS (build
# parallelism, default 2), FUZZ_TARGETS (default "obj off ply rig vdb archive").
# Exits non-zero when a fuzzer reports a finding (crash, sanitizer error, leak, timeout); the
# reproducer is saved in $FUZZ_BUILD_DIR/fuzz-artifacts/<format>/.
set -euo pipefail

seconds="${1:-${FUZZ_SECONDS:-60}}"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
build="${FUZZ_BUILD_DIR:-$root/build-fuzz}"
jobs="${FUZZ_JOBS:-2}"
targets="${FUZZ_TARGETS:-obj off ply rig vdb archive}"

# -O1 -g1 (line tables only; libFuzzer's documentation builds with -O1): the sanitizers check the
# same and stack traces keep file and line, for less compile time than -O2 -g (fuzz_vdb's
# volume/warp_volume.cpp: 142 instead of 167 CPU seconds).
cmake -S "$root" -B "$build" -G Ninja \
  -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -g1 -DNDEBUG" \
  -DSPACEWARP_BUILD_FUZZERS=ON \
  -DSPACEWARP_BUILD_TESTS=OFF \
  -DSPACEWARP_BUILD_APPS=OFF \
  -DSPACEWARP_BUILD_BENCHMARKS=OFF >/dev/null

build_targets=()
for format in $targets; do build_targets+=("fuzz_$format"); done
ninja -C "$build" -j "$jobs" "${build_targets[@]}"

status=0
findings=()
for format in $targets; do
  corpus="$build/fuzz-corpus/$format"
  artifacts="$build/fuzz-artifacts/$format/"
  mkdir -p "$corpus" "$artifacts"
  max_len=4096 leaks=1 rss=2048 timeout=10
  # A rig may ask for a solve of a few seconds within the memory cap (a 500-node graph that
  # does not converge in 50 iterations: ~2 s in a release build, 5-10 times that here).
  if [[ "$format" == rig ]]; then timeout=60; fi
  # A valid archive of a small cage or RBF fit is a few kilobytes; a loaded lazy RBF fit solves.
  if [[ "$format" == archive ]]; then max_len=16384 timeout=60; fi
  # The smallest VDB file is about 10 kB (the masks of a tree's internal nodes are raw bytes),
  # and OpenVDB's readTopology leaks the nodes it had read when a malformed file makes it throw:
  # those leaks pile up over a run (about 2 GB in 40 s), so the vdb target gets more room.
  # LeakSanitizer's own check at exit is off for it too (ASAN_OPTIONS): every leak it reports
  # there is a node OpenVDB's readTopology allocated before throwing.
  asan_options="${ASAN_OPTIONS:-}"
  if [[ "$format" == vdb ]]; then max_len=32768 leaks=0 rss=8192 asan_options="detect_leaks=0"; fi
  log="$build/fuzz-logs/$format.log"
  mkdir -p "$(dirname "$log")"
  echo "== fuzz_$format for ${seconds}s"
  if ! ASAN_OPTIONS="$asan_options" "$build/tests/fuzz/fuzz_$format" \
      -max_total_time="$seconds" -max_len="$max_len" -detect_leaks="$leaks" -timeout="$timeout" -rss_limit_mb="$rss" \
      -print_final_stats=1 -artifact_prefix="$artifacts" \
      "$corpus" "$root/tests/fuzz/corpus/$format" 2>&1 | tee "$log"; then
    echo "fuzz_$format: FINDING (reproducer in $artifacts)" >&2
    findings+=("$format")
    status=1
  fi
done
# The findings again at the very end, where a log cut to its tail (CI's) still shows them: the
# sanitizer's or libFuzzer's report, its first stack frames and the reproducer's bytes.
for format in "${findings[@]}"; do
  echo "== FINDING of fuzz_$format (full output: $build/fuzz-logs/$format.log)" >&2
  grep -m1 -A 30 -E '^==[0-9]+== *ERROR|ERROR: libFuzzer|^SUMMARY|runtime error' \
    "$build/fuzz-logs/$format.log" | grep -vE '^ *#([3-9][0-9]|2[0-9])' >&2 || true
  for crash in "$build/fuzz-artifacts/$format"/*; do
    if [[ -f "$crash" ]]; then
      echo "$crash:" >&2
      head -c 600 "$crash" | od -c | head -20 >&2
    fi
  done
done
exit "$status"
