#!/usr/bin/env bash
# `make demo`: evaluate the shipped trained stand-in (a state-only ACT trained on human-like T0 demos,
# checkpoints/act_pick_place_human) and the privileged oracle side by side on the built-in pick_place
# scene along pick_y (levels -3..3), then write the comparison report and plots.
set -euo pipefail
cd "$(dirname "$0")/.."
export MUJOCO_GL="${MUJOCO_GL:-egl}" HF_HUB_OFFLINE=1
OUT="${DEMO_OUT:-demo_out}"
EPISODES="${DEMO_EPISODES:-10}"  # >= 5: below that a level has too little data for a rate
INDGEN=.venv/bin/indgen
start=$(date +%s)
run() {  # run NAME POLICY REGIME
  echo "== indgen evaluate --policy $2 --scene pick_place --axis pick_y --levels -3:3 --episodes $EPISODES"
  "$INDGEN" evaluate --policy "$2" --scene pick_place --axis pick_y --levels -3:3 \
    --episodes "$EPISODES" --workers 2 --data-regime "$3" --out "$OUT/$1"
}
run act lerobot:checkpoints/act_pick_place_human h-only
run oracle standin:oracle oracle
"$INDGEN" report "$OUT/act" "$OUT/oracle" --out "$OUT/compare" >/dev/null
echo
echo "demo finished in $(( $(date +%s) - start )) s"
echo "  per-run reports: $OUT/act/report.md  $OUT/oracle/report.md"
echo "  comparison:      $OUT/compare/report.md"
echo "  plots:           $OUT/compare/plots/pick_y.png"
echo "  episodes:        $OUT/act/episodes.parquet (re-run to resume; delete $OUT to start over)"
