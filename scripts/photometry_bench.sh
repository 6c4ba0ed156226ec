#!/usr/bin/env bash
# Real captures I: what each imperfection of a hand-held capture costs and what each remedy buys.
# The built-in room (synth's defaults: 24 frames of 256x192 at 16 spp; 4 held-out views at 32 spp)
# is synthesised clean and with each flaw (`relume synth --imperfect`), prepared and fitted with
# the demo's schedule; each remedy is also switched off (`_values`: 8-bit codes taken as exact;
# `_no_gains`: no frame gains; `_rgb`: rgb frame gains asked for, not left to `auto`; `_kept`: no
# scale for lights seen only saturated). One row per fit: albedo MAE, held-out PSNR against the
# clean references, emitters, emission error, and the frame gains
# against the truth (gt/imperfections.json, in the fit's gauge). A benchmark, not a test.
# With SOURCE, any clean capture with float frames (e.g. scripts/cycles_capture.sh's OUT/capture)
# takes the room's place: its variants are made by `relume degrade`, scored against TRUTH
# (default SOURCE/gt/scene.json) and prepared with PREPARE_FLAGS (e.g. "--res 512,1024 --gutter-res 512").
# Usage: scripts/photometry_bench.sh [OUT]   RELUME=binary (default build/relume)  VARIANTS="name ..."
#   SOURCE=capture folder  TRUTH=scene.json  PREPARE_FLAGS="..."
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
R="${RELUME:-$ROOT/build/relume}"
OUT="${1:-$ROOT/out/photometry_bench}"
mkdir -p "$OUT"
echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "samples_per_ray": 1,
  "emission_texture_iterations": 40}' > "$OUT/fit.json"
echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "samples_per_ray": 1,
  "emission_texture_iterations": 40, "frame_gains": "none"}' > "$OUT/fit_no_gains.json"
# Float frames count as radiometrically known (frame_gains auto: none): the drift rows ask for gains.
echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "samples_per_ray": 1,
  "emission_texture_iterations": 40, "frame_gains": "rgb"}' > "$OUT/fit_rgb.json"
echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "samples_per_ray": 1,
  "emission_texture_iterations": 40, "frame_gains": "none", "clipped_light_scale": false}' > "$OUT/fit_kept.json"

# name | imperfection spec | prepare flags | fit config
declare -A SPEC PREP CFG
add() { SPEC[$1]="$2"; PREP[$1]="$3"; CFG[$1]="$4"; }
add clean "" "" fit.json
add ldr8 "ldr=8" "" fit_no_gains.json
add ldr8_values "ldr=8" "--no-encoding-clips" fit_no_gains.json
add ldr8_kept "ldr=8" "" fit_kept.json
add ldr8_bracket "bracket=-1.5,0,1.5;ldr=8" "" fit.json
add ldr8_bracket_kept "bracket=-1.5,0,1.5;ldr=8" "" fit_kept.json
add ldr8_bracket_values "bracket=-1.5,0,1.5;ldr=8" "--no-encoding-clips" fit.json
# A bracket with a frame dark enough to show the lights unclipped (what lights.json's darker_frame_ev asks).
add ldr8_bracket_dark "bracket=-6,-1.5,0,1.5;ldr=8" "" fit.json
add ldr8_drift "exposure-drift=0.3;wb=0.03;ldr=8" "" fit.json
add ldr8_bracket_wb "bracket=-1.5,0,1.5;wb=0.03;ldr=8" "" fit.json
add ldr8_bracket_wb_rgb "bracket=-1.5,0,1.5;wb=0.03;ldr=8" "" fit_rgb.json
add ldr8_bracket_rgb "bracket=-1.5,0,1.5;ldr=8" "" fit_rgb.json
add drift "exposure-drift=0.3;wb=0.03" "" fit_rgb.json
add drift_no_gains "exposure-drift=0.3;wb=0.03" "" fit_no_gains.json
add noise "noise=1000,0.002" "" fit.json
add handheld "pose=1cm,0.3deg;bracket=-1.5,0,1.5;wb=0.03;noise=1000,0.002;ldr=8;mesh=5mm;segmentation=none" "" fit.json
ORDER="${VARIANTS:-clean ldr8 ldr8_kept ldr8_values ldr8_bracket ldr8_bracket_kept ldr8_bracket_values ldr8_bracket_dark ldr8_bracket_rgb ldr8_drift ldr8_bracket_wb ldr8_bracket_wb_rgb drift drift_no_gains noise handheld}"

for name in $ORDER; do
  cap="$OUT/capture_${SPEC[$name]//[^a-z0-9]/_}"
  if [ -n "${SOURCE:-}" ] && [ -z "${SPEC[$name]}" ]; then
    cap="$SOURCE"
  elif [ -n "${SOURCE:-}" ]; then
    [ -f "$cap/transforms.json" ] || { rm -rf "$cap" && "$R" --log warn degrade "$SOURCE" --out "$cap" \
      --imperfect "${SPEC[$name]}" > /dev/null; }
  else
    [ -f "$cap/transforms.json" ] || "$R" --log warn synth --scene room --out "$cap" --test-spp 32 \
      --imperfect "${SPEC[$name]}" > /dev/null
  fi
  truth="${TRUTH:-$cap/gt/scene.json}"
  work="$OUT/work_$name"
  start=$(date +%s)
  # shellcheck disable=SC2086
  "$R" --log warn prepare "$cap" --out "$work" ${PREP[$name]} ${PREPARE_FLAGS:-} > /dev/null 2>&1
  "$R" --log warn fit "$work" --config "$OUT/${CFG[$name]}" --no-report > "$OUT/$name.fit.log" 2>&1
  # A capture whose mesh was perturbed (mesh=...) has no texel-wise truth: its views are scored alone.
  "$R" --log warn eval --scene "$work/result/scene.json" --cameras "$cap/transforms_test.json" --out "$OUT/$name.eval" \
    --truth "$truth" --coverage "$work/coverage.exr" --spp 32 > /dev/null 2>&1 ||
    "$R" --log warn eval --scene "$work/result/scene.json" --cameras "$cap/transforms_test.json" \
      --out "$OUT/$name.eval" --coverage "$work/coverage.exr" --spp 32 > /dev/null 2>&1
  python3 - "$name" "$OUT/$name.eval/eval.json" "$work/result/frames.json" "$cap/gt/imperfections.json" \
    "$(( $(date +%s) - start ))" <<'PY'
import json, math, sys
name, ev, frames, truth, seconds = sys.argv[1:]
e = json.load(open(ev))
t = e.get("truth", {"albedo_mae": float("nan"), "emitters_correct": "?", "emitters_true": "?",
                    "emitters_found": "?", "emission_rel_error": float("nan")})
psnr = e["views"]["psnr"]
g = json.load(open(frames)); gains = "not estimated"
if g["mode"] != "none":
    written = [f for f in json.load(open(truth))["frames"] if not f["left_out"]]
    tg = [[f["wb_gain"][c] * f["exposure_drift_gain"] for c in range(3)] for f in written]
    kept = [f["frame"] for f in g["frames"]]
    gauge = [math.exp(sum(math.log(tg[k][c]) for k in kept) / len(kept)) for c in range(3)]
    err = sorted(abs(f["gain"][c] / (tg[f["frame"]][c] / gauge[c]) - 1) for f in g["frames"] for c in range(3))
    gains = f"{g['mode']}: median {100 * err[len(err) // 2]:.1f}%, worst {100 * err[-1]:.1f}%"
print(f"| {name} | {t['albedo_mae']:.4f} | {psnr:.2f} | {t['emitters_correct']}/{t['emitters_true']} "
      f"(found {t['emitters_found']}) | {100 * t['emission_rel_error']:.1f}% | {gains} | {seconds} s |", flush=True)
PY
done
