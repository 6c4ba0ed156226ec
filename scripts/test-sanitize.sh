#!/usr/bin/env bash
# The whole CTest suite under AddressSanitizer + UndefinedBehaviorSanitizer: configures
# build-sanitize/ (RelWithDebInfo, -DRELUME_SANITIZE=ON, so reports carry file:line), builds and
# runs ctest. Any report fails the test that triggered it (UBSan halts, ASan aborts, leaks count).
# Needs the packages of setup.sh. Usage: scripts/test-sanitize.sh [ctest args...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
BUILD="$ROOT/build-sanitize"
JOBS="${JOBS:-$(nproc)}"
cmake -S "$ROOT" -B "$BUILD" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DRELUME_SANITIZE=ON > /dev/null
cmake --build "$BUILD" -j "$JOBS"
export ASAN_OPTIONS="detect_leaks=1:check_initialization_order=1:detect_stack_use_after_return=1"
export UBSAN_OPTIONS="halt_on_error=1:print_stacktrace=1"
export LSAN_OPTIONS="suppressions=$ROOT/scripts/lsan.supp"
# Tests write fixed names under the temp folder: keep this run's apart from any other build's.
export TMPDIR="$BUILD/tmp"
mkdir -p "$TMPDIR"
cd "$BUILD"
exec ctest --output-on-failure -j "$JOBS" "$@"
