#!/usr/bin/env bash
# `make demo`: evaluate the privileged oracle and a random stand-in side by side on the built-in
# pick_place scene along pick_y (levels -3..3), then write the comparison report and plots.
set -euo pipefail
cd "$(dirname "$0")/.."
export MUJOCO_GL="${MUJOCO_GL:-egl}" HF_HUB_OFFLINE=1
OUT="${DEMO_OUT:-demo_out}"
EPISODES="${DEMO_EPISODES:-4}"
INDGEN=.venv/bin/indgen
start=$(date +%s)
for policy in oracle random; do
  echo "== indgen evaluate --policy standin:$policy --scene pick_place --axis pick_y --levels -3:3 --episodes $EPISODES"
  "$INDGEN" evaluate --policy "standin:$policy" --scene pick_place --axis pick_y --levels -3:3 \
    --episodes "$EPISODES" --workers 2 --data-regime "$policy" --out "$OUT/$policy"
done
"$INDGEN" report "$OUT/oracle" "$OUT/random" --out "$OUT/compare" >/dev/null
echo
echo "demo finished in $(( $(date +%s) - start )) s"
echo "  per-run reports: $OUT/oracle/report.md  $OUT/random/report.md"
echo "  comparison:      $OUT/compare/report.md"
echo "  plots:           $OUT/compare/plots/pick_y.png"
echo "  episodes:        $OUT/oracle/episodes.parquet (re-run to resume; delete $OUT to start over)"
