"""``indgen demos``: its parser (over the passthrough arguments); the handler records the demonstrations
(``indgen_vla.app.regimes.demos.record_demos``) and prints what it kept."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_level_options, add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen demos`` parses its own arguments (``main``)."""
    add_passthrough(sp, "demos", "record demonstrations (T0, or levels of one axis) as a LeRobotDataset")


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    import os
    from pathlib import Path

    from indgen_vla.app.regimes import quiet_datasets
    from indgen_vla.app.regimes.demos import HumanNoise, LevelRequest, record_demos
    from scenes.family import get_scene

    p = IndgenParser(
        prog="indgen demos",
        description="record noisy-oracle demonstrations (T0, or --axis A --levels 0:2) as a LeRobotDataset; "
        "rerunning the same command resumes an interrupted recording",
    )
    p.add_argument("--scene", required=True, help="built-in scene to record (see `indgen scenes`)")
    p.add_argument("--task", default=None, help="task name or 'all' (default: the scene's first task)")
    p.add_argument(
        "--axis", default=None, help="record levels of this axis (see 'indgen axes'); default: T0 only"
    )
    add_level_options(p, levels_default="required with --axis")
    p.add_argument("--n", type=int, required=True, help="successful episodes per task (and level)")
    p.add_argument(
        "--out", required=True, help="dataset root: a new directory, or one to resume (same arguments)"
    )
    p.add_argument(
        "--seed", type=int, default=0, help="base seed; episode i of a task always gets the same seed"
    )
    p.add_argument("--image-size", type=int, default=96, help="camera side in pixels (square frames)")
    p.add_argument("--noise", type=float, default=0.1, help="std of motion noise (action units)")
    p.add_argument(
        "--pause-prob", type=float, default=0.02, help="per-step probability of a human-like pause"
    )
    p.add_argument(
        "--repo-id", default="local/indgen_demos", help="LeRobotDataset repo id stored in the dataset"
    )
    p.add_argument("--videos", action="store_true", help="store cameras as mp4 videos instead of images")
    p.add_argument(
        "--cameras", default="agentview,wrist", help="comma-separated cameras to record; empty = state only"
    )
    p.add_argument(
        "--objects",
        action="store_true",
        help="also record the pick and target poses as observation.environment_state (low-dim policies)",
    )
    p.add_argument("--workers", type=int, default=None, help="worker processes recording episodes (default: "
                   "number of cores); the dataset is the same for any number")  # fmt: skip
    a = p.parse_args(args.rest)
    cams = tuple(c for c in a.cameras.split(",") if c)
    levels = LevelRequest(a.axis, a.levels, a.step, a.axes_preset)
    quiet_datasets()
    from rich.console import Console

    console = Console(stderr=True, soft_wrap=True)  # a line is one line in a log, whatever the width

    def progress(label, kept, attempt):
        console.print(f"  {label}: {kept}/{a.n} kept ({attempt} attempts)", end="\r")

    out = Path(a.out)
    stats = record_demos(get_scene(a.scene), out, a.n, a.task, a.seed, a.image_size,
                         noise=HumanNoise(sigma=a.noise, pause_prob=a.pause_prob), repo_id=a.repo_id,
                         use_videos=a.videos, progress=progress, cameras=cams, objects=a.objects, levels=levels,
                         workers=(os.cpu_count() or 1) if a.workers is None else a.workers, notice=console.print)  # fmt: skip
    where = f" at levels {', '.join(map(str, stats['levels']))} of {stats['axis']}" if "axis" in stats else ""
    if stats.get("already_complete"):
        console.print(f"{out} is already complete: {stats['episodes']} episodes ({stats['frames']} frames) of "
                      f"{a.scene} {', '.join(stats['tasks'])}{where}; nothing to do")  # fmt: skip
        return 0
    console.print(f"\nrecorded {stats['episodes']} episodes ({stats['frames']} frames) of {a.scene} "
                  f"{', '.join(stats['tasks'])}{where} into {out}; oracle keep rate {100 * stats['success_rate']:.0f}% "
                  f"({stats['episodes']} of {stats['attempts']} attempts, pooled over tasks and levels)")  # fmt: skip
    if "axis" in stats:
        console.print("kept per task and level: " + ", ".join(
            f"{c['task']} {c['level']}: {c['kept']}/{c['attempts']}" for c in stats["cells"]))  # fmt: skip
    return 0
