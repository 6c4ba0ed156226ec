#!/usr/bin/env bash
# Fuzzes every reader of untrusted files (fuzz/readers.cpp) with libFuzzer + ASan + UBSan.
# Builds the harnesses with clang into build-fuzz/ and runs each for SECONDS (default 60), starting
# from the committed seeds in tests/data/fuzz/<reader>/; inputs that add coverage collect in
# build-fuzz/corpus/<reader>/ (not committed). A crash, hang (> 10 s) or out-of-memory input is
# copied into tests/data/fuzz/<reader>/, where the corpus-replay test (tests/fuzz) keeps it as a
# regression once the reader is fixed. Prints executions per reader; exits 1 if anything was found.
# Usage: scripts/fuzz.sh [SECONDS] [READER...]      (JOBS=2 builds with 2 cores)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$ROOT/build-fuzz"
SECONDS_EACH="${1:-60}"
shift || true
READERS=("$@")
# clang, and its runtimes (libFuzzer, ASan), which Debian packages apart from it.
if ! command -v clang++ > /dev/null || ! dpkg -s libclang-rt-dev > /dev/null 2>&1; then
  [[ $(id -u) -eq 0 ]] || { echo "fuzz.sh: needs clang (apt-get install clang libclang-rt-dev)" >&2; exit 1; }
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends clang libclang-rt-dev
fi
CXX=clang++ cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRELUME_FUZZ=ON > /dev/null
cmake --build "$BUILD" -j "${JOBS:-$(nproc)}" --target fuzzers
# By default every harness fuzz/CMakeLists.txt builds.
((${#READERS[@]})) || for h in "$BUILD"/fuzz/fuzz_*; do READERS+=("${h##*/fuzz_}"); done
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=0"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$ROOT/scripts/lsan.supp"
export TMPDIR="$BUILD/tmp"
mkdir -p "$TMPDIR"
found=0
summary=()
for r in "${READERS[@]}"; do
  seeds="$ROOT/tests/data/fuzz/$r" corpus="$BUILD/corpus/$r" artifacts="$BUILD/artifacts/$r"
  rm -rf "$artifacts"
  mkdir -p "$corpus" "$artifacts"
  log="$BUILD/fuzz_$r.log"
  echo "== $r: $SECONDS_EACH s"
  status=0
  "$BUILD/fuzz/fuzz_$r" -max_total_time="$SECONDS_EACH" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1 \
    -artifact_prefix="$artifacts/" "$corpus" "$seeds" > "$log" 2>&1 || status=$?
  execs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || echo "?")
  result=ok
  if ((status != 0)); then
    result="FOUND (exit $status, log $log)"
    found=1
    for a in "$artifacts"/*; do [[ -e "$a" ]] && cp "$a" "$seeds/" && echo "  kept $(basename "$a") in $seeds"; done
    tail -30 "$log"
  fi
  summary+=("$(printf '%-11s %6s s %12s executions  %s' "$r" "$SECONDS_EACH" "$execs" "$result")")
done
printf '%s\n' "${summary[@]}"
exit "$found"
