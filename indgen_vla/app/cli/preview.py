"""``indgen preview``: its parser; the handler renders the contact sheet (``indgen_vla.app.preview.write_preview``)."""

from __future__ import annotations

import argparse

from indgen_vla.app.cli.options import add_level_options, add_scene_options
from indgen_vla.core.protocol.progression import expand_axes


def add_parser(sp: argparse._SubParsersAction) -> None:
    """The preview subcommand: scene, task, axes, levels, camera, image size, episode, seed and the image file."""
    p = sp.add_parser(
        "preview",
        help="render each level's first observation into one labelled sheet (check an axis before a run)",
    )
    p.add_argument("--scene", required=True, help="scene (see 'indgen scenes')")
    p.add_argument("--task", default=None, help="task of the scene (default: the scene's first task)")
    p.add_argument(
        "--axis", required=True, help="axis, composition or comma list (one row each), e.g. pick_y"
    )
    add_level_options(p)
    p.add_argument(
        "--camera", default=None, help="camera to show (default: the scene's first, e.g. agentview)"
    )
    p.add_argument("--size", type=int, default=256, help="image side in pixels (default 256)")
    p.add_argument("--episode", type=int, default=0, help="episode whose initial state to show (default 0)")
    p.add_argument("--seed", type=int, default=0, help="run seed, as evaluate's --seed (default 0)")
    add_scene_options(p)
    p.add_argument("--out", required=True, help="image file: .png, .pdf, .svg or .jpg")


def main(args: argparse.Namespace) -> int:
    """``indgen preview --scene S [--task T] --axis A[,B] [--levels] [--camera] [--size] [--episode] --out F``."""
    from pathlib import Path

    from indgen_vla.app.preview import PreviewRequest, write_preview  # lazy: start-up (numpy)
    from scenes.family import get_scene  # lazy: start-up (registering the families: numpy)

    # the family configured once (a family without these options, a bad value: one line), handed on
    scene = get_scene(args.scene, {"split": args.split, "obj_registries": args.obj_registries})
    req = PreviewRequest(
        scene=scene, axes=expand_axes([a.strip() for a in args.axis.split(",") if a.strip()]), out=Path(args.out),
        task=args.task, levels=args.levels, step=args.step, preset=args.axes_preset, camera=args.camera,
        size=args.size, episode=args.episode, seed=args.seed,
    )  # fmt: skip
    path, tiles = write_preview(req)
    print(f"{path}: {len(tiles)} level(s) of {req.scene.name}, episode {req.episode}")
    return 0
