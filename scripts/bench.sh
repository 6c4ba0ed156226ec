#!/usr/bin/env bash
# Reproduces the performance figures of docs/design/rendering.md (about 12 minutes on 2 cores). Not part of the
# test suite. Output: out/perf/ (logs) and the figures on stdout. The speed/accuracy sweeps are
# `relume bench` (about 30 minutes), the peer comparison scripts/peer_bench.sh, the 4096^2 memory
# runs scripts/memory_4k.sh.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
R="$ROOT/build/relume"
OUT="${1:-$ROOT/out/perf}"
mkdir -p "$OUT"
run() { echo "\$ relume $*"; "$R" --log warn "$@" 2>&1 | tee -a "$OUT/bench.log"; echo; }
run profile --what render,leaks,scatter,visibility --max-depth 8
run profile --what adjoint --max-depth 8
run profile --what adjoint --max-depth 2 --repeats 1
run profile --what adjoint --max-depth 64 --repeats 1
run profile --what pairing --batches 64 --max-depth 8
run profile --what fit --iterations 20 --json "$OUT/profile_fit.json"
run gradcheck --synth room --max-depth 8
"$R" --log warn synth --scene scan --out "$OUT/scan" --frames 2000 --test-frames 1 --width 128 --height 96 --spp 1 --max-depth 2
echo "\$ relume prepare (1M triangles, 2000 frames)"
"$R" prepare "$OUT/scan" --out "$OUT/scan_work" --force 2>&1 | grep -E "done in|prepared|peak RSS" | tee -a "$OUT/bench.log"
du -sh "$OUT/scan_work"
