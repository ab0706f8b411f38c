"""``indgen reference RUN...``: its parser; the handler runs the black-box regime
(``core.reporting.black_box.write_reference``) and prints its report."""

from __future__ import annotations

import argparse


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The reference subcommand: the reference policies' runs, the axis, task and level of T0's candidates."""
    p = sp.add_parser(
        "reference",
        help="black-box regime: pick T0 from reference policies' runs, test the level ordering on held-out episodes",
        description="Black-box reference level (paper appendix B): each RUN_DIR is one reference policy evaluated on "
        "the (task, level) configurations of one axis. T0 = the configuration with the highest mean success over "
        "the policies, chosen on even-numbered episodes; the ordering of the levels around T0 is then tested "
        "(isotonic LRT and Cochran-Armitage) on the held-out odd-numbered episodes.",
    )
    p.add_argument("runs", nargs="+", metavar="RUN_DIR", help="one run directory per reference policy")
    p.add_argument(
        "--axis", default=None, help="axis whose levels are the configurations (default: the only shared one)"
    )
    p.add_argument(
        "--task", default=None, help="restrict the configurations to one task (default: every shared task)"
    )
    p.add_argument(
        "--level", type=int, default=None,
        help="choose T0 only among the configurations at this level, e.g. 0: the canonical configurations "
        "themselves (RoboCasa: --task Task@5x5 runs its canonical kitchens); default: every (task, level)",
    )  # fmt: skip
    p.add_argument("--out", default=None, help="folder for reference.json/.md (default: FIRST_RUN/reference)")


def main(args: argparse.Namespace) -> int:
    """Choose T0, test the ordering, print reference.md and where it went."""
    # lazy: start-up (numpy)
    from indgen_vla.core.reporting.black_box import (
        reference_dir,
        render_markdown,
        write_reference,
    )

    res = write_reference(args.runs, axis=args.axis, task=args.task, level=args.level, out=args.out)
    out = reference_dir(args.runs[0], args.out)
    print(render_markdown(res))
    print(f"wrote {out / 'reference.json'}, {out / 'reference.md'}")
    return 0
