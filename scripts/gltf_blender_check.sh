#!/usr/bin/env bash
# `relume export --gltf` in the real consumer: Blender 3.4's glTF importer reads the .glb as is
# (no fix-up), Cycles renders the cameras, and the per-object means are compared with relume's
# render of the same cameras (docs/user/export.md). Not part of the test suite (needs Blender:
# `apt-get install blender`). Cycles settings as scripts/cycles_compare.sh (max bounces 8 =
# relume's default --max-depth 9, GGX, no clamping, no denoising), two seeds each for the
# standard error.
#
# Usage: scripts/gltf_blender_check.sh [SCENE.json|WORK_DIR CAMERAS.json] [OUT_DIR]
#   default: the synthetic room's ground truth and its 4 held-out views (160x120), in out/gltf_blender_check
# Environment: SPP=256 (each half, both renderers)
#   BLENDER_ARGS=--front-emission   the one fix-up (Blender emits on both sides of a face, relume on the front)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
command -v blender > /dev/null || { echo "gltf_blender_check: blender not found (apt-get install blender)" >&2; exit 1; }
# Blender's glTF importer needs numpy in Blender's (Debian's) Python.
blender -b --factory-startup --python-expr "import numpy" 2>&1 | grep -q "No module named" &&
  { echo "gltf_blender_check: Blender's glTF importer needs numpy (apt-get install python3-numpy)" >&2; exit 1; }
BLENDER_ARGS="${BLENDER_ARGS:-}"
DEFAULT_OUT="$ROOT/out/gltf_blender_check"
# shellcheck source=export_check_input.sh
source "$ROOT/scripts/export_check_input.sh"
"$R" --log warn export "$INPUT" --gltf "$OUT/scene.glb"
PY="$ROOT/scripts/cycles_compare.py"
for seed in 1 2; do
  "$R" --log warn render --scene "$SCENE" --cameras "$CAMERAS" --out "$OUT/relume_$seed" --spp "$SPP" --seed "$seed" --aov object
  # shellcheck disable=SC2086
  blender -b --factory-startup --python-exit-code 1 --python "$PY" -- render "$(dirname "$SCENE")" "$OUT/blender_$seed" --gltf "$OUT/scene.glb" \
    --transforms "$CAMERAS" --spp "$SPP" --seed "$seed" $BLENDER_ARGS > "$OUT/blender_$seed.log" 2>&1 || { tail -20 "$OUT/blender_$seed.log" >&2; exit 1; }
done
echo "relume ($SPP+$SPP spp) / Blender 3.4 Cycles on the imported .glb ($SPP+$SPP spp${BLENDER_ARGS:+, $BLENDER_ARGS})"
blender -b --factory-startup --python-exit-code 1 --python "$PY" -- compare "$(dirname "$SCENE")" "$OUT/relume_1" "$OUT/relume_2" "$OUT/blender_1" \
  "$OUT/blender_2" --transforms "$CAMERAS" 2>&1 | grep -v -e "^Blender" -e "^$" -e "Blender quit"
