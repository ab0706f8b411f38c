"""``indgen setup robocasa``: create RoboCasa365's pinned venv (``scenes.robocasa.environment.setup_venv``) and say
where it is."""

from __future__ import annotations

import argparse


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The setup subcommand: the scene family, where its venv goes, whether to recreate it."""
    p = sp.add_parser(
        "setup", help="create a scene family's own simulator environment (robocasa: a pinned venv)"
    )
    p.add_argument("family", choices=["robocasa"], help="the scene family whose environment to create")
    p.add_argument("--venv", default=None, help="where to create it (default: $INDGEN_ROBOCASA_VENV or "
                   "~/.cache/indgen/robocasa-venv)")  # fmt: skip
    p.add_argument("--force", action="store_true", help="recreate it even when it is complete")


def main(args: argparse.Namespace) -> int:
    """Create (or find complete) the family's environment and print its interpreter."""
    from pathlib import Path

    from scenes.robocasa.environment import PYTHON_ENV, setup_venv

    py = setup_venv(Path(args.venv) if args.venv else None, force=args.force)
    print(f"RoboCasa interpreter: {py} (used by default; or export {PYTHON_ENV}={py})")
    return 0
