"""RoboCasa365 pick_x per kitchen: the range RoboCasa samples each task's pick object in (its declared region clipped
to the fixture, less the object's buffer for its centre), the level offsets and windows the worker uses there, and
the kitchens and objects that cannot hold the levels.

    INDGEN_ROBOCASA_ASSETS=DIR python scripts/robocasa_pick_regions.py [--seeds 16] [--task T ...] [--json OUT]

Every level 0..4 of every task is built and reset through ``resolve_scene_plan(...).builder`` (the run's own path: the plan's pick
config, the worker's window, its T0 cache); prints one markdown table for docs/results/robocasa_pick_regions.md.
"""

from __future__ import annotations

import argparse
import json
import re
import statistics
import time

from scenes.family import get_scene


def measure(task: str, seeds: list[int]) -> dict:
    """Each seed's range, and per level the episode's offset and window, or why the kitchen holds no level."""
    from indgen_vla.core.errors import EpisodeUnavailableError
    from scenes.planning import resolve_scene_plan
    from scenes.robocasa.pick_window import PICK_KEY

    rows: dict[int, dict] = {s: {"levels": {}} for s in seeds}
    for level in range(5):
        plan = resolve_scene_plan(get_scene("robocasa"), task, ("pick_x",), [level])
        env = plan.builder.make_env(task, "pick_x", level, cameras=(), image_size=(128, 128), max_steps=None)
        try:
            for seed in seeds:
                try:
                    env.reset(seed=seed)
                except EpisodeUnavailableError as e:  # its line names the kitchen's range
                    rows[seed].update(
                        unavailable=str(e),
                        width=float(re.search(r"a ([\d.]+) m range", str(e))[1]),
                        buffer=float(re.search(r"keeps ([\d.]+) m of it", str(e))[1]),
                    )
                    continue
                meta = env.call("ep_meta")
                lo, hi = meta[PICK_KEY]["range"]
                rows[seed].update(
                    range=[lo, hi], width=hi - lo, buffer=meta[PICK_KEY]["buffer"],
                    kitchen=(meta["layout_id"], meta["style_id"]),
                )  # fmt: skip
                rows[seed]["levels"][level] = {"param": env.episode_param, "window": meta[PICK_KEY]["window"]}
        finally:
            env.close()
    return rows


def summarize(task: str, rows: dict[int, dict]) -> dict:
    """The task's line: kitchens, clipped ones, their widths, the objects' buffers, unavailable ones (narrow
    kitchens apart), and whether every window held the object's centre its buffer inside the range."""
    from scenes.robocasa import PICK_REGIONS

    declared = PICK_REGIONS[task].width
    widths = [r["width"] for r in rows.values()]
    buffers = [r["buffer"] for r in rows.values()]
    held = all(
        lv["window"][0] - r["buffer"] >= r["range"][0] - 1e-9 and lv["window"][1] + r["buffer"] <= r["range"][1] + 1e-9
        for r in rows.values() if "range" in r for lv in r["levels"].values()
    )  # fmt: skip
    return {
        "task": task, "declared": declared, "kitchens": len(rows),
        "clipped": sum(w < declared - 1e-9 for w in widths), "min": min(widths), "median": statistics.median(widths),
        "buffer": (min(buffers), max(buffers)), "unavailable": sum("unavailable" in r for r in rows.values()),
        "narrow": sum("unavailable" in r and r["width"] <= 0.2 + 1e-9 for r in rows.values()),
        "windows_in_range": held,
    }  # fmt: skip


def table(lines: list[dict]) -> str:
    out = ["| task | declared (m) | kitchens | clipped | range min / median (m) | buffer min..max (m) | unavailable "
           "(range <= 0.20 m) | windows +- buffer in range |", "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for s in lines:
        out.append(f"| {s['task']} | {s['declared']:.2f} | {s['kitchens']} | {s['clipped']} | {s['min']:.3f} / "
                   f"{s['median']:.3f} | {s['buffer'][0]:.3f}..{s['buffer'][1]:.3f} | {s['unavailable']} "
                   f"({s['narrow']}) | {'yes' if s['windows_in_range'] else 'NO'} |")  # fmt: skip
    return "\n".join(out)


def main() -> None:
    from scenes.robocasa import AXIS_TASKS

    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--seeds", type=int, default=16, help="episode seeds 0..N-1 (RoboCasa draws each kitchen)")
    p.add_argument("--task", nargs="*", default=list(AXIS_TASKS["pick_x"]))
    p.add_argument("--json", help="also write every seed's numbers here")
    args = p.parse_args()
    t0, seeds, lines, raw = time.time(), list(range(args.seeds)), [], {}
    for task in args.task:
        raw[task] = measure(task, seeds)
        lines.append(summarize(task, raw[task]))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(raw, f, indent=1)
    print(table(lines))
    print(f"\n({len(seeds)} seeds x {len(args.task)} tasks x 5 levels in {time.time() - t0:.0f} s)")


if __name__ == "__main__":
    main()
