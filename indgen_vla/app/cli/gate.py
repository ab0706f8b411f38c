"""``indgen gate BASELINE CANDIDATE``: the regression gate's argparse parser and handler (``indgen_vla.core.comparison.gate``)."""

from __future__ import annotations

import argparse
import json
import math

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.imported import refuse_unpaired_imports

DEFAULT_MARGIN = (
    0.10  # indgen_vla.core.comparison.gate.DEFAULT_MARGIN (not imported here: `indgen --help` stays light)
)


def add_parser(sp: argparse._SubParsersAction) -> None:
    """Register ``indgen gate`` (a help line per option)."""
    p = sp.add_parser(
        "gate",
        help="regression gate for CI: is CANDIDATE no worse than BASELINE within --margin at every level "
        "(exit 0), worse somewhere (1), or undecided (5, a failure); --plan BASELINE sizes the smoke",
        description="Compare two runs of one protocol level by level. Paired runs (same seeds and plan): "
        "non-inferiority by the exact unconditional test on Tango's score statistic, worse by exact McNemar; unpaired: "
        "an exact test on the MOVER bound and Boschloo; Holm over every level and axis tested for worse. Exit 0: the candidate is "
        "shown non-inferior within the margin at every level; 1: significantly worse at a level; 5: neither, a "
        "failure (the output says how many more episodes per level would decide it with 80% chance); 2: bad input. "
        "With --plan, only BASELINE: the episodes a level with which equal policies pass with 80% chance "
        "(docs/statistics.md).",
    )
    p.add_argument(
        "baseline", metavar="BASELINE", help="run directory of the reference (e.g. the stored main run)"
    )
    p.add_argument("candidate", metavar="CANDIDATE", nargs="?", help="run directory of the run under test")
    p.add_argument(
        "--plan",
        action="store_true",
        help="size the smoke from BASELINE's per-level rates instead of gating (no CANDIDATE)",
    )
    p.add_argument(
        "--power",
        type=float,
        default=0.8,
        help="with --plan: the chance that two equal policies pass (default 0.8)",
    )
    p.add_argument(
        "--pairing",
        choices=["independent", "most-discordant"],
        default="independent",
        help="with --plan: how a candidate's outcomes pair with the baseline's (default independent)",
    )
    p.add_argument(
        "--margin", type=float, default=DEFAULT_MARGIN, metavar="M",
        help=f"largest drop in success per level that still passes, as a rate (default {DEFAULT_MARGIN}: 10 points)",
    )  # fmt: skip
    p.add_argument("--alpha", type=float, default=0.05, help="error rate of each verdict (default 0.05)")
    p.add_argument(
        "--test",
        choices=["auto", "mcnemar", "boschloo", "barnard"],
        default="auto",
        help="auto: exact McNemar when the runs are paired (same seeds and plan), else Boschloo (default auto)",
    )
    p.add_argument(
        "--gamma", type=float, default=0.2, help="break threshold of the runs' summaries (default 0.2)"
    )
    p.add_argument(
        "--allow-protocol-mismatch",
        action="store_true",
        help="gate runs whose protocol fingerprints differ in a field that changes outcomes (the output lists it)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the result as JSON instead of one line per verdict"
    )


def main(args: argparse.Namespace) -> int:
    """CLI handler: print the verdicts (or JSON) and return the gate's exit code."""
    from indgen_vla.core.comparison.gate import GateConfig, gate  # lazy: start-up (numpy)

    if args.plan:
        if args.candidate is not None:
            raise ConfigError("--plan takes one run directory, the baseline; drop CANDIDATE")
        GateConfig(
            args.baseline, args.baseline, margin=args.margin, alpha=args.alpha, gamma=args.gamma
        )  # validates
        return _plan(args)
    if args.candidate is None:
        raise ConfigError(
            "indgen gate needs BASELINE and CANDIDATE run directories (or --plan BASELINE to size them)"
        )
    if args.test in ("auto", "mcnemar"):  # imported runs (indgen import) pair by seed or are refused
        refuse_unpaired_imports(args.baseline, args.candidate)
    cfg = GateConfig(
        baseline=args.baseline, candidate=args.candidate, margin=args.margin, alpha=args.alpha, gamma=args.gamma,
        test=args.test, allow_protocol_mismatch=args.allow_protocol_mismatch,
    )  # fmt: skip
    res = gate(cfg)
    if args.json:
        print(json.dumps(_plain({k: v for k, v in res.items() if k != "lines"}), indent=2))
    else:
        print("\n".join(res["lines"]))
    return int(res["exit_code"])


def _plan(args: argparse.Namespace) -> int:
    """``gate --plan``: print the smoke's episodes a level (JSON with --json)."""
    # lazy: start-up (numpy)
    from indgen_vla.core.comparison.gate_plan import baseline_rates, plan_episodes, plan_lines

    levels = baseline_rates(args.baseline, args.gamma)
    plan = plan_episodes([p for _, _, p in levels], args.margin, args.alpha, args.power, args.pairing)
    print(json.dumps(plan, indent=2) if args.json else "\n".join(plan_lines(args.baseline, plan, levels)))
    return 0


def _plain(x):
    """NaN (a level without a test) as JSON null, so strict parsers read the output."""
    if isinstance(x, float) and math.isnan(x):
        return None
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_plain(v) for v in x]
    return x
