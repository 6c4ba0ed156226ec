#!/usr/bin/env bash
# A capture rendered by an independent path tracer: the synthetic room's ground truth exported
# as glTF (relume export), rendered by Blender 3.4 Cycles (Principled v1, 8 bounces, emission on
# the front side only, as relume) at the synthetic capture's cameras, then reconstructed by relume
# and scored against the truth and Cycles' held-out views. A benchmark, not a test (needs
# Blender: `apt-get install blender`; about 15 min on 2 cores).
# Usage: scripts/cycles_capture.sh [OUT_DIR]   (default out/cycles_capture)
#   SPP=64 (training frames; the test frames get 2x)   FIT_CONFIG=path to a fit config (default: the demo's schedule)
#   RELUME=binary (default build/relume)   EVAL_SPP=128 (re-rendering the held-out views)
#   FRAMES=24 WIDTH=256 HEIGHT=192 (the capture's cameras; e.g. 100 frames at 320x240)   THREADS=2 (Cycles)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh" > /dev/null
command -v blender > /dev/null || { echo "cycles_capture: blender not found (apt-get install blender)" >&2; exit 1; }
R="${RELUME:-$ROOT/build/relume}"  # a copy, to keep rebuilding while Cycles renders
OUT="${1:-$ROOT/out/cycles_capture}"
SPP="${SPP:-64}"
FRAMES="${FRAMES:-24}" WIDTH="${WIDTH:-256}" HEIGHT="${HEIGHT:-192}" THREADS="${THREADS:-2}"
mkdir -p "$OUT"
# relume's own capture supplies the mesh, segmentation, cameras and ground truth.
# Its images are replaced by Cycles' (hence 1 spp here).
[ -f "$OUT/synth/transforms.json" ] || "$R" --log warn synth --scene room --out "$OUT/synth" \
  --frames "$FRAMES" --width "$WIDTH" --height "$HEIGHT" --spp 1 --test-spp 1
"$R" --log warn export "$OUT/synth/gt/scene.json" --gltf "$OUT/room.glb"
render() {  # cameras, output folder, spp
  [ -f "$2/done" ] && return
  blender -b --factory-startup --python "$ROOT/scripts/cycles_compare.py" -- render "$OUT/synth/gt" "$2" \
    --gltf "$OUT/room.glb" --front-emission --transforms "$1" --spp "$3" --threads "$THREADS" > "$2.log" 2>&1 || { tail -20 "$2.log" >&2; exit 1; }
  touch "$2/done"
}
render "$OUT/synth/transforms.json" "$OUT/cycles_train" "$SPP"
render "$OUT/synth/transforms_test.json" "$OUT/cycles_test" $((2 * SPP))
# The capture: relume's mesh, objects and cameras; Cycles' images in place of relume's.
CAP="$OUT/capture"
rm -rf "$CAP" && mkdir -p "$CAP/images" "$CAP/test"
cp "$OUT/synth/mesh.ply" "$OUT/synth/objects.json" "$OUT/synth/transforms.json" "$OUT/synth/transforms_test.json" "$CAP/"
for f in "$OUT"/synth/images/*.exr; do cp "$OUT/cycles_train/$(basename "$f")" "$CAP/images/"; done
for f in "$OUT"/synth/test/*.exr; do cp "$OUT/cycles_test/$(basename "$f")" "$CAP/test/"; done
"$R" --log warn prepare "$CAP" --out "$OUT/work" --res 512,1024 --gutter-res 512 --force
if [ -n "${FIT_CONFIG:-}" ]; then cfg="$FIT_CONFIG"; else
  cfg="$OUT/fit.json"
  echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "emission_texture_iterations": 40}' > "$cfg"
fi
"$R" --log warn fit "$OUT/work" --config "$cfg"
"$R" eval --scene "$OUT/work/result/scene.json" --cameras "$CAP/transforms_test.json" --out "$OUT/eval" \
  --truth "$OUT/synth/gt/scene.json" --coverage "$OUT/work/coverage.exr" --spp "${EVAL_SPP:-128}" | head -2
