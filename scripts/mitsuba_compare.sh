#!/usr/bin/env bash
# `relume export --mitsuba` in the real consumer: Mitsuba 3 (scalar_rgb, CPU) loads the exported
# scene.xml as is and renders the cameras; per-object means are compared with relume's render of
# the same cameras (docs/user/export.md). Not part of the test suite, and Mitsuba is never a
# dependency of relume: `pip install mitsuba` (3.x).
#
# Usage: scripts/mitsuba_compare.sh [SCENE.json|WORK_DIR CAMERAS.json] [OUT_DIR]
#   default: the synthetic room's ground truth and its 4 held-out views (160x120), in out/mitsuba_compare
# Environment: SPP=256 (each half, both renderers)
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
python3 -c "import mitsuba" 2> /dev/null || { echo "mitsuba_compare: Mitsuba 3 not found (pip install mitsuba)" >&2; exit 1; }
DEFAULT_OUT="$ROOT/out/mitsuba_compare"
# shellcheck source=export_check_input.sh
source "$ROOT/scripts/export_check_input.sh"
"$R" --log warn export "$INPUT" --mitsuba "$OUT/mitsuba"
PY="$ROOT/scripts/mitsuba_compare.py"
for seed in 1 2; do
  "$R" --log warn render --scene "$SCENE" --cameras "$CAMERAS" --out "$OUT/relume_$seed" --spp "$SPP" --seed "$seed" --aov object
  python3 "$PY" render "$OUT/mitsuba/scene.xml" "$CAMERAS" "$OUT/mitsuba_$seed" --spp "$SPP" --seed "$seed"
done
echo "relume ($SPP+$SPP spp) / Mitsuba $(python3 -c 'import mitsuba; print(mitsuba.__version__)') scalar_rgb on the exported scene.xml ($SPP+$SPP spp)"
python3 "$PY" compare "$CAMERAS" "$SCENE" "$OUT/relume_1" "$OUT/relume_2" "$OUT/mitsuba_1" "$OUT/mitsuba_2"
