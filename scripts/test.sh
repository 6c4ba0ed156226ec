#!/usr/bin/env bash
# Set up, build and run the whole CTest suite.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
cd "$ROOT/build"
exec ctest --output-on-failure -j "$(nproc)"
