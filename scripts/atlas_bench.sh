#!/usr/bin/env bash
# Reruns the atlas table of docs/notes/2026-11-22-prepare-and-atlas.md: for each scene, a short capture rendered by relume itself, `relume prepare` end to
# end, and one table row from its prepare.json.
#
# The real interiors come from https://github.com/VElysianP/mitsuba_scenes (artist-made rooms,
# Mitsuba XML; not committed here, 10-60 MB each). Point MIRROR at a clone of it (any git
# directory holding its history: files are read with `git show HEAD:path`), e.g.
#   git clone https://github.com/VElysianP/mitsuba_scenes /data/mitsuba_scenes
#   MIRROR=/data/mitsuba_scenes scripts/atlas_bench.sh
# The procedural room and the 1M-triangle scan are made by `relume synth`. Captures already in OUT
# are reused (delete one to convert and render it again); `prepare` always reruns. Needs
# build/relume (scripts/demo.sh builds it) and python3 with numpy. OUT defaults
# to out/atlas_bench.
set -euo pipefail
cd "$(dirname "$0")/.."
RELUME=$(realpath "${RELUME:-build/relume}")
OUT=${OUT:-out/atlas_bench}
MIRROR=${MIRROR:-}
mkdir -p "$OUT"

# scene name | xml inside the mirror | metres per unit
REAL=(
  "statler_elevatorroom|statler_elevatorroom/elevatorRoom_statler_revised.xml|0.01"
  "flower_bedroom|flower_bedroom/bedroom_flower.xml|0.01"
  "starLight_loftroom|starLight_loftroom/loftroom_starlight.xml.xml|0.1"
  "glassChandelier_livingroom|glassChandelier_livingroom/livingroom_glassChandelier_final.xml|0.1"
)

# Runs prepare on a capture, keeping its log (the atlas summary line) next to the work folder.
prepare() {  # capture folder
  "$RELUME" prepare "$1" --out "$1/work" --force 2>&1 | tee "$1/prepare.log"
}

row() {  # name, capture folder
  python3 - "$1" "$2" <<'EOF'
import json, re, sys
name, cap = sys.argv[1], sys.argv[2]
p = json.load(open(f"{cap}/work/prepare.json"))
a, i = p["phases"]["atlas"], p["phases"]["init"]
s = a["stretch_p05_median_p95"]
log = open(f"{cap}/prepare.log").read()
hollow = re.search(r"(\d+) hollow ones cut", log).group(1)
blocked = re.search(r"(\d+) tiny ones in (\d+) shared blocks holding ([\d.]+)% of the surface", log)
print(f"| {name} | {a['triangles']:,} | {a['charts']:,} | {int(hollow):,} | {int(blocked.group(1)):,} in {blocked.group(2)} ({blocked.group(3)}%) | {a['packing_efficiency']:.3f} | "
      f"{s[0]:.2f}/{s[1]:.2f}/{s[2]:.2f} | {a['texels_per_metre']:.1f} | {a['atlas_seconds']:.1f} s | {a['uv_overlaps']} | "
      f"{a['dropped_degenerate']}/{a['dropped_coincident']} | {i['texels_geometric_normal']:,} | "
      f"{p['phases']['visibility']['skipped_rays'] + i['skipped_rays']} | {p['seconds_total_last_run']:.1f} s |")
EOF
}

rows=()
if [[ -n "$MIRROR" ]]; then
  for entry in "${REAL[@]}"; do
    IFS='|' read -r name xml scale <<<"$entry"
    cap="$OUT/$name"
    if [[ ! -d "$cap/images" ]]; then
      python3 scripts/mitsuba_to_capture.py --git "$MIRROR" --xml "$xml" --scale "$scale" --out "$cap"
      (cd "$cap" && mkdir -p images.tmp && "$RELUME" render --scene scene.json --cameras transforms.json --out images.tmp --spp 32 --max-depth 4 && mv images.tmp images)
    fi
    prepare "$cap"
    rows+=("$(row "$name ($scale m/unit)" "$cap")")
  done
else
  echo "MIRROR not set: skipping the real interiors (see the top of this script)" >&2
fi

[[ -f "$OUT/room/transforms.json" ]] || "$RELUME" synth --scene room --out "$OUT/room" --frames 24 --width 256 --height 192
prepare "$OUT/room"
rows+=("$(row "room (procedural)" "$OUT/room")")
[[ -f "$OUT/scan/transforms.json" ]] || "$RELUME" synth --scene scan --out "$OUT/scan" --frames 20 --width 64 --height 48 --spp 1 --max-depth 2
prepare "$OUT/scan"
rows+=("$(row "scan (procedural, noisy)" "$OUT/scan")")

echo "| scene | triangles | charts | hollow charts cut | tiny charts in shared blocks (surface share) | efficiency | stretch p05/median/p95 | texels/m at 1024 | atlas time | uv overlaps | dropped degenerate/coincident | texels on geometric normal | skipped rays | prepare total |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"
printf '%s\n' "${rows[@]}"
