"""``indgen demos``: record demonstrations with the scripted oracle plus human-like noise and pauses, at T0 or at
levels of one axis, written with lerobot's own ``LeRobotDataset`` API so lerobot's training code reads them
unchanged. A killed run resumes where it stopped (``journal``); ``--workers`` records in worker processes, with the
same dataset for any number of them (``demo_attempts``)."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

# `X as X`: re-exported for mimicgen, train and the tests, which import them from here (their home before the split)
from indgen_vla.app.regimes.demo_attempts import AttemptPlan, DemoCell, EnvMaker, kept_episodes
from indgen_vla.app.regimes.demo_attempts import HumanNoise as HumanNoise
from indgen_vla.app.regimes.journal import EPISODES_SIDECAR as EPISODES_SIDECAR
from indgen_vla.app.regimes.journal import JournaledDataset, drop_journal, read_record
from indgen_vla.app.regimes.journal import append_episode_sidecar as append_episode_sidecar
from indgen_vla.app.regimes.journal import read_episode_sidecar as read_episode_sidecar
from indgen_vla.app.regimes.resume import check_same_run
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import ACTION_DIM, OBJECT_DIM, OBJECT_NAMES, STATE_DIM
from scenes.family import Scene
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


@dataclass(frozen=True)
class LevelRequest:
    """``--axis``/``--levels``/``--step``/``--axes-preset`` of ``indgen demos``, resolved as ``evaluate`` resolves them.

    Attributes:
        axis: one axis or composition; None records T0 only (the default, as before levels existed).
        levels: ``--levels`` text (``0:2``, ``0,2``); required with ``axis``.
        step, preset: ``--step``, ``--axes-preset`` (as in ``evaluate``).
    """

    axis: str | None = None
    levels: str | None = None
    step: float | None = None
    preset: str | None = None

    def __post_init__(self) -> None:
        if self.axis is None and (self.levels, self.step, self.preset) != (None, None, None):
            raise ConfigError(
                "--levels, --step and --axes-preset need --axis, e.g. --axis pick_y --levels 0:2"
            )
        if self.axis is not None and "," in self.axis:
            raise ConfigError(
                f"--axis {self.axis!r}: indgen demos records one axis per dataset; run it once per axis"
            )
        if self.axis is not None and self.levels is None:
            raise ConfigError(f"--axis {self.axis} needs --levels, the levels to record (e.g. --levels 0:2)")

    def extra(self) -> dict:
        """What the sidecar records besides the level (and what ``indgen mimicgen`` rebuilds the level from)."""
        out: dict = {"axis": self.axis}
        if self.step is not None:
            out["step"] = self.step
        if self.preset is not None:
            out["axes_preset"] = self.preset
        return out


def plan_cells(
    sc: Scene, task: str | None, req: LevelRequest, cameras, image_size: int
) -> tuple[list[DemoCell], EnvMaker]:
    """The cells to record and the ``EnvMaker`` of their scenes; with ``--axis`` resolved exactly as ``evaluate``
    resolves it (``scenes.planning.resolve_scene_plan``: names, level range, condition 2, certificates)."""
    from indgen_vla.core.protocol.plan import FAILED
    from scenes.planning import resolve_scene_plan, scene_levels

    scene = sc.name
    if sc.fixed_initial_states:
        raise ConfigError(f"scene {scene} starts every episode from {sc.fixed_initial_states}, the initial states "
                          "`evaluate` runs; demonstrations there would train on them: record on a scene whose seed "
                          "draws the initial state (pick_place, stack, cabinet_pick)")  # fmt: skip
    if req.axis is None:  # T0: level 0 of the family's first axis, each task's own
        tasks = sc.select_tasks(task)
        builder = scene_levels(sc, (sc.default_axis,), tasks=tasks)
        return [DemoCell(t) for t in tasks], EnvMaker(
            scene, tuple(cameras), image_size, builder, sc.default_axis
        )

    plan = resolve_scene_plan(sc, task, (req.axis,), req.levels, req.step, req.preset)
    plan.builder.check_ready()
    axis = next(iter(plan.axes))
    failed = [c for c in plan.cells if c.certificate == FAILED]
    if failed:
        c = failed[0]
        raise ConfigError(f"{scene}/{axis}: the oracle failed its certification at task {c.task} level {c.level} "
                          f"({c.evidence}); drop it from --levels")  # fmt: skip
    cells = [DemoCell(c.task, c.level, axis, c.param) for c in plan.cells]
    return cells, EnvMaker(scene, tuple(cameras), image_size, plan.builder)


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


def record_demos(
    family: Scene, out: Path, n: int, task: str | None = None, seed: int = 0, image_size: int = 96,
    cameras: tuple[str, ...] = ("agentview", "wrist"), noise: HumanNoise | None = None,
    repo_id: str = "local/indgen_demos", use_videos: bool = False, max_attempts_factor: int = 3, progress=None,
    objects: bool = False, levels: LevelRequest | None = None, workers: int = 1, notice=None,
) -> dict:  # fmt: skip
    """Record ``n`` successful episodes per task (and level) into a LeRobotDataset at ``out``; return stats.

    ``objects`` adds the pick and target poses per frame as ``observation.environment_state``; ``levels`` (an axis
    and its levels) records each level, with its level, axis and axis parameter per frame (``LEVEL_FEATURES``)
    and in the sidecar. No episode starts from a seed of ``seeding.held_out_seeds`` (the ones ``evaluate`` uses).
    An ``out`` recorded with the same arguments is resumed after its last saved episode (``notice`` gets the line
    saying so); a complete one is left as it is (stats ``already_complete``). ``workers`` > 1 records in worker
    processes; the dataset is the same for any number.
    """
    noise, levels, scene = noise or HumanNoise(), levels or LevelRequest(), family.name
    for flag, value in (("--n", n), ("--workers", workers)):
        if value < 1:
            raise ConfigError(f"{flag} must be >= 1, got {value}")
    cells, maker = plan_cells(family, task, levels, cameras, image_size)
    args = json.loads(json.dumps({
        "scene": scene, "task": task, "axis": levels.axis, "levels": levels.levels, "step": levels.step,
        "axes_preset": levels.preset, "n": n, "seed": seed, "image_size": image_size, "cameras": list(cameras),
        "noise": noise.sigma, "pause_prob": noise.pause_prob, "pause_steps": list(noise.pause_steps),
        "repo_id": repo_id, "videos": use_videos, "objects": objects, "max_attempts_factor": max_attempts_factor,
    }))  # fmt: skip
    feats = features(tuple(cameras), (image_size, image_size), use_videos, objects, levels.axis is not None)
    lerobot = {"repo_id": repo_id, "fps": FPS, "features": feats, "robot_type": "panda", "use_videos": use_videos,
               "video_backend": "pyav"}  # fmt: skip
    dataset = _open(out, args, lerobot, repo_id=repo_id, record=ARGS_RECORD,
                    write=_EpisodeWriter(scene, tuple(cameras), objects, levels))  # fmt: skip
    if isinstance(dataset, dict):
        return dataset
    seeds = [c.attempt_seeds(scene, seed, max_attempts_factor * n) for c in cells]
    kept, attempts = _progress(cells, seeds, read_episode_sidecar(out))
    if sum(kept) and notice is not None:
        notice(f"resuming {out}: {sum(kept)} of {n * len(cells)} episodes already recorded")
    plan = AttemptPlan(maker, noise, cells, seeds, n, kept, attempts)
    _record(dataset, plan, workers, progress)
    stats = _stats(scene, cells, plan, read_episode_sidecar(out), levels)
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
