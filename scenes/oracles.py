"""The machinery every scene family's oracle shares: looking a family's oracle up (``Scene.oracle``), what a
certificate records of it (its version and a hash of its code), which tasks it scripts, what it declares, and the
gripper-down rotation the scripts steer towards. Each family's own oracle lives in its folder (``tabletop/oracle.py``,
``libero/oracle.py``, ``robocasa/oracle.py``)."""

from __future__ import annotations

import functools
import hashlib
import importlib
import inspect
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from indgen_vla.core.protocol.interface import PolicySpec
from scenes.family import TABLETOP_ORACLE

if TYPE_CHECKING:
    from scenes.family import Scene

# Gripper pointing straight down, fingers closing along world y (the Panda's home orientation, untilted).
R_DOWN = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


def _axis_angle(r: np.ndarray) -> np.ndarray:
    """Axis-angle vector of a rotation matrix."""
    cos = np.clip((np.trace(r) - 1) / 2, -1.0, 1.0)
    angle = np.arccos(cos)
    if angle < 1e-6:
        return np.zeros(3)
    v = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    n = np.linalg.norm(v)
    if n < 1e-9:  # angle ~ pi: take the axis from the symmetric part
        w, vecs = np.linalg.eigh((r + r.T) / 2)
        return vecs[:, np.argmax(w)] * angle
    return v / n * angle


def _load(ref: str) -> type:
    """The class a ``"module:Class"`` reference names (imported here: the simulator-free oracle modules)."""
    module, _, attr = ref.partition(":")
    return getattr(importlib.import_module(module), attr)


def oracle_for(scene: Scene | None = None):
    """``standin:oracle``: the privileged oracle of ``scene``'s family (``Scene.oracle``; the tabletop one when no
    scene is named)."""
    return _load(TABLETOP_ORACLE if scene is None else scene.oracle)()


def oracle_class(scene: Scene) -> type:
    """The class of ``scene``'s oracle (``Scene.oracle``), not instantiated."""
    return _load(scene.oracle)


def oracle_identity(scene: Scene) -> dict:
    """What a certificate records of the oracle that made it: its class, its hand-bumped ``version`` and
    a hash of its source (``oracle_code_hash``)."""
    cls = oracle_class(scene)
    return {"name": f"{cls.__module__}:{cls.__qualname__}", "version": int(cls.version),
            "code_hash": oracle_code_hash(cls)}  # fmt: skip


@functools.cache
def oracle_code_hash(cls: type) -> str:
    """SHA-256 (first 16 hex) of the source of every ``scenes`` module in the oracle class's hierarchy and the
    ``*oracle*.py``/``grasp*.py`` beside its own module: a behaviour change without a version bump shows here."""
    files: set[Path] = set()
    for k in cls.__mro__:
        mod = inspect.getmodule(k)
        if mod is not None and mod.__name__.startswith("scenes") and getattr(mod, "__file__", None):
            files.add(Path(mod.__file__))
    own = Path(inspect.getfile(cls)).parent
    files |= {*own.glob("*oracle*.py"), *own.glob("grasp*.py")}
    h = hashlib.sha256()
    # keyed by folder/name: tabletop/oracle.py and libero/oracle.py
    for name, f in sorted((f"{f.parent.name}/{f.name}", f) for f in files):
        h.update(name.encode() + b"\0" + f.read_bytes())
    return h.hexdigest()[:16]


def oracle_scripts(scene: Scene, task: str) -> bool:
    """Whether ``scene``'s oracle has a script for ``task`` (a family's oracle class may list its ``tasks``; one
    that lists none scripts every task). A task without one stays uncertified: no certificate, evaluate warns."""
    tasks = getattr(oracle_class(scene), "tasks", None)
    return tasks is None or task in tasks


def oracle_spec(action_dim: int) -> PolicySpec:
    """What every scene family's scripted oracle declares: privileged, camera-free, one instance per env."""
    return PolicySpec(
        family="standin",
        name="standin:oracle",
        privileged=True,
        cameras=(),
        batched=False,
        action_dim=action_dim,
    )
