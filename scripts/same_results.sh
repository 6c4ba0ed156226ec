#!/usr/bin/env bash
# Do two relume binaries compute the same thing? Runs the same small pipeline with each, then
# compares every output byte for byte: the synthetic capture (a render of every frame and AOV), the
# prepared texture space, the checkpoint after 200 fit iterations, the whole fit's result and a
# render with edits. Use it around a restructuring that must not change behaviour.
#   scripts/same_results.sh OLD_BINARY NEW_BINARY [SCRATCH]
set -euo pipefail
[ $# -ge 2 ] || { echo "usage: $0 OLD_BINARY NEW_BINARY [SCRATCH]" >&2; exit 2; }
A="$(realpath "$1")" B="$(realpath "$2")" SCRATCH="${3:-/tmp/relume_same_results}"
rm -rf "$SCRATCH" && mkdir -p "$SCRATCH"

run() {  # BINARY DIR
  local bin="$1" d="$2"
  mkdir -p "$d"
  "$bin" --log warn synth --scene room --out "$d/cap" --frames 12 --test-frames 2 --test-spp 16 --width 160 --height 120
  "$bin" --log warn render --scene "$d/cap/gt/scene.json" --cameras "$d/cap/transforms_test.json" --out "$d/views" \
    --spp 8 --aov albedo,normal,depth,object
  "$bin" --log warn prepare "$d/cap" --out "$d/work" --res 256,512 --gutter-res 256
  cp -r "$d/work" "$d/work200"
  cat > "$d/fit.json" <<'EOF'
{"emission_iterations": 100, "material_iterations": 150, "albedo_passes": 20, "samples_per_ray": 1,
 "emission_texture_iterations": 40}
EOF
  jq '. + {"stop_after_iterations": 200}' "$d/fit.json" > "$d/fit200.json"
  "$bin" --log warn fit "$d/work200" --config "$d/fit200.json" --no-report
  "$bin" --log warn fit "$d/work" --config "$d/fit.json" --no-report
  "$bin" --log warn eval --scene "$d/work/result/scene.json" --cameras "$d/cap/transforms_test.json" --out "$d/eval" \
    --truth "$d/cap/gt/scene.json" --coverage "$d/work/coverage.exr" --spp 8
}

run "$A" "$SCRATCH/a" > "$SCRATCH/a.log" 2>&1 || { echo "$A failed: $SCRATCH/a.log" >&2; exit 1; }
run "$B" "$SCRATCH/b" > "$SCRATCH/b.log" 2>&1 || { echo "$B failed: $SCRATCH/b.log" >&2; exit 1; }

# Timings, peak memory, the scratch folder (and the fingerprints that hash it)'s name and the EXR header's capture date differ between
# runs by nature; everything else must not.
python3 - "$SCRATCH/a" "$SCRATCH/b" <<'PY'
import json, pathlib, re, sys
a, b = map(pathlib.Path, sys.argv[1:3])
VARYING = re.compile(r"second|_ms$|elapsed|rss|^time|fingerprint")  # fingerprints hash the paths
def scrub(v):
    if isinstance(v, dict): return {k: scrub(x) for k, x in v.items() if not VARYING.search(k)}
    if isinstance(v, list): return [scrub(x) for x in v]
    return v
def content(path, root):
    data = path.read_bytes().replace(str(root).encode(), b"ROOT")
    if path.suffix == ".exr": return re.sub(rb"capDate\x00string\x00\x13\x00\x00\x00.{19}", b"capDate", data, flags=re.S)
    if path.suffix in (".json", ".jsonl"):
        return [scrub(json.loads(line)) for line in data.decode().splitlines() if line.strip()] if path.suffix == ".jsonl" \
            else scrub(json.loads(data))
    return data
fa = sorted(p.relative_to(a) for p in a.rglob("*") if p.is_file())
fb = sorted(p.relative_to(b) for p in b.rglob("*") if p.is_file())
differ = [str(f) for f in sorted(set(fa) ^ set(fb))]
for f in fa:
    if f in set(fb) and content(a / f, a) != content(b / f, b): differ.append(str(f))
for f in differ: print("differs:", f)
print(f"{len(fa)} files compared, {len(differ)} differ")
sys.exit(1 if differ else 0)
PY
