"""``indgen real plan|record|status``: a passthrough subcommand; its sub-parsers and their handlers are the real-robot
protocol's own CLI (``indgen_vla.app.real.cli``), handed the policy registry's ``--check-policy`` trigger here
(``indgen_vla.app.real_policy``), since that package never imports a policy."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_passthrough


def add_parser(sp: argparse._SubParsersAction) -> None:
    """``indgen real`` parses its own arguments (``main``)."""
    add_passthrough(sp, "real", "real-robot protocol with an operator: plan | record | status")


def main(args: argparse.Namespace) -> int:
    """Parse ``args.rest`` with the real-robot sub-parsers and run the one named."""
    from indgen_vla.app.real.cli import run
    from indgen_vla.app.real_policy import PolicyCheck

    return run(args.rest, policy_check=PolicyCheck)
