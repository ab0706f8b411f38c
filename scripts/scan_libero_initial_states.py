"""Which of LIBERO's fixed initial states a level cannot hold: the moved pick object (or basket) overlaps a
neighbour, and MuJoCo throws it out during lerobot's settling steps or the first steps of the episode.

For each (task, axis, level) and initial state i (= episode i, the state ``episode % 50``) it resets the level,
holds the arm still for ``--steps`` no-op steps, and records how far the pick object and the basket ended from
the poses the level put them at (xy, the largest over the reset and those steps). LIBERO's own states (level 0)
are at rest: 0.0 mm. A state the env's placement check refuses (``scenes.libero.placement_check``: the level's
pose more than 5 mm inside a neighbour, or moved more than 1 cm by the settle) is listed as ``unavailable`` with
the check's reason; its move is the one after the settle. Rows go to a JSONL file as each level finishes (a
killed scan resumes).

    python scripts/scan_libero_initial_states.py --out scan.jsonl --tasks cream_cheese --axes pick_y --levels=-3,-2
    python scripts/scan_libero_initial_states.py --out scan.jsonl --table
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from scenes.family import get_scene

SCENE = "libero_object"
MOVED = 0.01  # a state whose pick object or basket ends this far (m) from its level pose: thrown, not settled


def moved(env, episode: int, steps: int) -> list[float]:
    """How far (xy, m) the pick object and the basket got from their level poses: the largest over the reset of
    ``episode`` and ``steps`` no-op steps after it (after the reset only, where the placement check refused it)."""
    return watch(env, episode, steps)[0]


def watch(env, episode: int, steps: int) -> tuple[list[float], str]:
    """``moved``'s distances and the placement check's reason for refusing the state ('' where it holds)."""
    import numpy as np

    from indgen_vla.core.errors import EpisodeUnavailableError
    from scenes.libero.env import DUMMY_ACTION

    why = ""
    try:
        env.reset(seed=0, options={"episode": episode})
    except EpisodeUnavailableError as e:
        why, steps = str(e).split(": ", 1)[1], 0  # the env holds the state as the settle left it
    pose = env._level_state(env.init_index)
    bodies = [(1 + env._qpos[env.info.pick], env._pick_body), (1 + env._qpos[env.info.goal], env._goal_body)]
    worst = [0.0, 0.0]
    for t in range(steps + 1):
        xpos = env._env.sim.data.body_xpos
        for k, (q, b) in enumerate(bodies):
            worst[k] = max(worst[k], float(np.linalg.norm(xpos[b][:2] - pose[q : q + 2])))
        if t < steps:
            env.step(np.array(DUMMY_ACTION, dtype=np.float32))
    return [round(w, 4) for w in worst], why


def scan_level(task: str, axis: str, level: int, states: int, steps: int) -> dict:
    """``moved`` for each of ``states`` initial states of one level, and the states thrown (> ``MOVED``)."""
    from scenes.planning import resolve_scene_plan

    t0 = time.time()
    plan = resolve_scene_plan(get_scene(SCENE), task, (axis,), [level])
    env = plan.builder.make_env(task, axis, level, cameras=(), image_size=(64, 64), max_steps=None)
    try:
        seen = [watch(env, i, steps) for i in range(states)]
    finally:
        env.close()
    rows = [m for m, _ in seen]
    thrown = [i for i, (p, g) in enumerate(rows) if max(p, g) > MOVED]
    unavailable = {i: why for i, (_, why) in enumerate(seen) if why}
    return {"task": task, "axis": axis, "level": level, "states": states, "steps": steps, "moved": rows,
            "thrown": thrown, "unavailable": unavailable, "wall_s": round(time.time() - t0, 1)}  # fmt: skip


def table(out: Path) -> str:
    """Markdown: one row per (task, axis, level) with the states thrown and the largest displacement."""
    rows = {}
    for line in out.read_text().splitlines():
        if line.strip():
            r = json.loads(line)
            rows[(r["task"], r["axis"], r["level"])] = r
    lines = [
        "| task | axis | level | states thrown (> 1 cm) | largest move: pick / basket (cm) | unavailable (placement check) |",
        "|---|---|---|---|---|---|",
    ]
    for (t, a, k), r in sorted(rows.items()):
        p = max(m[0] for m in r["moved"]) * 100
        g = max(m[1] for m in r["moved"]) * 100
        kept = [i for i in range(r["states"]) if i not in r["thrown"]]
        ids = ", ".join(map(str, r["thrown"])) or "-"
        if len(kept) < len(r["thrown"]):
            ids = "all but " + (", ".join(map(str, kept)) or "none")
        gone = r.get("unavailable")
        refused = "not checked" if gone is None else f"{len(gone)}/{r['states']}"
        lines.append(
            f"| {t} | {a} | {k:+d} | {len(r['thrown'])}/{r['states']}: {ids} | {p:.1f} / {g:.1f} | {refused} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="JSONL file of scanned levels (appended; resumes)")
    ap.add_argument("--tasks", default="all", help="comma-separated tasks (default: all ten)")
    ap.add_argument("--axes", default="pick_y,goal_y,scale", help="comma-separated axes")
    ap.add_argument("--levels", default=None, help="comma-separated levels (default: each axis's range)")
    ap.add_argument("--states", type=int, default=50, help="initial states (episodes 0..N-1)")
    ap.add_argument("--steps", type=int, default=10, help="no-op steps after the reset to watch")
    ap.add_argument("--table", action="store_true", help="print the markdown table of --out and exit")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.table:
        print(table(out))
        return 0
    import scenes
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.axes import get_successor

    tasks = list(scenes.get_scene(SCENE).tasks) if a.tasks == "all" else tuple(a.tasks.split(","))
    done = set()
    if out.is_file():
        done = {
            (r["task"], r["axis"], r["level"]) for r in map(json.loads, out.read_text().splitlines()) if r
        }
    for axis in a.axes.split(","):
        levels = (
            [int(x) for x in a.levels.split(",")]
            if a.levels
            else list(get_successor(AxisRef.parse(axis)).axis.default_levels())
        )
        for task in tasks:
            for k in levels:
                if (task, axis, k) in done:
                    continue
                r = scan_level(task, axis, k, a.states, a.steps)
                with out.open("a") as f:
                    f.write(json.dumps(r) + "\n")
                print(f"{task} {axis} {k:+d}: {len(r['thrown'])}/{r['states']} thrown {r['thrown']}, "
                      f"{len(r['unavailable'])} unavailable ({r['wall_s']:.0f} s)", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
