#!/usr/bin/env bash
# Renders a fit report (WORK/report/index.html, written by `relume fit` or `relume report`) in
# headless Chromium, offline, and saves a full-page screenshot to look at. Not part of the test
# suite (needs Debian's `chromium`). Fails if the page references anything outside its folder.
#
# Usage: scripts/report_check.sh WORK_DIR [SCREENSHOT.png]   (default WORK_DIR/report/screenshot.png)
set -euo pipefail
WORK="$1"
PAGE="$(cd "$WORK/report" && pwd)/index.html"
SHOT="${2:-$WORK/report/screenshot.png}"
command -v chromium > /dev/null || { echo "report_check: chromium not found (apt-get install chromium)" >&2; exit 1; }
if grep -Eo '(src|href)="[^"]*"' "$PAGE" | grep -Ev '="[A-Za-z0-9_.-]+"$'; then
  echo "report_check: the page references something outside its folder (above)" >&2
  exit 1
fi
for f in $(grep -Eo 'src="[^"]*"' "$PAGE" | sed 's/src="\(.*\)"/\1/'); do
  [[ -f "$(dirname "$PAGE")/$f" ]] || { echo "report_check: missing image $f" >&2; exit 1; }
done
# No network: an unroutable proxy makes any remote request fail instead of silently loading.
chromium --headless --no-sandbox --disable-gpu --proxy-server=127.0.0.1:9 --hide-scrollbars \
  --window-size=1400,4200 --screenshot="$SHOT" "file://$PAGE" 2> /dev/null
echo "report_check: $PAGE rendered to $SHOT"
