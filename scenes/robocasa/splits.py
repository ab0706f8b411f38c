"""Which kitchens and object instances T0 is drawn from: RoboCasa365's evaluation split and RoboCasa's object
registries, chosen once per command: ``--split`` / ``--obj-registries`` (the API's ``split`` / ``obj_registries``),
else ``INDGEN_ROBOCASA_SPLIT`` / ``INDGEN_ROBOCASA_OBJ_REGISTRIES``, else the defaults; the flag wins.

RoboCasa's ``create_env`` (``robocasa/utils/env_utils.py``, be22d659 = the pinned rlinf-robocasa365 1.0.1) turns a
split into ``Kitchen`` arguments: ``pretrain`` the 50 x 50 kitchens of layouts and styles 11..60 and each object
category's pretraining instances, ``target`` the ten kitchens (layout i, style i), i = 1..10, and the other instances,
``all`` every layout and style 1..60 and every instance. ``kitchen_objects.sample_kitchen_object_helper``
(``robocasa/models/objects/kitchen_object_utils.py``) splits a category's models at ``max(n - 5, ceil(n / 2))``:
pretrain the first ones, target the rest, so a category with one model has no target instance. RoboCasa365's
benchmark evaluates the multi-task and lifelong-learning policies in the pretrain split and the foundation-model
(target post-trained) ones in the target split (its docs/benchmarking/*.md); its openpi client defaults to
pretrain, and every appendix-B task is a pretraining task (``PRETRAINING_TASKS["pretrain300"]``), 6 of the 17 also
target tasks. ``Kitchen``'s own registries are objaverse and lightwheel; lerobot evaluates ``split="all"`` with
lightwheel alone.

Imports only the standard library at module level: the worker loads it by path (``backend.py``), our venv imports it
as ``scenes.robocasa.splits``.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

SPLIT_ENV = "INDGEN_ROBOCASA_SPLIT"
REGISTRIES_ENV = "INDGEN_ROBOCASA_OBJ_REGISTRIES"
# how a bad value is named: the commands' flags (the API's split, obj_registries), which win, or the environment's
FLAGS, ENVIRON = ("--split ", "--obj-registries "), (f"${SPLIT_ENV}=", f"${REGISTRIES_ENV}=")
# RoboCasa365's multi-task and lifelong-learning evaluation split, its openpi client's default
DEFAULT_SPLIT = "pretrain"
DEFAULT_REGISTRIES = ("objaverse", "lightwheel")  # RoboCasa's Kitchen default (obj_registries)
# the split the worker built with before the option (RoboCasa's Kitchen defaults): its runs keep their fingerprint
LEGACY = ("all", DEFAULT_REGISTRIES)
# each registry's folder under the asset tree's objects/ (kitchen_object_utils.ObjCat: reg_type "aigen_objs")
REGISTRY_FOLDERS = {"objaverse": "objaverse", "aigen": "aigen_objs", "lightwheel": "lightwheel"}
# what create_env passes robosuite.make for each split (tests/scenes/robocasa/test_splits.py reads it back)
SPLITS: dict[str, dict] = {
    "pretrain": {"obj_instance_split": "pretrain", "layout_ids": -2, "style_ids": -2},
    "target": {"obj_instance_split": "target", "layout_and_style_ids": [(i, i) for i in range(1, 11)]},
    "all": {"obj_instance_split": None, "layout_ids": -3, "style_ids": -3},
}
SPLIT_WORDS = {
    "pretrain": "layouts and styles 11..60 (2,500 kitchens), each object category's pretraining instances",
    "target": "the ten kitchens (layout i, style i), i = 1..10, each category's target instances",
    "all": "every layout and style 1..60, every object instance",
}


def kitchen_kwargs(split: str, registries, layout_ids=None, style_ids=None) -> dict:
    """``robosuite.make``'s kitchen arguments: the split's kitchens and object instances, as ``create_env`` sets
    them, unless the run pins one kitchen (``Task@L-S``: its ``layout_ids`` / ``style_ids``), and the registries."""
    kwargs = dict(SPLITS[split])
    if layout_ids is not None:
        kwargs.pop("layout_and_style_ids", None)
        kwargs.update(layout_ids=layout_ids, style_ids=style_ids)
    return {**kwargs, "obj_registries": tuple(registries)}


def in_split(split: str, layout: int, style: int) -> bool:
    """Is the kitchen (``layout``, ``style``) one of the split's?"""
    if split == "target":
        return layout == style and 1 <= layout <= 10
    low = 11 if split == "pretrain" else 1
    return low <= layout <= 60 and low <= style <= 60


def check(split: str | None = None, registries: str | None = None, where: tuple[str, str] = FLAGS) -> None:
    """One line listing the valid values (``ConfigError``) when ``split`` or ``registries`` (a comma list) is not
    RoboCasa's; None is "not given". ``where`` names them in the line (the flags, or the environment variables)."""
    # lazy: optional indgen_vla (the RoboCasa worker loads this file by path in its own venv, without our packages)
    from indgen_vla.core.errors import ConfigError

    if split is not None and split not in SPLITS:
        valid = "; ".join(
            f"{k}{' (default)' if k == DEFAULT_SPLIT else ''}: {v}" for k, v in SPLIT_WORDS.items()
        )
        raise ConfigError(f"{where[0]}{split!r} is not one of RoboCasa365's splits; use one of {valid}")
    if registries is None:
        return
    if not isinstance(registries, str):
        name = where[1].strip(" =")
        raise ConfigError(f"{name} must be a comma list such as 'objaverse,lightwheel', got {registries!r}")
    names = [r.strip() for r in registries.split(",")]
    bad = [r for r in names if r not in REGISTRY_FOLDERS]
    if bad or len(set(names)) != len(names):
        what = f"names {bad[0]!r}" if bad else "repeats a registry"
        raise ConfigError(
            f"{where[1]}{registries!r} {what}; use a comma list of RoboCasa's object registries "
            f"{', '.join(REGISTRY_FOLDERS)} (default {','.join(DEFAULT_REGISTRIES)}; lerobot uses lightwheel)"
        )


def choice(
    environ=None, split: str | None = None, registries: str | None = None
) -> tuple[str, tuple[str, ...]]:
    """The split and registries: ``split`` / ``registries`` (the flags' values, a comma list) where given, else
    ``$INDGEN_ROBOCASA_SPLIT`` and ``$INDGEN_ROBOCASA_OBJ_REGISTRIES``, else the defaults; a value RoboCasa has
    not is one line listing the valid ones (``ConfigError``)."""
    environ = os.environ if environ is None else environ
    check(split, registries)
    env_split = environ.get(SPLIT_ENV, "").strip() or None
    env_regs = environ.get(REGISTRIES_ENV, "").strip() or None
    if split is None or registries is None:  # only what the flags leave to the environment is read from it
        check(None if split else env_split, None if registries else env_regs, ENVIRON)
    split = split or env_split or DEFAULT_SPLIT
    raw = registries or env_regs
    return split, tuple(r.strip() for r in raw.split(",")) if raw else DEFAULT_REGISTRIES


def tree_problem(assets: Path, split: str, registries: tuple[str, ...], placeholders: bool) -> str | None:
    """One line when the asset tree cannot serve the choice: a registry with no object model (RoboCasa would draw a
    category from it and fail on NaN probabilities), or the target split on the placeholder tree, whose categories
    hold one model each but for the few the wheel's sources name (no target instance for almost every draw);
    None when it can."""
    for reg in registries:
        folder = assets / "objects" / REGISTRY_FOLDERS[reg]
        if (
            next(folder.glob("*/*/model.xml"), None) is None
            and next(folder.glob("*/*/*/model.xml"), None) is None
        ):
            return (
                f"RoboCasa's object registry {reg!r} has no model under {folder}: pass --obj-registries (or set "
                f"{REGISTRIES_ENV}) with the registries the tree holds (e.g. lightwheel, as lerobot does) or download it with RoboCasa's "
                "download_kitchen_assets"
            )
    if split == "target" and placeholders:
        return (
            f"{assets} is the placeholder tree, one model per object category, and RoboCasa's target split keeps "
            "only a category's models after the first max(n - 5, ceil(n / 2)), none of one: pass --split pretrain "
            f"or all (or set {SPLIT_ENV}), or use RoboCasa's real assets"
        )
    return None


@contextlib.contextmanager
def one_line(split: str, registries):
    """RoboCasa's failure when a category it drew has no model in the split and registries (``rng.choice`` on 0 / 0
    probabilities: "Probabilities contain NaN") as one line naming the choice and the fix."""
    try:
        yield
    except ValueError as e:
        if "Probabilities contain NaN" not in str(e):
            raise
        raise ValueError(
            f"RoboCasa drew an object category with no model under split {split} in registries "
            f"{', '.join(registries)} ({e}): the asset tree lacks that split's instances; pass --split and "
            f"--obj-registries (or {SPLIT_ENV}, {REGISTRIES_ENV}) naming what it holds"
        ) from None


def describe(split: str, registries: tuple[str, ...]) -> str:
    """The choice in words, as the protocol facts' ``initial_states`` and ``indgen scenes`` show it."""
    return f"RoboCasa365 split {split} ({SPLIT_WORDS[split]}), object registries {', '.join(registries)}"
