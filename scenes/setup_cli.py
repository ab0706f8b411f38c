"""``indgen setup FAMILY``: one entry point for the scene families that need something installed first."""

from __future__ import annotations


def setup_main(args) -> int:
    """robocasa: its pinned venv (``scenes.robocasa.setup``); libero: its complete asset tree (``scenes.libero.setup``)."""
    if args.family == "libero":
        from scenes.libero.setup import setup_libero_main

        return setup_libero_main(args)
    from scenes.robocasa.setup import setup_main as robocasa_main

    return robocasa_main(args)
