"""``indgen compare``: its parser; the handler picks two runs (``two_runs.compare_runs``), two axes
(``two_runs.compare_run_axes``) or two groups (``two_groups.compare_run_groups``) and prints compare.md."""

from __future__ import annotations

import argparse

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan_lock import run_status
from indgen_vla.core.runs.imported import refuse_unpaired_imports
from indgen_vla.core.runs.records import RunDir


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The compare subcommand: two runs, two axes or two groups, the test, γ, α and the output folder."""
    p = sp.add_parser(
        "compare",
        help="per-level exact tests between two runs (paired when seeds match), or two axes (--axes), Holm",
    )
    p.add_argument("run_a", metavar="RUN_A", nargs="?", help="run directory A (or use --a for a group)")
    p.add_argument("run_b", metavar="RUN_B", nargs="?", help="run directory B (or use --b for a group)")
    p.add_argument(
        "--a", nargs="+", metavar="RUN", help="group A: one run per training seed (paired with --b by order)"
    )
    p.add_argument(
        "--b", nargs="+", metavar="RUN", help="group B: one run per training seed, same seed order as --a"
    )
    p.add_argument(
        "--label-a", default=None, help="name of group/run A in tables (default: its data regime or policy)"
    )
    p.add_argument("--label-b", default=None, help="name of group/run B in tables")
    p.add_argument(
        "--axes", default=None, metavar="A_AXIS:B_AXIS",
        help="compare axis A against axis B, paired episode by episode (same task, level, episode and seed): within "
        "one run (compare RUN --axes pick_y+distractor:pick_y) or A of RUN_A against B of RUN_B",
    )  # fmt: skip
    p.add_argument(
        "--margin", type=float, default=0.10,
        help="equivalence margin (default 0.10): groups: TOST on the OOD mean success; --axes: paired TOST per level",
    )  # fmt: skip
    p.add_argument(
        "--test",
        choices=["auto", "mcnemar", "boschloo", "barnard"],
        default="auto",
        help="auto: exact McNemar when the runs are paired episode by episode (same seeds and plan), else "
        "Boschloo (default auto)",
    )
    p.add_argument("--gamma", type=float, default=0.2, help="break threshold (paper: 0.2)")
    p.add_argument("--alpha", type=float, default=0.05, help="significance level after Holm (default 0.05)")
    p.add_argument(
        "--allow-protocol-mismatch",
        action="store_true",
        help="compare runs whose protocol fingerprints differ in a field that changes outcomes (horizon, assets, "
        "simulator versions, cameras, render backend, conventions of one policy family); the output lists them",
    )
    p.add_argument(
        "--out", default=None, help="output folder (default: RUN_A/compare; --axes A:B: RUN_A/compare_A_vs_B)"
    )


def main(args: argparse.Namespace) -> int:
    """Compare, then print compare.md and what was written."""
    from indgen_vla.core.comparison import two_groups, two_runs  # lazy: start-up (numpy)

    two_runs.check_levels(args.gamma, args.alpha)
    common = dict(gamma=args.gamma, alpha=args.alpha, out=args.out, label_a=args.label_a, label_b=args.label_b,
                  allow_protocol_mismatch=args.allow_protocol_mismatch)  # fmt: skip
    if args.axes:
        if args.a or args.b:
            raise ConfigError(
                "--axes compares axes of one run (RUN) or of two runs (RUN_A RUN_B), not groups (--a/--b)"
            )
        result = two_runs.compare_run_axes(args.run_a, args.run_b, axes=args.axes, test=args.test,
                                           margin=args.margin, **common)  # fmt: skip
        out = two_runs.axes_dir(args.run_a, args.axes, args.out)
        return _printed(two_runs.markdown(result), out, plots=True)
    if args.a or args.b:
        if args.run_a or args.run_b:
            raise ConfigError("give either RUN_A RUN_B or --a RUN... --b RUN..., not both")
        result = two_groups.compare_run_groups(args.a, args.b, margin=args.margin, **common)
        text = two_groups.render_markdown(result, result["label_a"], result["label_b"])
        return _printed(text, two_groups.groups_dir(args.a[0], args.out), plots=False)
    if not (args.run_a and args.run_b):
        raise ConfigError(
            "compare needs two run directories (RUN_A RUN_B) or two groups (--a RUN... --b RUN...)"
        )
    if args.test in (
        "auto",
        "mcnemar",
    ):  # imported runs (indgen import) pair by seed or are refused, as in gate
        refuse_unpaired_imports(args.run_a, args.run_b)
    result = two_runs.compare_runs(args.run_a, args.run_b, test=args.test, **common)

    for path in (args.run_a, args.run_b):  # "locked, hash H, followed" or its deviations (docs/budget.md)
        run = RunDir(path)
        if line := run_status(run.manifest, len(run.episodes()), gamma=args.gamma, alpha=args.alpha):
            print(f"{run.path}: {line}")
    return _printed(two_runs.markdown(result), two_runs.compare_dir(args.run_a, args.out), plots=True)


def _printed(text: str, out, plots: bool) -> int:
    print(text)
    print(f"wrote {out / 'compare.json'}, {out / 'compare.md'}, {out / 'report.html'}"
          + (f", {out / 'plots'}/" if plots else ""))  # fmt: skip
    return 0
