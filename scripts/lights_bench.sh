#!/usr/bin/env bash
# Light sources on a prepared capture with a ground truth: fits it with the default decisions and,
# for the issue's PSNR target, with the true light set given as the `lights` hint, then prints one
# row per fit: emitters true / found / correct / false, emission error, held-out PSNR, albedo MAE,
# and the decisions (result/lights.json). A benchmark, not a test.
# Usage: scripts/lights_bench.sh WORK TRUTH_SCENE_JSON TEST_TRANSFORMS_JSON [OUT]
#   FIT_CONFIG=file (default: the demo's schedule)  RELUME=binary (default build/relume)
#   EVAL_SPP=128  HINT=0 (skip the true-light-set fit)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
R="${RELUME:-$ROOT/build/relume}"
WORK="$1" TRUTH="$2" TEST="$3" OUT="${4:-$1/../lights_bench}"
mkdir -p "$OUT"
cfg="${FIT_CONFIG:-$OUT/fit.json}"
[ -n "${FIT_CONFIG:-}" ] || echo '{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 40, "emission_texture_iterations": 40}' > "$cfg"

run() {  # name, config file
  local name="$1" config="$2"
  "$R" fit "$WORK" --config "$config" 2> "$OUT/$name.fit.log" > /dev/null
  "$R" --log warn eval --scene "$WORK/result/scene.json" --cameras "$TEST" --out "$OUT/$name.eval" --truth "$TRUTH" \
    --coverage "$WORK/coverage.exr" --spp "${EVAL_SPP:-128}" > /dev/null
  cp "$WORK/result/lights.json" "$OUT/$name.lights.json"
  python3 - "$name" "$OUT/$name.eval/eval.json" "$WORK/result/materials.json" "$TRUTH" "$OUT/$name.lights.json" <<'EOF'
import json, sys
name, ev, mat, truth, lights = sys.argv[1:]
e = json.load(open(ev)); t = e["truth"]
true_lights = {o["name"] for o in json.load(open(truth))["objects"] if max(o.get("emission", [0, 0, 0])) > 0}
found = {o["name"] for o in json.load(open(mat))["objects"] if o["is_emitter"]}
false = sorted(found - true_lights)
print(f"{name}: emitters true {t['emitters_true']} found {t['emitters_found']} correct {t['emitters_correct']} "
      f"false {len(false)} {false}; emission error {100 * t['emission_rel_error']:.1f}%; held-out PSNR "
      f"{e['views']['psnr']:.2f} dB; albedo MAE {t['albedo_mae']:.4f}")
for d in json.load(open(lights))["decisions"]:
    picked = [f"{o['name']} ({o['decision']}, {100 * o['unexplained_share']:.0f}%)" for o in d["objects"]
              if o["decision"] in ("light", "out_of_model") or o["name"] in true_lights or "under_lit" in o]
    print(f"  after {d['after']}: " + "; ".join(picked))
EOF
}
run default "$cfg"
if [ "${HINT:-1}" != 0 ]; then
  python3 - "$cfg" "$TRUTH" "$OUT/hint.json" <<'EOF'
import json, sys
c = json.load(open(sys.argv[1]))
c["lights"] = [o["name"] for o in json.load(open(sys.argv[2]))["objects"] if max(o.get("emission", [0, 0, 0])) > 0]
json.dump(c, open(sys.argv[3], "w"))
EOF
  run true_lights "$OUT/hint.json"
fi
