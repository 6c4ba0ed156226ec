#!/usr/bin/env bash
# Set up, build and run the end-to-end demo on the built-in synthetic room.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
exec "$ROOT/build/relume" demo --out "${1:-$ROOT/out/demo}"
