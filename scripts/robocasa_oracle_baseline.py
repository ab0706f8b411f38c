"""Measure the RoboCasa oracle's baseline on the placeholder tree and write it to the data file the slow test reads.

    INDGEN_ROBOCASA_ASSETS=DIR python scripts/robocasa_oracle_baseline.py [--tasks T1,T2] [--out FILE]
    python scripts/robocasa_oracle_baseline.py --table   # the file as the markdown table docs/results quotes

DIR is a placeholder tree (``indgen setup robocasa --placeholders DIR``); each task's levels run ``evaluate``'s
episodes (seed 0) under RoboCasa365's default split, pretrain. ``--tasks`` re-measures those tasks and keeps the
file's others (their rows must come from the same oracle version and tree: the default-suite test checks). Every
scripted task (``RoboCasaOracle.tasks``) has a row in ``PLAN``.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import sys
import time
from pathlib import Path

from scenes.family import get_scene

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OUT = ROOT / "tests/scenes/robocasa/oracle_baseline.json"
SPLIT = "pretrain"  # RoboCasa365's default split (scenes.robocasa.splits.DEFAULT_SPLIT), what evaluate runs
EPISODES = 2
# task -> (axis, levels): the three pick-place tasks issue 54 recorded at its levels (counter to cabinet base_y
# 0..2, counter to drawer and to sink horizon 0..1), CoffeeSetupMug at two pick_x levels, every other task at
# level 0 of an axis of its own
PLAN: dict[str, tuple[str, tuple[int, ...]]] = {
    "PickPlaceCounterToCabinet": ("base_y", (0, 1, 2)),
    "PickPlaceCounterToDrawer": ("horizon", (0, 1)),
    "PickPlaceCounterToSink": ("horizon", (0, 1)),
    "PickPlaceCounterToBlender": ("horizon", (0,)),
    "PickPlaceFridgeDrawerToShelf": ("horizon", (0,)),
    "PickPlaceCabinetToCounter": ("clutter", (0,)),
    "PickPlaceSinkToCounter": ("pick_x", (0,)),
    "CoffeeSetupMug": ("pick_x", (0, 1)),
    "CheesyBread": ("pick_x", (0,)),
    "CloseToasterOvenDoor": ("horizon", (0,)),
    "CloseStandMixerHead": ("fixture_x", (0,)),
    "OpenStandMixerHead": ("fixture_x", (0,)),
    "TurnOnBlender": ("fixture_x", (0,)),
    "OpenElectricKettleLid": ("fixture_x", (0,)),
    "CloseElectricKettleLid": ("fixture_x", (0,)),
    "TurnOnElectricKettle": ("fixture_x", (0,)),
}


def table(data: dict) -> str:
    """The baseline as a markdown table: a row per task, each level's successes / episodes and steps."""
    rows = ["| task | axis | level: successes / n (steps of each episode) |", "|---|---|---|"]
    for task, row in data["tasks"].items():
        cells = [f"{k}: {v['successes']}/{v['episodes']} ({', '.join(map(str, v['steps']))})"
                 for k, v in row["levels"].items()]  # fmt: skip
        rows.append(f"| {task} | `{row['axis']}` | {'; '.join(cells)} |")
    return "\n".join(rows)  # no pooled total: each cell is one task at one level


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--tasks", default=",".join(PLAN), help="comma list (default: every task of PLAN)")
    p.add_argument("--out", type=Path, default=OUT)
    p.add_argument("--table", action="store_true", help="print the file as a markdown table; measure nothing")
    args = p.parse_args()
    if args.table:
        print(table(json.loads(args.out.read_text())))
        return 0
    from indgen_vla.app.certify.baseline import baseline_episodes, level_entry
    from scenes.oracles import oracle_identity
    from scenes.robocasa.placeholder_tree import VERSION

    if not os.environ.get("INDGEN_ROBOCASA_ASSETS"):
        print("error: set INDGEN_ROBOCASA_ASSETS (indgen setup robocasa --placeholders DIR writes a tree)")
        return 2
    tasks = [t for t in args.tasks.split(",") if t]
    unknown = [t for t in tasks if t not in PLAN]
    if unknown:
        print(f"error: no baseline plan for {', '.join(unknown)}; one of {', '.join(PLAN)}")
        return 2
    data = json.loads(args.out.read_text()) if args.out.is_file() else {"tasks": {}}
    oracle = {
        k: v for k, v in oracle_identity(get_scene("robocasa")).items() if k in ("name", "version")
    }  # not the code hash
    data.update(scene="robocasa", split=SPLIT, seed=0, oracle=oracle, tree_version=VERSION)
    for task in tasks:
        axis, levels = PLAN[task]
        rows = {}
        for level in levels:
            t0 = time.time()
            results = baseline_episodes(
                get_scene("robocasa"), task, axis, level, EPISODES, options={"split": SPLIT}
            )
            rows[str(level)] = level_entry(results)
            print(f"{task} {axis} {level}: {rows[str(level)]} ({time.time() - t0:.0f} s)", flush=True)
        data["tasks"][task] = {"axis": axis, "levels": rows}
        data["tasks"] = dict(sorted(data["tasks"].items()))
        data["measured"] = f"{datetime.date.today()}, {platform.machine()} with {os.cpu_count()} cores"
        # after every task: an interrupted run keeps those done
        args.out.write_text(json.dumps(data, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
