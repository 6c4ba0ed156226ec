#!/usr/bin/env bash
# A capture rendered by an independent path tracer: a ground-truth scene exported as glTF (relume
# export), rendered by Blender 3.4 Cycles (Principled v1, 8 bounces, emission on the front side
# only, as relume) at the capture's cameras, then reconstructed by relume and scored against the
# truth and Cycles' held-out views. The scene is the synthetic room, or with SOURCE any folder
# holding scene.json, mesh.ply, objects.json, transforms.json and transforms_test.json (e.g. an
# artist-made interior converted by scripts/mitsuba_to_capture.py --test-frames N). A benchmark,
# not a test (needs Blender: `apt-get install blender`; about 15 min on 2 cores for the room).
# Usage: scripts/cycles_capture.sh [OUT_DIR]   (default out/cycles_capture)
#   SOURCE=folder (default: the synthetic room, made with the FRAMES/WIDTH/HEIGHT below)
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
# The source supplies the mesh, segmentation, cameras and ground truth; for the room, relume's own
# capture, whose images are replaced by Cycles' (hence 1 spp here).
if [ -n "${SOURCE:-}" ]; then
  SRC="$SOURCE" TRUTH="$SOURCE/scene.json"
else
  SRC="$OUT/synth" TRUTH="$OUT/synth/gt/scene.json"
  [ -f "$SRC/transforms.json" ] || "$R" --log warn synth --scene room --out "$SRC" \
    --frames "$FRAMES" --width "$WIDTH" --height "$HEIGHT" --spp 1 --test-spp 1
fi
"$R" --log warn export "$TRUTH" --gltf "$OUT/scene.glb"
for f in transforms.json transforms_test.json; do
  [ -f "$SRC/$f" ] || { echo "cycles_capture: $SRC/$f missing (mitsuba_to_capture.py writes the held-out one with --test-frames)" >&2; exit 1; }
done
render() {  # cameras, output folder, spp; renders kept in OUT are reused only for the same scene, cameras and spp
  local stamp
  stamp="$(cat "$TRUTH" "$1" | sha256sum | cut -c1-16) spp $3 with albedo"
  [ -f "$2/done" ] && [ "$(cat "$2/done")" = "$stamp" ] && return
  rm -rf "$2"
  blender -b --factory-startup --python-exit-code 1 --python "$ROOT/scripts/cycles_compare.py" -- render "$SRC" "$2" \
    --gltf "$OUT/scene.glb" --front-emission --transforms "$1" --spp "$3" --threads "$THREADS" > "$2.log" 2>&1 || { tail -20 "$2.log" >&2; exit 1; }
  echo "$stamp" > "$2/done"
}
frames() {  # the image paths a transforms.json lists
  python3 -c 'import json, sys; print("\n".join(f["file_path"] for f in json.load(open(sys.argv[1]))["frames"]))' "$1"
}
render "$SRC/transforms.json" "$OUT/cycles_train" "$SPP"
render "$SRC/transforms_test.json" "$OUT/cycles_test" $((2 * SPP))
# The capture: relume's mesh, objects and cameras; Cycles' images in place of relume's.
CAP="$OUT/capture"
rm -rf "$CAP" && mkdir -p "$CAP/images" "$CAP/test"
cp "$SRC/mesh.ply" "$SRC/objects.json" "$CAP/"
# Cycles formed the pixels with its default filter (Blackman-Harris, Filter Width 1.5 px): the capture says so.
# The held-out frames carry Cycles' Diffuse Color pass as their albedo_path (eval's per-pixel albedo).
for f in transforms.json transforms_test.json; do
  python3 -c 'import json, os, sys; t = json.load(open(sys.argv[1])); t["pixel_filter"] = {"type": "blackman-harris", "width": 1.5}
for fr in t["frames"] if sys.argv[3] == "test" else []:
    stem, ext = os.path.splitext(fr["file_path"]); fr["albedo_path"] = stem + "_albedo" + ext
json.dump(t, open(sys.argv[2], "w"), indent=1)' "$SRC/$f" "$CAP/$f" "$([ $f = transforms_test.json ] && echo test)"
done
frames "$SRC/transforms.json" | while read -r p; do cp "$OUT/cycles_train/$(basename "$p")" "$CAP/$p" || exit 1; done
frames "$SRC/transforms_test.json" | while read -r p; do
  stem="$(basename "${p%.*}")"
  cp "$OUT/cycles_test/$stem.exr" "$CAP/$p" && cp "$OUT/cycles_test/${stem}_albedo.exr" "$CAP/${p%.*}_albedo.exr" || exit 1
done
"$R" --log warn prepare "$CAP" --out "$OUT/work" --res 512,1024 --gutter-res 512 --force
if [ -n "${FIT_CONFIG:-}" ]; then cfg="$FIT_CONFIG"; else
  cfg="$OUT/fit.json"
  echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "emission_texture_iterations": 40}' > "$cfg"
fi
"$R" --log warn fit "$OUT/work" --config "$cfg"
"$R" eval --scene "$OUT/work/result/scene.json" --cameras "$CAP/transforms_test.json" --out "$OUT/eval" \
  --truth "$TRUTH" --coverage "$OUT/work/coverage.exr" --spp "${EVAL_SPP:-128}" | grep -v '^  {'  # per-object lines are in eval.json
