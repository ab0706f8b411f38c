"""``indgen setup robocasa``: create RoboCasa365's pinned venv and say where it is (``scenes.robocasa.environment``)."""

from __future__ import annotations

from pathlib import Path


def setup_main(args) -> int:
    from scenes.robocasa.environment import PYTHON_ENV, setup_venv

    py = setup_venv(Path(args.venv) if args.venv else None, force=args.force)
    print(f"RoboCasa interpreter: {py} (used by default; or export {PYTHON_ENV}={py})")
    return 0
