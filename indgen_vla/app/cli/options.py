"""What every ``indgen`` parser shares: one-line errors with a suggestion, negative level ranges as values, the
level options (evaluate, certify, preview, demos) and the passthrough subcommands that parse their own arguments."""

from __future__ import annotations

import argparse
import copy
import re


class IndgenParser(argparse.ArgumentParser):
    """argparse that suggests the closest subcommand or choice on a typo, in one line, and reads
    level ranges such as ``--levels -3:3`` or ``--levels -2,0,2`` as values, not as options."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\d+(\.\d+)?$|^-\d+:-?\d+$|^-\d+(,-?\d+)+$")

    def error(self, message: str) -> None:  # type: ignore[override]
        import difflib

        m = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
        if m:
            choices = re.findall(r"'([^']*)'", m.group(2)) or [c.strip() for c in m.group(2).split(",")]
            close = difflib.get_close_matches(m.group(1), choices, n=1, cutoff=0.5)
            if close:
                message += f"; did you mean {close[0]!r}?"
        self.exit(2, f"{self.prog}: error: {message}\n")


def add_level_options(p: argparse.ArgumentParser, levels_default: str = "default: the axis range") -> None:
    """--levels, --step and --axes-preset: which levels run and how far apart (evaluate, certify, preview and demos
    alike; ``levels_default`` says what an omitted --levels means there)."""
    p.add_argument(
        "--levels",
        default=None,
        help=f"inclusive range like -3:3 or list like 0,1,2 ({levels_default})",
    )
    p.add_argument("--step", type=float, default=None, help="override the axis's atomic step size")
    p.add_argument(
        "--axes-preset",
        default=None,
        metavar="NAME|PATH",
        help="shipped axes preset (paper, quick) or YAML path: steps and level ranges, compositions' components too",
    )


def add_passthrough(sp: argparse._SubParsersAction, name: str, help_: str) -> None:
    """A subcommand whose handler parses the rest of the command line itself (``args.rest``)."""
    sp.add_parser(name, help=help_, add_help=False)


def add_evaluate_protocol(sp: argparse._SubParsersAction, p: argparse.ArgumentParser, skip: set[str]) -> None:
    """Give ``p`` evaluate's own option definitions (``sp`` holds evaluate's parser already), all but ``skip``'s
    dests: ``budget`` and ``series`` take a protocol exactly as ``evaluate`` does."""
    for action in sp.choices["evaluate"]._actions:
        if action.dest not in skip and action.dest != "help":
            p._add_action(copy.copy(action))
