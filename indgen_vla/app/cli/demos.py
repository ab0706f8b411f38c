"""``indgen demos``: its parser (over the passthrough arguments, made from ``DemosConfig``'s fields); the handler
records the demonstrations (``indgen_vla.app.api.demos``) and prints what it kept."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_passthrough
from indgen_vla.app.config_fields import add_flags, from_args
from indgen_vla.app.regimes import quiet_datasets


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen demos`` parses its own arguments (``main``)."""
    add_passthrough(sp, "demos", "record demonstrations (T0, or levels of one axis) as a LeRobotDataset")


def build_parser() -> argparse.ArgumentParser:
    """``indgen demos``'s own parser: ``DemosConfig``'s fields as flags."""
    from indgen_vla.app.regimes.demos import FLAGS, DemosConfig  # lazy: start-up

    p = IndgenParser(
        prog="indgen demos",
        description="record noisy-oracle demonstrations (T0, or --axis A --levels 0:2) as a LeRobotDataset; "
        "rerunning the same command resumes an interrupted recording",
    )
    add_flags(p, DemosConfig, FLAGS)
    return p


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    from indgen_vla.app.api import demos  # lazy: start-up
    from indgen_vla.app.regimes.demos import DemosConfig  # lazy: start-up

    cfg = from_args(DemosConfig, build_parser().parse_args(args.rest), command="demos")
    quiet_datasets()
    from rich.console import Console  # lazy: start-up

    console = Console(stderr=True, soft_wrap=True)  # a line is one line in a log, whatever the width

    def progress(label, kept, attempt):
        console.print(f"  {label}: {kept}/{cfg.n} kept ({attempt} attempts)", end="\r")

    stats = demos(cfg, progress=progress, notice=console.print)
    out, scene = cfg.out, cfg.scene
    where = f" at levels {', '.join(map(str, stats['levels']))} of {stats['axis']}" if "axis" in stats else ""
    if stats.get("already_complete"):
        console.print(f"{out} is already complete: {stats['episodes']} episodes ({stats['frames']} frames) of "
                      f"{scene} {', '.join(stats['tasks'])}{where}; nothing to do")  # fmt: skip
        return 0
    console.print(f"\nrecorded {stats['episodes']} episodes ({stats['frames']} frames) of {scene} "
                  f"{', '.join(stats['tasks'])}{where} into {out}; oracle keep rate {100 * stats['success_rate']:.0f}% "
                  f"({stats['episodes']} of {stats['attempts']} attempts, pooled over tasks and levels)")  # fmt: skip
    if "axis" in stats:
        console.print("kept per task and level: " + ", ".join(
            f"{c['task']} {c['level']}: {c['kept']}/{c['attempts']}" for c in stats["cells"]))  # fmt: skip
    return 0
