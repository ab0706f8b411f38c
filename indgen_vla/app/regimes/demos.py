"""``indgen demos``: record demonstrations with the scripted oracle plus human-like noise and pauses, at T0 or at
levels of one axis, written with lerobot's own ``LeRobotDataset`` API so lerobot's training code reads them
unchanged. A killed run resumes where it stopped (``journal``); ``--workers`` records in worker processes, with the
same dataset for any number of them (``demo_attempts``)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

# `X as X`: re-exported for mimicgen, train and the tests, which import them from here (their home before the split)
from indgen_vla.app.config_fields import check_types, option, section
from indgen_vla.app.engine.config import OPTIONS, levels_text
from indgen_vla.app.regimes.demo_attempts import AttemptPlan, DemoCell, EnvMaker, kept_episodes
from indgen_vla.app.regimes.demo_attempts import HumanNoise as HumanNoise
from indgen_vla.app.regimes.journal import EPISODES_SIDECAR as EPISODES_SIDECAR
from indgen_vla.app.regimes.journal import JournaledDataset, drop_journal, read_record
from indgen_vla.app.regimes.journal import append_episode_sidecar as append_episode_sidecar
from indgen_vla.app.regimes.journal import read_episode_sidecar as read_episode_sidecar
from indgen_vla.app.regimes.resume import check_same_run
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import ACTION_DIM, OBJECT_DIM, OBJECT_NAMES, STATE_DIM
from indgen_vla.core.protocol.plan import FAILED
from scenes.family import Scene
from scenes.planning import resolve_scene_plan, scene_levels
from scenes.poses import object_vector

FPS = 20  # robosuite control frequency used by every scene
STATE_NAMES = ["eef_x", "eef_y", "eef_z", "eef_ax", "eef_ay", "eef_az", "gripper_l", "gripper_r"]
ACTION_NAMES = ["dx", "dy", "dz", "drx", "dry", "drz", "gripper"]
ENV_STATE = "observation.environment_state"
# per-frame columns of a dataset recorded with --axis: each frame's level, axis and axis parameter (lerobot reads
# them back like any column: ds.hf_dataset.filter(lambda r: r["level"] <= 1); policies ignore them)
LEVEL_FEATURES = {
    "level": {"dtype": "int64", "shape": (1,), "names": None},
    "axis": {"dtype": "string", "shape": (1,), "names": None},
    "axis_param": {"dtype": "float64", "shape": (1,), "names": None},
}


def features(
    cameras: tuple[str, ...], image_size: tuple[int, int], use_videos: bool, objects: bool = False,
    levels: bool = False,
) -> dict:  # fmt: skip
    """LeRobotDataset feature spec: one image per camera, 8-d state, 7-d action (+ object poses, + the level
    columns ``LEVEL_FEATURES``, if asked)."""
    h, w = image_size
    feats = {
        f"observation.images.{cam}": {"dtype": "video" if use_videos else "image", "shape": (h, w, 3),
                                      "names": ["height", "width", "channels"]}
        for cam in cameras
    }  # fmt: skip
    feats["observation.state"] = {"dtype": "float32", "shape": (STATE_DIM,), "names": STATE_NAMES}
    if objects:  # robomimic's "object" observation, as lerobot's environment_state
        feats[ENV_STATE] = {"dtype": "float32", "shape": (OBJECT_DIM,), "names": list(OBJECT_NAMES)}
    feats["action"] = {"dtype": "float32", "shape": (ACTION_DIM,), "names": ACTION_NAMES}
    if levels:
        feats.update({k: dict(v) for k, v in LEVEL_FEATURES.items()})
    return feats


def save_episode(ds, frames: list, cameras: tuple[str, ...], objects: bool, per_level: dict) -> None:
    """Add one episode's (observation, executed action, object poses) frames to ``ds`` and save it."""
    for obs, a, pose in frames:
        frame = {f"observation.images.{c}": obs.images[c] for c in cameras}
        frame.update(
            {"observation.state": obs.state.astype(np.float32), "action": a, "task": obs.instruction}
        )
        if objects:
            frame[ENV_STATE] = object_vector(pose)
        frame.update(per_level)
        ds.add_frame(frame)
    ds.save_episode()


def rounded_poses(poses: list[dict]) -> dict:
    """Per-frame object poses as the sidecar stores them: object -> frames -> 6-decimal numbers."""
    return {k: [[round(v, 6) for v in p[k]] for p in poses] for k in poses[0]}


def level_columns(level: int, axis: str | None, param: float | None) -> dict:
    """One frame's ``LEVEL_FEATURES`` values."""
    return {"level": np.array([level], np.int64), "axis": axis or "",
            "axis_param": np.array([np.nan if param is None else param], np.float64)}  # fmt: skip


def _evaluate_option(name: str) -> Any:
    """evaluate's option ``name`` (its help line, type, metavar) as a field of ``indgen demos``' config."""
    meta = OPTIONS[name].field.metadata
    help_ = meta["help"].replace("{levels_default}", "required with --axis")
    return option(None, help_, **meta["argparse"])


@dataclass(frozen=True, kw_only=True)
class LevelRequest:
    """``--axis``/``--levels``/``--step``/``--axes-preset`` of ``indgen demos``, resolved as ``evaluate`` resolves
    them: one axis or composition (no axis: T0 only, the default), the levels to record (required with an axis),
    and the step and axes preset as in ``evaluate``."""

    axes: tuple[str, ...] = option((), "record levels of this axis (see 'indgen axes'); default: T0 only",
                                   flag="axis")  # fmt: skip
    levels: str | None = _evaluate_option("levels")
    step: float | None = _evaluate_option("step")
    axes_preset: str | None = _evaluate_option("axes_preset")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if isinstance(self.axes, str):  # the flag's text
            object.__setattr__(self, "axes", tuple(a.strip() for a in self.axes.split(",") if a.strip()))
        object.__setattr__(self, "axes", tuple(self.axes))
        object.__setattr__(self, "levels", levels_text(self.levels))
        if not self.axes and (self.levels, self.step, self.axes_preset) != (None, None, None):
            raise ConfigError(
                "--levels, --step and --axes-preset need --axis, e.g. --axis pick_y --levels 0:2"
            )
        if len(self.axes) > 1:
            raise ConfigError(
                f"--axis {','.join(self.axes)!r}: indgen demos records one axis per dataset; run it once per axis"
            )
        if self.axes and self.levels is None:
            raise ConfigError(f"--axis {self.axis} needs --levels, the levels to record (e.g. --levels 0:2)")

    @property
    def axis(self) -> str | None:
        """The axis recorded (None: T0 only)."""
        return self.axes[0] if self.axes else None

    def extra(self) -> dict:
        """What the sidecar records besides the level (and what ``indgen mimicgen`` rebuilds the level from)."""
        out: dict = {"axis": self.axis}
        if self.step is not None:
            out["step"] = self.step
        if self.axes_preset is not None:
            out["axes_preset"] = self.axes_preset
        return out


@dataclass(frozen=True, kw_only=True)
class DemosConfig:
    """What ``indgen demos`` records: ``n`` kept episodes per task (and level) of ``scene`` into the dataset ``out``,
    with the noisy oracle ``noise``, at T0 or the levels ``at``; the frames' cameras, size and object poses."""

    scene: str = option(help="built-in scene to record (see `indgen scenes`)", required=True)
    task: str | None = option(None, "task name or 'all' (default: the scene's first task)")
    at: LevelRequest = section(LevelRequest)
    n: int = option(help="successful episodes per task (and level)", type=int, required=True)
    out: Path = option(help="dataset root: a new directory, or one to resume (same arguments)", required=True)
    seed: int = option(0, "base seed; episode i of a task always gets the same seed", type=int)
    image_size: int = option(96, "camera side in pixels (square frames)", type=int)
    noise: HumanNoise = section(HumanNoise)
    repo_id: str = option("local/indgen_demos", "LeRobotDataset repo id stored in the dataset")
    videos: bool = option(False, "store cameras as mp4 videos instead of images")
    cameras: tuple[str, ...] = option(
        ("agentview", "wrist"), "comma-separated cameras to record; empty = state only"
    )
    objects: bool = option(False, "also record the pick and target poses as observation.environment_state (low-dim "
                           "policies)")  # fmt: skip
    workers: int | None = option(None, "worker processes recording episodes (default: number of cores); the "
                                 "dataset is the same for any number", type=int)  # fmt: skip
    max_attempts_factor: int = option(3)  # attempts per cell at most, in units of n (API only)

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if isinstance(self.cameras, str):  # the flag's text
            object.__setattr__(self, "cameras", tuple(c for c in self.cameras.split(",") if c))
        object.__setattr__(self, "cameras", tuple(self.cameras))
        object.__setattr__(self, "out", Path(self.out))
        object.__setattr__(self, "workers", (os.cpu_count() or 1) if self.workers is None else self.workers)
        if not self.scene:
            raise ConfigError("--scene is required; list scenes with 'indgen scenes'")
        for flag, value in (("--n", self.n), ("--workers", self.workers)):
            if value < 1:
                raise ConfigError(f"{flag} must be >= 1, got {value}")
        if self.image_size < 1 or self.max_attempts_factor < 1:
            raise ConfigError(f"--image-size and max_attempts_factor must be >= 1, got {self.image_size}, "
                              f"{self.max_attempts_factor}")  # fmt: skip


# the flags of ``indgen demos`` in its --help order
FLAGS = ("scene", "task", "axes", "levels", "step", "axes_preset", "n", "out", "seed", "image_size", "noise",
         "pause_prob", "repo_id", "videos", "cameras", "objects", "workers")  # fmt: skip


def plan_cells(
    scene: Scene, task: str | None, req: LevelRequest, cameras, image_size: int
) -> tuple[list[DemoCell], EnvMaker]:
    """The cells to record and the ``EnvMaker`` of their scenes; with ``--axis`` resolved exactly as ``evaluate``
    resolves it (``scenes.planning.resolve_scene_plan``: names, level range, condition 2, certificates)."""
    name = scene.name
    if scene.fixed_initial_states:
        raise ConfigError(f"scene {name} starts every episode from {scene.fixed_initial_states}, the initial states "
                          "`evaluate` runs; demonstrations there would train on them: record on a scene whose seed "
                          "draws the initial state (pick_place, stack, cabinet_pick)")  # fmt: skip
    if req.axis is None:  # T0: level 0 of the family's first axis, each task's own
        tasks = scene.select_tasks(task)
        builder = scene_levels(scene, (scene.default_axis,), tasks=tasks)
        return [DemoCell(t) for t in tasks], EnvMaker(
            name, tuple(cameras), image_size, builder, scene.default_axis
        )

    plan = resolve_scene_plan(scene, task, (req.axis,), req.levels, req.step, req.axes_preset)
    plan.builder.check_ready()
    axis = next(iter(plan.axes))
    failed = [c for c in plan.cells if c.certificate == FAILED]
    if failed:
        c = failed[0]
        raise ConfigError(f"{name}/{axis}: the oracle failed its certification at task {c.task} level {c.level} "
                          f"({c.evidence}); drop it from --levels")  # fmt: skip
    cells = [DemoCell(c.task, c.level, axis, c.param) for c in plan.cells]
    return cells, EnvMaker(name, tuple(cameras), image_size, plan.builder)


ARGS_RECORD = (
    "meta/indgen_demos.json"  # the arguments a dataset was recorded with, and whether it is complete
)
# what defines a dataset's content, in the order a mismatch is reported, with the option that sets it
# (pause_steps and max_attempts_factor: record_demos arguments only)
RECORDED = {"scene": "--scene", "task": "--task", "axis": "--axis", "levels": "--levels", "step": "--step",
            "axes_preset": "--axes-preset", "n": "--n", "seed": "--seed", "image_size": "--image-size",
            "cameras": "--cameras", "noise": "--noise", "pause_prob": "--pause-prob", "pause_steps": "pause_steps",
            "repo_id": "--repo-id", "videos": "--videos", "objects": "--objects",
            "max_attempts_factor": "max_attempts_factor"}  # fmt: skip


def check_args(out: Path, recorded: dict, args: dict, finished: bool = False) -> None:
    """Refuse to continue a dataset with other arguments than it was recorded with: one line naming the first."""
    flags = [key for key, flag in RECORDED.items() if flag.startswith("--")]
    now = {key: args[key] for key in RECORDED}
    check_same_run(out, {key: recorded.get(key) for key in RECORDED}, now, "demos", flags, finished)


@dataclass(frozen=True)
class _EpisodeWriter:
    """Saves one kept episode into the dataset (frames, per-frame level columns) and returns its sidecar record."""

    scene: str
    cameras: tuple[str, ...]
    objects: bool
    levels: LevelRequest

    def __call__(self, ds, kept: dict) -> dict:
        cell, frames = kept["cell"], kept["frames"]
        per_level = level_columns(cell.level, cell.axis, cell.param) if self.levels.axis is not None else {}
        save_episode(ds, frames, self.cameras, self.objects, per_level)
        record = {"episode_index": ds.num_episodes - 1, "regime": "demos", "scene": self.scene,
                  "task": cell.task, "seed": kept["seed"], "level": cell.level}  # fmt: skip
        if self.levels.axis is not None:
            record.update(self.levels.extra(), param=cell.param)
        record.update(frames=len(frames), object_poses=rounded_poses([p for _, _, p in frames]))
        return record


def _progress(
    cells: list[DemoCell], seeds: list[list[int]], records: list[dict]
) -> tuple[list[int], list[int]]:
    """Per cell, (episodes kept, attempts run up to the last kept one) according to the sidecar ``records``."""
    kept, attempts = [0] * len(cells), [0] * len(cells)
    index = {(c.task, c.level): i for i, c in enumerate(cells)}
    for r in records:
        c = index.get((r["task"], r["level"]))
        if c is None or r["seed"] not in seeds[c]:
            raise ConfigError(f"episode {r['episode_index']} of the dataset ({r['task']} level {r['level']}, seed "
                              f"{r['seed']}) is not one these arguments record; choose a new --out")  # fmt: skip
        kept[c] += 1
        attempts[c] = seeds[c].index(r["seed"]) + 1
    return kept, attempts


def record_demos(cfg: DemosConfig, scene: Scene, *, progress=None, notice=None) -> dict:
    """Record ``cfg.n`` successful episodes per task (and level) of ``scene`` into a LeRobotDataset at ``cfg.out``;
    return stats.

    ``cfg.objects`` adds the pick and target poses per frame as ``observation.environment_state``; ``cfg.at`` (an
    axis and its levels) records each level, with its level, axis and axis parameter per frame (``LEVEL_FEATURES``)
    and in the sidecar. No episode starts from a seed of ``seeding.held_out_seeds`` (the ones ``evaluate`` uses).
    An ``out`` recorded with the same arguments is resumed after its last saved episode (``notice`` gets the line
    saying so); a complete one is left as it is (stats ``already_complete``). ``cfg.workers`` > 1 records in worker
    processes; the dataset is the same for any number. ``progress(label, kept, attempt)`` follows each cell.
    """
    if scene.name != cfg.scene:
        raise ConfigError(f"record_demos: the scene given is {scene.name}, the config's {cfg.scene}")
    noise, levels, cameras, out = cfg.noise, cfg.at, cfg.cameras, cfg.out
    cells, maker = plan_cells(scene, cfg.task, levels, cameras, cfg.image_size)
    args = json.loads(json.dumps({
        "scene": cfg.scene, "task": cfg.task, "axis": levels.axis, "levels": levels.levels, "step": levels.step,
        "axes_preset": levels.axes_preset, "n": cfg.n, "seed": cfg.seed, "image_size": cfg.image_size,
        "cameras": list(cameras), "noise": noise.sigma, "pause_prob": noise.pause_prob,
        "pause_steps": list(noise.pause_steps), "repo_id": cfg.repo_id, "videos": cfg.videos, "objects": cfg.objects,
        "max_attempts_factor": cfg.max_attempts_factor,
    }))  # fmt: skip
    feats = features(
        cameras, (cfg.image_size, cfg.image_size), cfg.videos, cfg.objects, levels.axis is not None
    )
    lerobot = {"repo_id": cfg.repo_id, "fps": FPS, "features": feats, "robot_type": "panda", "use_videos": cfg.videos,
               "video_backend": "pyav"}  # fmt: skip
    dataset = _open(out, args, lerobot, repo_id=cfg.repo_id, record=ARGS_RECORD,
                    write=_EpisodeWriter(cfg.scene, cameras, cfg.objects, levels))  # fmt: skip
    if isinstance(dataset, dict):
        return dataset
    n = cfg.n
    seeds = [c.attempt_seeds(cfg.scene, cfg.seed, cfg.max_attempts_factor * n) for c in cells]
    kept, attempts = _progress(cells, seeds, read_episode_sidecar(out))
    if sum(kept) and notice is not None:
        notice(f"resuming {out}: {sum(kept)} of {n * len(cells)} episodes already recorded")
    plan = AttemptPlan(maker, noise, cells, seeds, n, kept, attempts)
    _record(dataset, plan, cfg.workers, progress)
    stats = _stats(cfg.scene, cells, plan, read_episode_sidecar(out), levels)
    dataset.complete({"stats": stats})
    return stats


def _open(out: Path, args: dict, lerobot: dict, **kw) -> JournaledDataset | dict:
    """A new dataset at ``out``, or the one there recorded with ``args`` reopened (its stats if it is complete)."""
    recorded = _recorded(out)
    if recorded is None:
        return JournaledDataset.create(out, {"command": "indgen demos", "args": args}, lerobot, **kw)
    check_args(out, recorded.get("args", {}), args, finished=bool(recorded.get("complete")))
    if recorded.get("complete"):
        drop_journal(out)  # left by a run killed as it finished
        return {**recorded["stats"], "already_complete": True}
    return JournaledDataset.reopen(out, **kw)


def _record(dataset: JournaledDataset, plan: AttemptPlan, workers: int, progress) -> None:
    """Add every episode ``plan`` keeps to ``dataset``, in order; an interrupted run leaves it to the journal."""
    episodes = kept_episodes(plan, workers)
    try:
        with dataset.recording():
            for c, a, frames in episodes:
                dataset.add({"cell": plan.cells[c], "seed": plan.seeds[c][a], "frames": frames})
                if progress is not None:
                    progress(plan.cells[c].label, plan.kept[c], a + 1)
    finally:
        episodes.close()  # stops the workers at once


def _recorded(out: Path) -> dict | None:
    """The arguments record of ``out`` (None: ``out`` is absent or empty); refuses any other directory."""
    if out.exists() and not out.is_dir():
        raise ConfigError(f"--out {out} is a file; choose a directory")
    if not out.exists() or not any(out.iterdir()):
        return None
    recorded = read_record(out, ARGS_RECORD)
    if recorded is None:
        raise ConfigError(f"--out {out} already exists and is not an indgen demos dataset (it has no "
                          f"{ARGS_RECORD}); choose a new directory")  # fmt: skip
    return recorded


def _stats(
    scene: str, cells: list[DemoCell], plan: AttemptPlan, records: list[dict], levels: LevelRequest
) -> dict:
    """What ``record_demos`` returns (and the record keeps): episodes, frames and attempts, per cell too."""
    stats = {"scene": scene, "tasks": list(dict.fromkeys(c.task for c in cells)), "episodes": len(records),
             "attempts": sum(plan.next_attempt), "frames": sum(r["frames"] for r in records),
             "cells": [{"task": c.task, "level": c.level, "kept": k, "attempts": a}
                       for c, k, a in zip(cells, plan.kept, plan.next_attempt, strict=True)]}  # fmt: skip
    if levels.axis is not None:
        stats.update(axis=cells[0].axis, levels=sorted({c.level for c in cells}))
    stats["success_rate"] = stats["episodes"] / max(stats["attempts"], 1)
    return stats
