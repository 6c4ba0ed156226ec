# Sourced by scripts/mitsuba_compare.sh and scripts/gltf_blender_check.sh: what to check, from
# their arguments [SCENE.json|WORK_DIR CAMERAS.json] [OUT_DIR], by default the synthetic room's
# ground truth and its 4 held-out views (160x120) rendered into OUT_DIR/cap.
# In: ROOT, DEFAULT_OUT, the script's arguments, SPP (default 256).
# Out: R (the relume binary), SPP, INPUT (as given to `relume export`), SCENE (its scene.json),
# CAMERAS, OUT (created).
R="$ROOT/build/relume"
SPP="${SPP:-256}"
if [[ $# -ge 2 ]]; then
  INPUT="$1" CAMERAS="$2" OUT="${3:-$DEFAULT_OUT}"
else
  OUT="${1:-$DEFAULT_OUT}"
  [[ -f "$OUT/cap/gt/scene.json" ]] || "$R" --log warn synth --scene room --out "$OUT/cap" --frames 1 --test-frames 4 \
    --width 160 --height 120 --spp 1
  INPUT="$OUT/cap/gt/scene.json" CAMERAS="$OUT/cap/transforms_test.json"
fi
SCENE="$INPUT"
if [[ -d "$INPUT" ]]; then SCENE="$INPUT/result/scene.json"; fi
mkdir -p "$OUT"
