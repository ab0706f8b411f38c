"""``indgen mimicgen``: its parser (over the passthrough arguments, made from ``MimicGenConfig``'s fields); the
handler augments the demonstrations (``indgen_vla.app.api.mimicgen``) under a progress bar."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_passthrough
from indgen_vla.app.config_fields import add_flags, from_args
from indgen_vla.app.regimes import quiet_datasets


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen mimicgen`` parses its own arguments (``main``)."""
    add_passthrough(
        sp, "mimicgen", "MimicGen-style augmentation of demonstrations (each at its source level)"
    )


def build_parser() -> argparse.ArgumentParser:
    """``indgen mimicgen``'s own parser: ``MimicGenConfig``'s fields as flags."""
    from indgen_vla.app.regimes.mimicgen import FLAGS, MimicGenConfig  # lazy: start-up

    p = IndgenParser(
        prog="indgen mimicgen",
        description="MimicGen-style augmentation of `indgen demos` demonstrations, level by level (LeRobotDataset)",
    )
    add_flags(p, MimicGenConfig, FLAGS)
    return p


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    from indgen_vla.app.api import mimicgen  # lazy: start-up
    from indgen_vla.app.regimes.mimicgen import STATS_FILE, MimicGenConfig  # lazy: start-up

    cfg = from_args(MimicGenConfig, build_parser().parse_args(args.rest), command="mimicgen")
    quiet_datasets()
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(stderr=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    done = (cfg.out / STATS_FILE).is_file()
    with Progress(*columns, console=console, transient=True) as bar:
        bars: dict[str, object] = {}

        def progress(task, ok, attempt, total):
            if task not in bars:
                bars[task] = bar.add_task(task, total=total)
            bar.update(bars[task], completed=attempt, description=f"{task}: {ok} ok")

        stats = mimicgen(cfg, progress=progress, say=console.print)
    if done:
        return 0
    console.print(f"generated {stats['successes']}/{stats['attempts']} attempts succeeded "
                  f"({100 * stats['rate']:.1f} %) → {cfg.out}")  # fmt: skip
    return 0 if stats["successes"] else 1
