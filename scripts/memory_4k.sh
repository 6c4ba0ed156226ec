#!/usr/bin/env bash
# Memory-bounded 4096^2 reconstruction from the command line (docs/notes/2026-11-23-memory-4k.md): a
# scan-like capture (1M-triangle noisy room, 128x96 frames) at 2000 and 500 frames, prepared at
# 1024/2048/4096, fitted to 4096^2. The 2000-frame depth-9 fit is a whole (short) reconstruction;
# the other three (500 frames, and depth 2) reach the 4096^2 stage in a few iterations each, to
# show that peak memory does not grow with frames or depth. Prints peak RSS (/usr/bin/time) and
# the fit's own breakdown (result/materials.json "memory_bytes"). About 1.5 h on 2 cores (most of
# it rendering the frames and the 4096^2 stage). Not part of the tests.
# Usage: scripts/memory_4k.sh [OUT]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
R="$ROOT/build/relume"
OUT="${1:-$ROOT/out/4k}"
mkdir -p "$OUT"
peak() { grep "Maximum resident" "$1" | awk '{printf "%.0f MiB", $6 / 1024}'; }
for n in 2000 500; do
  [[ -f "$OUT/scan$n/transforms_test.json" ]] ||
    "$R" --log warn synth --scene scan --out "$OUT/scan$n" --frames "$n" --test-frames 2 --width 128 --height 96 --spp 1 --max-depth 2
  /usr/bin/time -v "$R" --log info prepare "$OUT/scan$n" --out "$OUT/work$n" --res 1024,2048,4096 > "$OUT/prepare$n.log" 2>&1
  echo "prepare, $n frames: peak RSS $(peak "$OUT/prepare$n.log")"
done
# Full: the demo-like schedule, one albedo pass per stage. Probes: a few iterations per stage.
echo '{"emission_iterations": 60, "material_iterations": 40, "albedo_passes": 1.0, "emission_texture_iterations": 20, "max_resolution": 4096}' > "$OUT/full.json"
for depth in 9 2; do
  echo "{\"emission_iterations\": 5, \"material_iterations\": 5, \"albedo_passes\": 0.01, \"emission_texture_iterations\": 5, \"max_resolution\": 4096, \"max_depth\": $depth}" > "$OUT/probe_depth$depth.json"
done
fit() {  # fit WORK CONFIG LABEL
  /usr/bin/time -v "$R" --log info fit "$1" --config "$2" --no-report > "$OUT/fit_$3.log" 2>&1
  python3 - "$1/result/materials.json" "$3" "$(peak "$OUT/fit_$3.log")" <<'PY'
import json, sys
m = json.load(open(sys.argv[1]))
parts = ", ".join(f"{k} {v / 2**20:.0f}" for k, v in m["memory_bytes"].items() if k != "total")
print(f"fit {sys.argv[2]}: {m['iterations']} iterations, peak RSS {sys.argv[3]}; held at the largest stage "
      f"{m['memory_bytes']['total'] / 2**20:.0f} MiB ({parts} MiB)")
PY
}
fit "$OUT/work2000" "$OUT/full.json" full_2000_depth9
fit "$OUT/work2000" "$OUT/probe_depth9.json" probe_2000_depth9
fit "$OUT/work2000" "$OUT/probe_depth2.json" probe_2000_depth2
fit "$OUT/work500" "$OUT/probe_depth9.json" probe_500_depth9
fit "$OUT/work500" "$OUT/probe_depth2.json" probe_500_depth2
