#!/usr/bin/env bash
# The paper's figure-11 ablation on one synthetic capture of the room: each variant adds one
# ingredient of the method, (a) image-space baseline ... (i) the full method. Every variant runs
# the same schedule (same iterations and rays per iteration; times are reported); then each result
# is scored against the ground truth and the held-out views. Not part of the tests (about 45 min).
# (d), the paper's per-object material parameterisation, is not a variant here: relume has no
# per-texel roughness/specular to start from, so it is part of every variant. (j) adds relume's
# own change, the Gauss-Newton albedo step, to the full method.
# Usage: scripts/ablation.sh [OUT]
#   ABLATION_EXTRA='"max_depth": 4'   extra fit config keys for every variant
#   ABLATION_RES=512,1024             prepared resolutions (the first is also the gutter grid)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
"$ROOT/scripts/setup.sh"
R="$ROOT/build/relume"
OUT="${1:-$ROOT/out/ablation}"
EXTRA="${ABLATION_EXTRA:+, $ABLATION_EXTRA}"
mkdir -p "$OUT"
[ -f "$OUT/capture/transforms.json" ] || "$R" --log warn synth --scene room --out "$OUT/capture"
RES="${ABLATION_RES:-512,1024}"
"$R" --log warn prepare "$OUT/capture" --out "$OUT/prepared" --res "$RES" --gutter-res "${RES%%,*}" --force
# Variant name and its config (each adds one ingredient to the previous one).
base='"albedo_step": "adam", "sampler": "image", "image_rays": 24576, "emitter_parameterisation": false, "median_init": false, "init_white_point": 0, "gradient_clamp": 0, "masked_adam": false, "per_entry_steps": false, "polyak_fraction": 0, "material_polyak_fraction": 0, "coarse_to_fine": false'
variants=(
  "a_image_space|$base"
  "b_texture_space|${base/\"sampler\": \"image\"/\"sampler\": \"texture\"}"
)
b="${base/\"sampler\": \"image\"/\"sampler\": \"texture\"}"
c="${b/\"emitter_parameterisation\": false/\"emitter_parameterisation\": true}"
variants+=("c_emitter_param|$c")
e="${c/\"median_init\": false, \"init_white_point\": 0/\"median_init\": true}"
variants+=("e_median_init|$e")
f="${e/\"gradient_clamp\": 0/\"gradient_clamp\": 10}"
variants+=("f_gradient_clamp|$f")
g="${f/\"masked_adam\": false, \"per_entry_steps\": false/\"masked_adam\": true, \"per_entry_steps\": true}"
variants+=("g_masked_adam|$g")
h="${g/\"polyak_fraction\": 0, \"material_polyak_fraction\": 0/\"polyak_fraction\": 0.1, \"material_polyak_fraction\": 0.5}"
variants+=("h_polyak|$h")
i="${h/\"coarse_to_fine\": false/\"coarse_to_fine\": true}"
variants+=("i_full_method|$i")
j="${i/\"albedo_step\": \"adam\"/\"albedo_step\": \"gauss-newton\"}"
variants+=("j_gauss_newton|$j")
for v in "${variants[@]}"; do
  name="${v%%|*}"; cfg="${v#*|}"
  rm -rf "$OUT/$name" && cp -r "$OUT/prepared" "$OUT/$name"
  echo "{$cfg$EXTRA}" > "$OUT/$name/config.json"
  echo "== $name"
  start=$(date +%s)
  "$R" --log warn fit "$OUT/$name" --config "$OUT/$name/config.json"
  echo $(( $(date +%s) - start )) > "$OUT/$name/seconds"
  "$R" --log warn eval --scene "$OUT/$name/result/scene.json" --cameras "$OUT/capture/transforms_test.json" \
    --out "$OUT/$name/eval" --truth "$OUT/capture/gt/scene.json" --coverage "$OUT/$name/coverage.exr" --spp 32 | grep -v '^  {'  # per-object lines are in eval.json
done
python3 - "$OUT" <<'PY'
import json, sys, os
out = sys.argv[1]
print("| variant | test PSNR (dB) | test MSRE | albedo MAE | roughness MAE | specular MAE | emitters found/true | emission error | fit time (s) |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- |")
for name in sorted(d for d in os.listdir(out) if d[:2] in {f"{c}_" for c in "abcefghij"}):
    e = json.load(open(os.path.join(out, name, "eval", "eval.json")))
    t, v = e["truth"], e["views"]
    secs = open(os.path.join(out, name, "seconds")).read().strip()
    print(f"| {name} | {v['psnr']:.2f} | {v['msre']:.4f} | {t['albedo_mae']:.4f} | {t['roughness_mae']:.3f} | {t['specular_mae']:.3f} "
          f"| {t['emitters_found']}/{t['emitters_true']} | {100*t['emission_rel_error']:.1f}% | {secs} |")
PY
