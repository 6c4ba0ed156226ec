#!/usr/bin/env bash
# relume against Blender 3.4 Cycles on the same scene (docs/notes/2026-11-22-cycles-agreement.md).
# Not part of the test suite (needs Blender: `apt-get install blender`). Writes the scene
# (scripts/cycles_scene.py), renders it with relume and with Cycles, twice each with independent
# seeds (the two halves give each per-object mean its standard error), and prints per-object
# relume/Cycles ratios. Cycles: Principled v1, metallic 0, GGX, max bounces 8 (diffuse, glossy and
# transmission 8 too), no clamping, Filter Glossy 0, no denoising, adaptive sampling off, CPU.
#
# Usage: scripts/cycles_compare.sh [OUT_DIR]            (default out/cycles_compare)
# Environment:
#   SPP=512            samples per pixel of each half (both renderers; 4 views of 160x120)
#   MODEL=principled-v1
#   RELUME_ARGS=       extra `relume render` options, e.g. "--max-depth 8"
#   CYCLES_ARGS=       extra Cycles options (scripts/cycles_compare.py render), e.g.
#                      "--distribution MULTI_GGX", "--bounces 9", "--diffuse-bounces 4 --glossy-bounces 4"
# Cycles renders are reused when OUT_DIR already holds them for the same SPP and CYCLES_ARGS.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" > /dev/null
command -v blender > /dev/null || { echo "cycles_compare: blender not found (apt-get install blender)" >&2; exit 1; }
OUT="${1:-$ROOT/out/cycles_compare}"
SPP="${SPP:-512}"
MODEL="${MODEL:-principled-v1}"
RELUME_ARGS="${RELUME_ARGS:-}"
CYCLES_ARGS="${CYCLES_ARGS:-}"
PY="$ROOT/scripts/cycles_compare.py"
mkdir -p "$OUT"
python3 "$ROOT/scripts/cycles_scene.py" "$OUT/scene" --model "$MODEL"
stamp="spp $SPP cycles $CYCLES_ARGS"
for seed in 1 2; do
  # shellcheck disable=SC2086
  "$ROOT/build/relume" --log warn render --scene "$OUT/scene/scene.json" --cameras "$OUT/scene/transforms.json" \
    --out "$OUT/relume_$seed" --spp "$SPP" --seed "$seed" --aov object $RELUME_ARGS
  if [[ "$(cat "$OUT/cycles_$seed/stamp" 2> /dev/null)" != "$stamp" ]]; then
    rm -rf "$OUT/cycles_$seed"
    # shellcheck disable=SC2086
    blender -b --factory-startup --python-exit-code 1 --python "$PY" -- render "$OUT/scene" "$OUT/cycles_$seed" --spp "$SPP" --seed "$seed" \
      $CYCLES_ARGS > "$OUT/cycles_$seed.log" 2>&1 || { tail -20 "$OUT/cycles_$seed.log" >&2; exit 1; }
    echo "$stamp" > "$OUT/cycles_$seed/stamp"
  fi
done
echo "relume ($MODEL, $SPP+$SPP spp${RELUME_ARGS:+, $RELUME_ARGS}) / Cycles 3.4 ($SPP+$SPP spp${CYCLES_ARGS:+, $CYCLES_ARGS})"
blender -b --factory-startup --python-exit-code 1 --python "$PY" -- compare "$OUT/scene" "$OUT/relume_1" "$OUT/relume_2" "$OUT/cycles_1" \
  "$OUT/cycles_2" 2>&1 | grep -v -e "^Blender" -e "^$" -e "Blender quit"
