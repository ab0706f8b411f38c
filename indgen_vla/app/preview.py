"""``indgen preview``: what a policy sees at t = 0 on each level of an axis, in one labelled contact sheet.

The paper's Fig. 5 (and the appendix's axis figure), and a check to run before spending GPU hours: every level is
built the way ``evaluate`` builds it (``scenes.planning.resolve_scene_plan``: the same names, levels and condition-2
checks and one-line errors, then the plan's builder), reset with episode ``--episode``'s seed of a run with
``--seed`` (after the scene's settling steps) and its camera image drawn upright, as videos show it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.plan import ScenePlan
from indgen_vla.core.protocol.seeding import evaluation_seed
from indgen_vla.core.reporting.figures import contact_sheet, unit_name
from indgen_vla.core.runs.records import atomic_savefig
from scenes.axes import get_path, shifts, spec_at_level
from scenes.base_env import check_env_args
from scenes.external import close_idle_workers
from scenes.family import Scene
from scenes.planning import resolve_scene_plan

FORMATS = (".png", ".pdf", ".svg", ".jpg")  # what the sheet is written as, by --out's suffix


@dataclass(frozen=True)
class PreviewRequest:
    """What ``indgen preview`` renders; checked on construction, never corrected silently."""

    scene: Scene  # the family as the command configured it (RoboCasa365's --split, --obj-registries)
    axes: tuple[str, ...]
    out: Path
    task: str | None = None
    levels: str | None = None
    step: float | None = None
    preset: str | None = None
    camera: str | None = None  # None: the scene family's first camera (agentview on the tabletop scenes)
    size: int = 256
    episode: int = 0
    seed: int = 0

    def __post_init__(self) -> None:
        if not self.axes:
            raise ConfigError("--axis is empty; name an axis, e.g. --axis pick_y (see 'indgen axes')")
        if not 8 <= self.size <= 2048:
            raise ConfigError(f"--size {self.size} must lie in 8..2048 pixels")
        if self.episode < 0:
            raise ConfigError(f"--episode {self.episode} must be >= 0")
        if self.task == "all":
            raise ConfigError("--task all: a preview shows one task; name one (see 'indgen scenes')")
        if self.out.suffix.lower() not in FORMATS:
            raise ConfigError(
                f"--out {self.out}: the sheet is written as {', '.join(FORMATS[:-1])} or {FORMATS[-1]}; end the "
                f"name with one of them, e.g. --out {self.out.with_suffix('.png')}"
            )


@dataclass(frozen=True)
class Tile:
    """One level's initial image and what it shows."""

    axis: str
    level: int
    caption: str
    image: np.ndarray


def level_caption(plan: ScenePlan, task: str, axis: str, level: int) -> str:
    """The level over its axis parameter as ``evaluate`` records it, e.g. "k = +2" over "pick_y = -0.080 m" (one
    line per component of a composition, and for a held axis's held one)."""
    successor = plan.builder.successors[axis]
    head = f"k = {level:+d}" if plan.axes[axis].signed and level else f"k = {level}"
    parts = shifts(successor)
    if len(parts) == 1:
        return f"{head}\n{axis} = {_value(plan.cell(task, axis, level).param, plan.axes[axis].unit)}"
    spec = spec_at_level(plan.builder.family.base(task), successor, level)
    return "\n".join(
        [head, *(f"{p.axis.name} = {_value(get_path(spec, p.axis.field), p.axis.unit)}" for p in parts)]
    )


def _value(x: float, unit: str) -> str:
    """An axis parameter in its unit: "-0.080 m", "×1.133" (a scale factor), "2 objects"."""
    if unit == "m":
        return f"{x:.3f} m"
    if unit == "fraction":
        return f"×{x:.3f}"
    return f"{x:g} {unit_name(unit, x)}"


def render_level(
    plan: ScenePlan, task: str, axis: str, level: int, req: PreviewRequest, camera: str
) -> np.ndarray:
    """One level's ``camera`` observation right after ``reset`` with the run's seed for ``req.episode`` (the
    policy's pixels before its wrapper's conventions), drawn upright."""
    env = plan.builder.make_env(task, axis, level, cameras=(camera,), image_size=(req.size, req.size),
                                max_steps=None)  # fmt: skip
    try:
        seed = evaluation_seed(req.seed, plan.scene, task, req.episode)
        obs, _ = env.reset(seed=seed, options={"episode": req.episode})  # LIBERO: the episode's fixed state
        return env.upright(obs.images[camera])
    finally:
        env.close()


def preview_tiles(req: PreviewRequest) -> tuple[ScenePlan, list[Tile]]:
    """Resolve the request as ``evaluate`` would and render every level of every axis, in level order."""
    plan = resolve_scene_plan(req.scene, req.task, req.axes, req.levels, req.step, req.preset)
    plan.builder.check_ready()
    cameras = plan.builder.env_spec.cameras
    camera = check_env_args((req.camera or cameras[0],), None, cameras)[0]
    task = plan.tasks[0]
    tiles = []
    try:
        for axis in plan.axes:
            for k in plan.levels[axis]:
                img = render_level(plan, task, axis, k, req, camera)
                tiles.append(Tile(axis, k, level_caption(plan, task, axis, k), img))
    finally:
        if plan.builder.family.runtime is not None:  # a family in its own venv: stop its idle worker now
            close_idle_workers()
    return plan, tiles


def write_preview(req: PreviewRequest) -> tuple[Path, list[Tile]]:
    """Render the levels and write the labelled sheet to ``req.out``; returns the path and the tiles."""
    _check_writable(req.out)  # before the renders, not after them
    plan, tiles = preview_tiles(req)
    task, camera = plan.tasks[0], req.camera or plan.builder.env_spec.cameras[0]
    rows = [(axis, [(t.image, t.caption) for t in tiles if t.axis == axis]) for axis in plan.axes]
    boxes = " — placeholder assets (boxes)" if getattr(plan.builder, "placeholder_assets", False) else ""
    title = (f"{plan.scene} / {task} — {', '.join(plan.axes)}{boxes}\nepisode {req.episode} (run seed "
             f"{req.seed}), {camera} at t = 0")  # fmt: skip
    fig = contact_sheet(rows, title)
    try:
        atomic_savefig(fig, req.out)
    except OSError as e:
        raise RunDirError(f"cannot write --out {req.out}: {e.strerror}; choose another path") from None
    return req.out, tiles


def _check_writable(out: Path) -> None:
    """Fail in one line before minutes of rendering when ``out``'s folder cannot take a file."""
    import tempfile

    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out.parent):
            pass
    except OSError as e:
        raise RunDirError(f"cannot write --out {out}: {e.strerror}; choose another path") from None
