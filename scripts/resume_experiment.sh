#!/usr/bin/env bash
# One variant of a fit resumed from a shared checkpoint, then scored: how the notes'
# "resumed from one checkpoint" tables were measured (e.g. the albedo stage with 2 samples per
# ray, the material stage with highlight texels). A benchmark helper, not a test.
#
# 1. Stop a fit where the variants should start and keep its checkpoint, e.g. at the start of the
#    albedo stage of the demo capture (stage boundaries are in WORK/metrics.jsonl):
#      echo '{"stop_after_iterations": 201}' > stop.json
#      relume fit out/demo/work --config stop.json && cp out/demo/work/checkpoint.bin ck.bin
# 2. Run a variant (the checkpoint's config with OVERRIDES, written into a copy of it so that
#    `fit --resume` accepts it), then `relume eval` against the capture's truth:
#      scripts/resume_experiment.sh out/demo/work ck.bin /tmp/v1 \
#        '{"samples_per_ray": 2, "albedo_passes": 100.0, "albedo_damping": 0.004999999888241291}'
#    Float overrides must be the float32 value's shortest decimal, as the checkpoint stores them;
#    a checkpoint written before a config key existed needs that key (at its default) in OVERRIDES.
# Usage: scripts/resume_experiment.sh WORK CHECKPOINT OUT OVERRIDES_JSON [CAPTURE]
#   CAPTURE defaults to WORK/../capture; RELUME=binary (default build/relume); EVAL_SPP=128
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
[ $# -ge 4 ] || { sed -n 2,18p "$0" >&2; exit 2; }
WORK="$(realpath "$1")" CK="$2" OUT="$3" OVERRIDES="$4"
CAPTURE="$(realpath "${5:-$WORK/../capture}")"
R="${RELUME:-$ROOT/build/relume}"
rm -rf "$OUT" && mkdir -p "$OUT"
for f in albedo_init.exr albedo_init.png atlas_mesh.ply coverage.exr coverage.png frames.bin prepare.json visibility.bin; do
  [ -e "$WORK/$f" ] && ln -s "$WORK/$f" "$OUT/$f"
done
# The checkpoint: 8-byte magic, u64 header length, JSON header (meta.config), then the arrays.
python3 - "$CK" "$OUT/checkpoint.bin" "$OUT/config.json" "$OVERRIDES" <<'PY'
import json, struct, sys
src, dst, config_out, overrides = sys.argv[1], sys.argv[2], sys.argv[3], json.loads(sys.argv[4])
data = open(src, 'rb').read()
n = struct.unpack('<Q', data[8:16])[0]
header = json.loads(data[16:16 + n])
config = header['meta']['config']
config.pop('stop_after_iterations', None)
config.update(overrides)
text = json.dumps(header).encode()
open(dst, 'wb').write(data[:8] + struct.pack('<Q', len(text)) + text + data[16 + n:])
json.dump(config, open(config_out, 'w'))
print(f"resuming stage {header['meta']['stage']}, iteration {header['meta']['iteration']}")
PY
/usr/bin/time -f "fit: %e s, peak RSS %M KB" "$R" --log warn fit "$OUT" --config "$OUT/config.json" --resume
"$R" --log warn eval --scene "$OUT/result/scene.json" --cameras "$CAPTURE/transforms_test.json" \
  --truth "$CAPTURE/gt/scene.json" --coverage "$OUT/coverage.exr" --out "$OUT/eval" --spp "${EVAL_SPP:-128}"
python3 - "$OUT/eval/eval.json" <<'PY'
import json, sys
e = json.load(open(sys.argv[1])); t = e['truth']
print(f"albedo MAE {t['albedo_mae']:.4f}, roughness MAE {t['roughness_mae']:.3f}, specular MAE {t['specular_mae']:.3f}, "
      f"emission {t['emission_rel_error']:.3f}, emitters {t['emitters_found']}/{t['emitters_true']}, held-out PSNR {e['views']['psnr']:.2f} dB")
for o in t['objects']:
    line = o['name']
    if 'albedo' in o: line += f"  albedo MAE {o['albedo']['mae']:.3f} bias {o['albedo']['bias']:+.3f}"
    if o.get('materials_scored'): line += f"  roughness {o['roughness'][0]:.3f} (truth {o['roughness'][1]:.2f}), specular {o['specular'][0]:.3f} (truth {o['specular'][1]:.2f})"
    print(line)
PY
