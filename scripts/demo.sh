#!/usr/bin/env bash
# `make demo`: evaluate the shipped trained stand-in (a state-only ACT trained on human-like T0 demos,
# checkpoints/act_pick_place_human) and the privileged oracle side by side on the built-in pick_place
# scene along pick_y (levels -3..3), then write the comparison report and plots (report.md and report.html each).
set -euo pipefail
cd "$(dirname "$0")/.."
export MUJOCO_GL="${MUJOCO_GL:-egl}" HF_HUB_OFFLINE=1
OUT="${DEMO_OUT:-demo_out}"
EPISODES="${DEMO_EPISODES:-10}"  # >= 5: below that a level has too little data for a rate
INDGEN="${INDGEN:-.venv/bin/indgen}"  # another install of indgen: INDGEN=/path/to/indgen make demo
start=$(date +%s)
run() {  # run NAME POLICY REGIME
  echo "== indgen evaluate --policy $2 --scene pick_place --axis pick_y --levels -3:3 --episodes $EPISODES"
  "$INDGEN" evaluate --policy "$2" --scene pick_place --axis pick_y --levels -3:3 \
    --episodes "$EPISODES" --workers 2 --data-regime "$3" --out "$OUT/$1"
}
run act lerobot:checkpoints/act_pick_place_human h-only
run oracle standin:oracle oracle
# what each level looks like at t = 0 (no policy; the same scenes for both runs): report.html shows it
if [ ! -s "$OUT/act/preview/pick_y.png" ]; then
  "$INDGEN" preview --scene pick_place --axis pick_y --levels -3:3 --size 160 --out "$OUT/act/preview/pick_y.png"
fi
mkdir -p "$OUT/oracle/preview" && cp "$OUT/act/preview/pick_y.png" "$OUT/oracle/preview/pick_y.png"
"$INDGEN" report "$OUT/act" "$OUT/oracle" --out "$OUT/compare" >/dev/null
echo
echo "demo finished in $(( $(date +%s) - start )) s"
echo "  per-run reports: $OUT/act/report.md  $OUT/oracle/report.md"
echo "  comparison:      $OUT/compare/report.md"
echo "  in a browser:    $OUT/*/report.html, or all of them: $INDGEN view $OUT  (http://127.0.0.1:8765/)"
echo "  plots:           $OUT/compare/plots/pick_y.png"
echo "  episodes:        $OUT/act/episodes.parquet (re-run to resume; delete $OUT to start over)"
