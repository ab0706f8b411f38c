"""``indgen blockenv sample|train|eval|reproduce|ablate``: a passthrough subcommand whose sub-parsers are here
(its handlers: ``cli/blockenv_handlers.py``); the work is the BlockEnv study's (``indgen_vla.app.blockenv``).
Importing this module imports neither numpy nor torch."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import IndgenParser, add_passthrough  # one-line errors, as every command


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen blockenv`` parses its own arguments (``main``)."""
    add_passthrough(sp, "blockenv", "the toy BlockEnv benchmark: sample | train | eval | reproduce | ablate")


def main(args: argparse.Namespace) -> int:
    """Parse ``args.rest`` with the blockenv sub-parsers and run the one named."""
    return run(args.rest)


def build_parser() -> argparse.ArgumentParser:

    p = IndgenParser(prog="indgen blockenv", description="the paper's toy inductive benchmark")
    sp = p.add_subparsers(dest="cmd", required=True)
    s = sp.add_parser("sample", help="print initial grids of a level")
    s.add_argument(
        "--level", type=int, required=True, help="level k: two chains of k distractors around the goal"
    )
    s.add_argument("--n", type=int, default=1, help="how many initial grids (default 1)")
    s.add_argument("--seed", type=int, default=0, help="sampling seed (default 0)")
    s.add_argument("--grid-size", type=int, default=12, help="grid side G (default 12)")
    s.add_argument("--json", action="store_true", help="a JSON list of GxG integer lists")
    t = sp.add_parser("train", help="behaviour-clone one method on oracle demonstrations")
    t.add_argument(
        "--method", required=True, help="learner key, e.g. ind or rnn (docs/blockenv.md, The learners)"
    )
    t.add_argument("--levels", default="0:2", help="training levels (paper: 0:2)")
    t.add_argument(
        "--seed", type=int, default=0, help="training seed: init, demonstrations, batches (default 0)"
    )
    t.add_argument("--steps", type=int, default=2000, help="optimiser updates (default 2000)")
    t.add_argument(
        "--demos-per-level",
        type=int,
        default=300,
        help="oracle demonstrations per training level (default 300)",
    )
    t.add_argument("--grid-size", type=int, default=12, help="grid side G (default 12)")
    t.add_argument("--option", action="append", default=[], metavar="KEY=VALUE",
                   help="a variant option of the method, e.g. legal_head=local (see docs/blockenv.md)")  # fmt: skip
    t.add_argument("--out", required=True, help="checkpoint directory to write")
    e = sp.add_parser("eval", help="evaluate a checkpoint (or --method oracle) on levels")
    e.add_argument("--method", required=True, help="learner key of the checkpoint, or oracle")
    e.add_argument(
        "--checkpoint", default=None, help="directory written by 'indgen blockenv train' (not for oracle)"
    )
    e.add_argument("--levels", default="0:5", help="levels to evaluate, like 0:10 or 0,3,5 (default 0:5)")
    e.add_argument("--episodes", type=int, default=100, help="episodes per level (default 100)")
    e.add_argument(
        "--seed", type=int, default=1000, help="evaluation seed (default 1000, apart from training seeds)"
    )
    e.add_argument(
        "--grid-size",
        type=int,
        default=None,
        help="oracle grid side (default: fits the levels, >= 12); learned methods use their checkpoint's",
    )
    e.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    e.add_argument("--out", default=None, help="write results JSON here")
    r = sp.add_parser("reproduce", help="train and evaluate every method: Table 1")
    r.add_argument("--quick", action="store_true", help="a tiny smoke run of the same pipeline")
    r.add_argument(
        "--seeds", type=int, default=None, help="training seeds per method (default 3; 1 with --quick)"
    )
    r.add_argument(
        "--max-level", type=int, default=None, help="evaluate levels 0..K (default 10; 4 with --quick)"
    )
    r.add_argument(
        "--workers", type=int, default=None, help="processes training side by side (default: cores)"
    )
    r.add_argument("--resume", action="store_true", help="keep finished jobs in OUT/jobs and reuse them")
    r.add_argument("--out", required=True, help="folder for table1.json, table1.md, table1.png (and jobs/)")
    ab = sp.add_parser("ablate", help="the reduced-scale ablations of docs/results/blockenv_ablations.md")
    ab.add_argument(
        "--name", action="append", default=None, help="ablation to run (repeatable; default: all)"
    )
    ab.add_argument("--seeds", type=int, default=3, help="training seeds per ablation (default 3)")
    ab.add_argument("--results", default="docs/results/blockenv_ablations.json", help="JSON merged into")
    ab.add_argument(
        "--doc",
        default="docs/results/blockenv_ablations.md",
        help="markdown whose ablation section is rewritten",
    )
    return p


def run(argv: list[str]) -> int:
    """``indgen blockenv ARGV...``: parse with the blockenv sub-parsers, run the one named."""
    a = build_parser().parse_args(argv)
    from indgen_vla.app.cli.blockenv_handlers import HANDLERS  # lazy: start-up (numpy)

    return HANDLERS[a.cmd](a)
