#!/usr/bin/env bash
# relume against its peer, Mitsuba 3 (prb integrator, Dr.Jit LLVM autodiff, Adam with
# mask_updates), on the built-in room through `relume export --mitsuba` (issue 12). Measures
# (a) time and peak RSS of one gradient iteration by path depth and batch size, (b) forward
# agreement (scripts/mitsuba_compare.sh), (c) albedo error of the same reconstruction at equal wall
# clock, (e) each renderer's efficiency (its render against its Embree traversal alone on the same rays). Writes OUT/peer.md (and prints it). Not part of the test suite; Mitsuba is never a
# dependency of relume (pip install mitsuba OpenEXR; its llvm_ad_rgb variant needs libLLVM >= 16 on
# bookworm: apt-get install libllvm19, Debian's libLLVM 14/15 fail to compile its kernels).
#
# Usage: scripts/peer_bench.sh [OUT]      (default out/peer_bench; ~55 minutes on 2 cores, (c) ~35 of them)
# Environment: ROUNDS=3 (interleaved relume/Mitsuba rounds of (a)), BUDGETS=120,300,600 (seconds, (c)),
#   FWD_SPP=16 (spp per half of (b)), SETTINGS="65536:2 65536:4 65536:8 65536:16 16384:8 262144:8" (rays:depth),
#   PARTS="a b c e" (which parts to run; the table shows the parts whose results OUT holds)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
OUT="$(mkdir -p "${1:-$ROOT/out/peer_bench}" && cd "${1:-$ROOT/out/peer_bench}" && pwd)"
ROUNDS="${ROUNDS:-3}"
BUDGETS="${BUDGETS:-120,300,600}"
FWD_SPP="${FWD_SPP:-16}"
SETTINGS="${SETTINGS:-65536:2 65536:4 65536:8 65536:16 16384:8 262144:8}"
PARTS="${PARTS:-a b c e}"
RES=512
PY="$ROOT/scripts/peer_bench.py"
R="$ROOT/build/relume"
T0=$(date +%s)

# Build (Release) as scripts/setup.sh does; falls back to plain cmake where setup.sh cannot install.
"$ROOT/scripts/setup.sh" > /dev/null || { cmake -S "$ROOT" -B "$ROOT/build" -DCMAKE_BUILD_TYPE=Release > /dev/null &&
  cmake --build "$ROOT/build" -j2 --target relume; }

# Mitsuba with a working LLVM backend (a principled-BSDF kernel exercises the f32 min/max LLVM 14/15 cannot select).
python3 - << 'PYEOF' || { echo "peer_bench: Mitsuba 3 llvm_ad_rgb does not work here (pip install mitsuba OpenEXR; apt-get install libllvm19)" >&2; exit 1; }
import OpenEXR  # peer_bench.py writes the Mitsuba fit's textures with it
import mitsuba as mi
mi.set_variant("llvm_ad_rgb")
s = mi.load_dict({"type": "scene", "s": {"type": "sphere", "bsdf": {"type": "principled"}},
                  "e": {"type": "constant"}, "integrator": {"type": "prb"}})
mi.render(s, spp=1, sensor=mi.load_dict({"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}}))
PYEOF

stamp() { echo "[$(date +%H:%M:%S), $(( $(date +%s) - T0 )) s, load $(cut -d' ' -f1-3 /proc/loadavg)] $*"; }
part() { [[ " $PARTS " == *" $1 "* ]]; }
mkdir -p "$OUT/iter" "$OUT/fit"
python3 - "$OUT" "$BUDGETS" "$ROUNDS" "$SETTINGS" "$RES" << 'PYEOF'
import json, os, subprocess, sys
import mitsuba
out, budgets, rounds, settings, res = sys.argv[1:]
settings = [[int(x) for x in s.split(":")] for s in settings.split()]
cpu = [l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")]
json.dump({"mitsuba": mitsuba.__version__, "variant": "llvm_ad_rgb", "rounds": int(rounds), "settings": settings,
           "depth_rays": 65536, "batch_depth": 8, "res": int(res), "cpu": cpu[0] if cpu else "?",
           "cores": "%d cores" % os.cpu_count(), "uptime_start": subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip(),
           "fit_config": {"material_iterations": 0, "emission_textures": False, "emission_iterations": 100,
                          "max_resolution": int(res)}}, open(os.path.join(out, "meta.json"), "w"), indent=1)
PYEOF

# The room: the demo's capture (24 frames 256x192 at 16 spp, 4 held-out), its ground truth exported to Mitsuba.
stamp "synth"
[[ -f "$OUT/cap/gt/scene.json" ]] || "$R" --log warn synth --scene room --out "$OUT/cap" --frames 24 --test-frames 4 \
  --width 256 --height 192 --spp 16
"$R" --log warn export "$OUT/cap/gt/scene.json" --mitsuba "$OUT/gt_mitsuba" --max-depth 9

# (a) one gradient iteration. The Mitsuba batch is one held-out camera at 1 spp, sized to N pixels;
# its L2 reference is relume's 4-spp render of that camera.
part a && for s in $SETTINGS; do
  n=${s%%:*}; side=$(python3 -c "import math; print(int(round(math.sqrt($n))))")
  [[ -f "$OUT/iter/ref_$side/ref_$side.exr" ]] && continue
  python3 "$PY" camera "$OUT/cap/transforms_test.json" "$OUT/iter/cam_$side.json" --rays "$n"
  "$R" --log warn render --scene "$OUT/cap/gt/scene.json" --cameras "$OUT/iter/cam_$side.json" --out "$OUT/iter/ref_$side" --spp 4 > /dev/null
done
part a && for round in $(seq 1 "$ROUNDS"); do
  for s in $SETTINGS; do
    n=${s%%:*}; d=${s##*:}; side=$(python3 -c "import math; print(int(round(math.sqrt($n))))")
    stamp "(a) round $round: $n rays, depth $d"
    "$R" --log warn profile --what adjoint --rays "$n" --max-depth "$d" --repeats 1 > "$OUT/iter/relume_${n}_${d}_r$round.txt"
    python3 "$PY" iter "$OUT/gt_mitsuba/scene.xml" "$OUT/iter/cam_$side.json" "$OUT/iter/ref_$side/ref_$side.exr" \
      --depth "$d" --repeats 1 --seed "$round" > "$OUT/iter/mitsuba_${n}_${d}_r$round.json"
  done
done

# (e) renderer efficiency, both tracers: relume renders one held-out view (256^2, 4 spp, depth 8) and
# replays exactly its rays through Embree alone (--rays-out keeps them); Mitsuba's `path` integrator
# renders the same view and its own Embree traversal replays the same rays.
if part e; then
  mkdir -p "$OUT/eff"
  [[ -f "$OUT/iter/cam_256.json" ]] || python3 "$PY" camera "$OUT/cap/transforms_test.json" "$OUT/iter/cam_256.json" --rays 65536
  for round in $(seq 1 "$ROUNDS"); do
    stamp "(e) round $round: renderer efficiency"
    "$R" --log warn profile --what render --scene "$OUT/cap/gt/scene.json" --cameras "$OUT/iter/cam_256.json" --spp 4 \
      --max-depth 8 --rays-out "$OUT/eff/rays.bin" > "$OUT/eff/relume_r$round.txt"
    python3 "$PY" efficiency "$OUT/gt_mitsuba/scene.xml" "$OUT/iter/cam_256.json" "$OUT/eff/rays.bin" --spp 4 --depth 8 \
      > "$OUT/eff/mitsuba_r$round.json"
  done
  rm -f "$OUT/eff/rays.bin"
fi

# (b) forward agreement: the existing comparison (Mitsuba scalar_rgb, exported ground truth, 4 held-out views 160x120).
if part b; then
  stamp "(b) forward agreement, SPP=$FWD_SPP"
  SPP="$FWD_SPP" "$ROOT/scripts/mitsuba_compare.sh" "$OUT/forward" > "$OUT/forward.txt"
fi

if part c; then
  # (c) time to accuracy. relume: prepare at 512^2 (the resolution the frames resolve), then
  # `relume fit --time-budget` once per budget.
  stamp "(c) prepare"
  tp0=$(date +%s.%N)
  "$R" --log warn prepare "$OUT/cap" --out "$OUT/work" --res "$RES" --gutter-res "$RES" --force
  tp=$(python3 -c "print($(date +%s.%N) - $tp0)")
  CONFIG=$(python3 -c "import json; print(json.dumps(json.load(open('$OUT/meta.json'))['fit_config']))")
  stamp "(c) relume fits, budgets $BUDGETS"
  python3 "$PY" relumefits "$R" "$OUT/work" "$OUT/fit" --budgets "$BUDGETS" --config "$CONFIG" --prepare-seconds "$tp"
  # Mitsuba: from mid-grey albedo, roughness/specular 0.5 (as relume's fit keeps them), emitters (1,1,1)
  # on the true emitters; snapshots at the budgets (relume may end before its budget: its schedule
  # at its longest, or converged).
  python3 "$PY" initscene "$OUT/cap/gt/scene.json" "$OUT/work" "$OUT/fit/mitsuba_init" --res "$RES"
  "$R" --log warn export "$OUT/fit/mitsuba_init/scene.json" --mitsuba "$OUT/fit/mitsuba_init/mitsuba" --max-depth 9
  stamp "(c) Mitsuba fit, snapshots at $BUDGETS s"
  cut -d' ' -f1 /proc/loadavg > "$OUT/fit/mitsuba_load.txt"
  rm -rf "$OUT/fit/mitsuba"
  python3 "$PY" fit "$OUT/fit/mitsuba_init/mitsuba/scene.xml" "$OUT/cap/transforms.json" "$OUT/fit/mitsuba_init/scene.json" \
    "$OUT/fit/mitsuba" --snapshots "$BUDGETS" --depth 9
  stamp "(c) eval"
  for k in $(seq 0 $(( $(tr ',' '\n' <<< "$BUDGETS" | wc -l) - 1 ))); do
    for sc in "$OUT/fit/relume_$k" "$OUT/fit/mitsuba/t$k"; do
      "$R" --log warn eval --scene "$sc/scene.json" --cameras "$OUT/cap/transforms_test.json" --out "$sc/eval" \
        --truth "$OUT/cap/gt/scene.json" --coverage "$OUT/work/coverage.exr" --spp 4 > /dev/null
    done
  done
fi
uptime > "$OUT/uptime_end.txt"
stamp "table"
python3 "$PY" table "$OUT"
echo "total $(( $(date +%s) - T0 )) s"
