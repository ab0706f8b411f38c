"""``indgen mimicgen``: its parser (over the passthrough arguments); the handler augments the demonstrations
(``indgen_vla.app.regimes.mimicgen.generate``) under a progress bar."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen mimicgen`` parses its own arguments (``main``)."""
    add_passthrough(
        sp, "mimicgen", "MimicGen-style augmentation of demonstrations (each at its source level)"
    )


def main(args: argparse.Namespace) -> int:
    """The handler: its own parser over ``args.rest``, then the library call."""
    from indgen_vla.app.regimes import quiet_datasets
    from indgen_vla.app.regimes.mimicgen import SELECTIONS, STATS_FILE, MimicGenConfig, generate

    p = IndgenParser(
        prog="indgen mimicgen",
        description="MimicGen-style augmentation of `indgen demos` demonstrations, level by level (LeRobotDataset)",
    )
    p.add_argument("--source", required=True, help="dataset written by `indgen demos`")
    p.add_argument(
        "--n",
        type=int,
        required=True,
        help="generation attempts per task and level (successes with --guarantee)",
    )
    p.add_argument("--out", required=True,
                   help="dataset root: new, or an unfinished one to resume with the same arguments")  # fmt: skip
    p.add_argument("--seed", type=int, default=0, help="seed of the new initial states and the source choice")
    p.add_argument("--guarantee", action="store_true", help="attempt until --n successes per task and level")
    p.add_argument(
        "--max-attempts", type=int, default=None, help="attempt cap per task and level with --guarantee (5 n)"
    )
    p.add_argument("--selection", choices=SELECTIONS, default="nearest", help="per-subtask source choice")
    p.add_argument("--action-noise", type=float, default=0.05, help="std of motion noise on executed actions")
    p.add_argument(
        "--repo-id", default="local/indgen_mimicgen", help="LeRobotDataset repo id stored in the dataset"
    )
    a = p.parse_args(args.rest)
    cfg = MimicGenConfig(source=a.source, out=a.out, n=a.n, seed=a.seed, guarantee=a.guarantee,
                         max_attempts=a.max_attempts, selection=a.selection, action_noise=a.action_noise,
                         repo_id=a.repo_id)  # fmt: skip
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

        stats = generate(cfg, progress, say=console.print)
    if done:
        return 0
    console.print(f"generated {stats['successes']}/{stats['attempts']} attempts succeeded "
                  f"({100 * stats['rate']:.1f} %) → {cfg.out}")  # fmt: skip
    return 0 if stats["successes"] else 1
