"""``indgen demos``: record demonstrations with the scripted oracle plus human-like noise and pauses, at T0 or at
levels of one axis, written with lerobot's own ``LeRobotDataset`` API so lerobot's training code reads them
unchanged."""

from __future__ import annotations

import argparse
import json
import shutil
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from indgen_vla.errors import ConfigError
from indgen_vla.interface import ACTION_DIM, OBJECT_DIM, OBJECT_NAMES, STATE_DIM, Observation
from indgen_vla.regimes import quiet_datasets
from indgen_vla.seeding import fresh_seed, held_out_seeds
from scenes.poses import object_poses, object_vector
from scenes.privileged import privileged_of, with_privileged

FPS = 20  # robosuite control frequency used by every scene
STATE_NAMES = ["eef_x", "eef_y", "eef_z", "eef_ax", "eef_ay", "eef_az", "gripper_l", "gripper_r"]
ACTION_NAMES = ["dx", "dy", "dz", "drx", "dry", "drz", "gripper"]
# per-episode sidecar beside lerobot's own metadata: episode seed and per-frame object poses (MimicGen's source)
EPISODES_SIDECAR = "meta/indgen_episodes.jsonl"
ENV_STATE = "observation.environment_state"
# per-frame columns of a dataset recorded with --axis: each frame's level, axis and axis parameter (lerobot reads
# them back like any column: ds.hf_dataset.filter(lambda r: r["level"] <= 1); policies ignore them)
LEVEL_FEATURES = {
    "level": {"dtype": "int64", "shape": (1,), "names": None},
    "axis": {"dtype": "string", "shape": (1,), "names": None},
    "axis_param": {"dtype": "float64", "shape": (1,), "names": None},
}


@dataclass(frozen=True)
class HumanNoise:
    """Teleoperator-like imperfections layered on the oracle: jittery motion and short hesitations.

    Attributes:
        sigma: std of Gaussian noise added to the 6 motion dims (action units, [-1, 1] range).
        pause_prob: chance per step of starting a pause (zero motion, gripper held).
        pause_steps: (min, max) length of a pause in control steps.
    """

    sigma: float = 0.1
    pause_prob: float = 0.02
    pause_steps: tuple[int, int] = (2, 8)

    def __post_init__(self) -> None:
        if self.sigma < 0 or not 0 <= self.pause_prob < 1:
            raise ConfigError(f"noise sigma must be >= 0 and pause probability in [0, 1); got {self}")
        if not 1 <= self.pause_steps[0] <= self.pause_steps[1]:
            raise ConfigError(f"pause_steps must be 1 <= min <= max, got {self.pause_steps}")


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


def append_episode_sidecar(root: Path, record: dict) -> None:
    """Append one episode's record (seed, task, per-frame object poses) to the dataset's sidecar."""
    path = Path(root) / EPISODES_SIDECAR
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps(record, separators=(",", ":")) + "\n")


def read_episode_sidecar(root: Path) -> list[dict]:
    """The sidecar records of a dataset written by ``indgen demos`` or ``indgen mimicgen`` ([] if absent)."""
    path = Path(root) / EPISODES_SIDECAR
    if not path.is_file():
        return []
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def noisy_oracle_episode(env, seed: int, noise: HumanNoise) -> Iterator[tuple[Observation, np.ndarray, dict]]:
    """Yield (observation, executed action, info) for one episode of the noisy oracle, seeded."""
    from scenes.oracle import OraclePolicy

    rng = np.random.default_rng(seed)
    oracle = OraclePolicy()
    obs, _ = env.reset(seed=seed)
    oracle.reset(obs.instruction, seed=seed)
    pause = 0
    for _ in range(env.max_steps):
        obs = with_privileged(obs, env)  # yielded too, so recorders can keep object poses
        a = oracle.act([obs])[0, 0].astype(np.float64)
        if pause == 0 and rng.random() < noise.pause_prob:
            pause = int(rng.integers(noise.pause_steps[0], noise.pause_steps[1] + 1))
        if pause > 0:
            pause -= 1
            a[:6] = 0.0
        else:
            a[:6] = np.clip(a[:6] + rng.normal(0.0, noise.sigma, 6), -1.0, 1.0)
        a = a.astype(np.float32)
        next_obs, _, terminated, truncated, info = env.step(a)
        yield obs, a, info
        obs = next_obs
        if terminated or truncated:
            return


@dataclass(frozen=True)
class DemoCell:
    """One (task, level) ``indgen demos`` records: ``axis`` None is T0 as recorded without ``--axis``."""

    task: str
    level: int = 0
    axis: str | None = None
    param: float | None = None

    @property
    def label(self) -> str:
        return self.task if self.axis is None else f"{self.task} {self.axis} level {self.level}"

    def seed_key(self, scene: str) -> tuple:
        """The seed key of its episodes: level 0 keeps T0's key, so it holds the same episodes on every axis."""
        if self.level == 0:
            return ("demos", scene, self.task)
        return ("demos", scene, self.task, self.axis, self.level)


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
    scene: str, task: str | None, req: LevelRequest, cameras, image_size
) -> tuple[list[DemoCell], Callable]:
    """The cells to record and a ``make_env(cell)`` for them; with ``--axis`` resolved exactly as ``evaluate``
    resolves it (``scenes.planning.resolve_scene_plan``: names, level range, condition 2, certificates)."""
    import scenes
    from indgen_vla.plan import FAILED
    from scenes.registry import get_scene

    fixed = get_scene(scene).fixed_initial_states
    if fixed:
        raise ConfigError(f"scene {scene} starts every episode from {fixed}, the initial states `evaluate` runs; "
                          "demonstrations there would train on them: record on a scene whose seed draws the "
                          "initial state (pick_place, stack, cabinet_pick)")  # fmt: skip
    size = (image_size, image_size)
    if req.axis is None:
        cells = [DemoCell(t) for t in scenes.select_tasks(scene, task)]
        return cells, lambda c: scenes.make_env(scene, task=c.task, level=0, cameras=cameras, image_size=size)
    from scenes.planning import resolve_scene_plan

    plan = resolve_scene_plan(scene, task, (req.axis,), req.levels, req.step, req.preset)
    axis = next(iter(plan.axes))
    failed = [c for c in plan.cells if c.certificate == FAILED]
    if failed:
        c = failed[0]
        raise ConfigError(f"{scene}/{axis}: the oracle failed its certification at task {c.task} level {c.level} "
                          f"({c.evidence}); drop it from --levels")  # fmt: skip
    cells = [DemoCell(c.task, c.level, axis, c.param) for c in plan.cells]

    def make_env(c: DemoCell):
        return plan.builder.make_env(c.task, axis, c.level, cameras=cameras, image_size=size, max_steps=None)

    return cells, make_env


def record_demos(
    scene: str, out: Path, n: int, task: str | None = None, seed: int = 0, image_size: int = 96,
    cameras: tuple[str, ...] = ("agentview", "wrist"), noise: HumanNoise | None = None,
    repo_id: str = "local/indgen_demos", use_videos: bool = False, max_attempts_factor: int = 3, progress=None,
    objects: bool = False, levels: LevelRequest | None = None,
) -> dict:  # fmt: skip
    """Record ``n`` successful episodes per task (and level) into a LeRobotDataset at ``out``; return stats.

    ``objects`` adds the pick and target poses per frame as ``observation.environment_state``; ``levels`` (an axis
    and its levels) records each level, with its level, axis and axis parameter per frame (``LEVEL_FEATURES``)
    and in the sidecar. No episode starts from a seed of ``seeding.held_out_seeds`` (the ones ``evaluate`` uses).
    """
    noise, levels = noise or HumanNoise(), levels or LevelRequest()
    if n < 1:
        raise ConfigError(f"--n must be >= 1, got {n}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ConfigError(f"--out {out} already exists and is not empty; choose a new directory")
    cells, make_env = plan_cells(scene, task, levels, cameras, image_size)
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.rmdir()
    feats = features(cameras, (image_size, image_size), use_videos, objects, levels.axis is not None)
    ds = LeRobotDataset.create(repo_id=repo_id, fps=FPS, features=feats, root=out, robot_type="panda",
                               use_videos=use_videos, video_backend="pyav")  # fmt: skip
    stats = {"scene": scene, "tasks": list(dict.fromkeys(c.task for c in cells)), "episodes": 0, "attempts": 0,
             "frames": 0, "cells": []}  # fmt: skip
    if levels.axis is not None:
        stats.update(axis=cells[0].axis, levels=sorted({c.level for c in cells}))
    recorder = _Recorder(ds, out, scene, cameras, objects, levels, noise)
    try:
        for cell in cells:
            env = make_env(cell)
            try:
                kept, attempt, frames = recorder.record(env, cell, n, seed, max_attempts_factor * n, progress)
            finally:
                env.close()
            stats["episodes"] += kept
            stats["attempts"] += attempt
            stats["frames"] += frames
            stats["cells"].append({"task": cell.task, "level": cell.level, "kept": kept, "attempts": attempt})
    except BaseException:
        ds.finalize()
        raise
    ds.finalize()
    stats["success_rate"] = stats["episodes"] / max(stats["attempts"], 1)
    return stats


@dataclass
class _Recorder:
    """Writes kept noisy-oracle episodes of one dataset: frames, per-frame level columns, sidecar records."""

    ds: Any
    out: Path
    scene: str
    cameras: tuple[str, ...]
    objects: bool
    levels: LevelRequest
    noise: HumanNoise

    def record(
        self, env, cell: DemoCell, n: int, seed: int, max_attempts: int, progress
    ) -> tuple[int, int, int]:
        """Record ``n`` successful episodes of ``cell``; return (kept, attempts, frames)."""
        avoid = held_out_seeds(self.scene, cell.task, also=(seed,))
        kept = attempt = total = 0
        while kept < n:
            if attempt >= max_attempts:
                raise ConfigError(f"only {kept}/{n} noisy oracle demos of {self.scene}/{cell.label} succeeded in "
                                  f"{attempt} attempts; lower the noise")  # fmt: skip
            ep_seed = fresh_seed(seed, *cell.seed_key(self.scene), attempt, avoid=avoid)
            attempt += 1
            frames, success = [], False
            for obs, a, info in noisy_oracle_episode(env, ep_seed, self.noise):
                frames.append((obs, a))
                success = bool(info.get("success", False))
            if not success:
                continue  # keep only successful demonstrations, like a human operator's keepers
            self._save(cell, ep_seed, frames)
            kept += 1
            total += len(frames)
            if progress is not None:
                progress(cell.label, kept, attempt)
        return kept, attempt, total

    def _save(self, cell: DemoCell, ep_seed: int, frames: list) -> None:
        poses = [object_poses(privileged_of(obs, "indgen demos")) for obs, _ in frames]
        per_level = level_columns(cell.level, cell.axis, cell.param) if self.levels.axis is not None else {}
        save_episode(self.ds, [(o, a, p) for (o, a), p in zip(frames, poses, strict=True)], self.cameras,
                     self.objects, per_level)  # fmt: skip
        record = {"episode_index": self.ds.num_episodes - 1, "regime": "demos", "scene": self.scene,
                  "task": cell.task, "seed": ep_seed, "level": cell.level}  # fmt: skip
        if self.levels.axis is not None:
            record.update(self.levels.extra(), param=cell.param)
        record.update(frames=len(frames), object_poses=rounded_poses(poses))
        append_episode_sidecar(self.out, record)


def demos_main(args: argparse.Namespace) -> int:
    """CLI handler for ``indgen demos`` (its own parser over the passthrough arguments)."""
    from indgen_vla.cli import IndgenParser, add_level_options

    p = IndgenParser(
        prog="indgen demos",
        description="record noisy-oracle demonstrations (T0, or --axis A --levels 0:2) as a LeRobotDataset",
    )
    p.add_argument("--scene", required=True, help="built-in scene to record (see `indgen scenes`)")
    p.add_argument("--task", default=None, help="task name or 'all' (default: the scene's first task)")
    p.add_argument(
        "--axis", default=None, help="record levels of this axis (see 'indgen axes'); default: T0 only"
    )
    add_level_options(p, levels_default="required with --axis")
    p.add_argument("--n", type=int, required=True, help="successful episodes per task (and level)")
    p.add_argument("--out", required=True, help="dataset root directory (must not exist)")
    p.add_argument(
        "--seed", type=int, default=0, help="base seed; episode i of a task always gets the same seed"
    )
    p.add_argument("--image-size", type=int, default=96, help="camera side in pixels (square frames)")
    p.add_argument("--noise", type=float, default=0.1, help="std of motion noise (action units)")
    p.add_argument(
        "--pause-prob", type=float, default=0.02, help="per-step probability of a human-like pause"
    )
    p.add_argument(
        "--repo-id", default="local/indgen_demos", help="LeRobotDataset repo id stored in the dataset"
    )
    p.add_argument("--videos", action="store_true", help="store cameras as mp4 videos instead of images")
    p.add_argument(
        "--cameras", default="agentview,wrist", help="comma-separated cameras to record; empty = state only"
    )
    p.add_argument(
        "--objects",
        action="store_true",
        help="also record the pick and target poses as observation.environment_state (low-dim policies)",
    )
    a = p.parse_args(args.rest)
    cams = tuple(c for c in a.cameras.split(",") if c)
    levels = LevelRequest(a.axis, a.levels, a.step, a.axes_preset)
    quiet_datasets()
    from rich.console import Console

    console = Console(stderr=True)

    def progress(label, kept, attempt):
        console.print(f"  {label}: {kept}/{a.n} kept ({attempt} attempts)", end="\r")

    out = Path(a.out)
    # on a failure only what this run made is removed (a partial dataset would only block the re-run)
    fresh = not out.exists() or (out.is_dir() and not any(out.iterdir()))
    try:
        stats = record_demos(a.scene, out, a.n, a.task, a.seed, a.image_size,
                             noise=HumanNoise(sigma=a.noise, pause_prob=a.pause_prob), repo_id=a.repo_id,
                             use_videos=a.videos, progress=progress, cameras=cams, objects=a.objects,
                             levels=levels)  # fmt: skip
    except BaseException:
        if fresh:
            shutil.rmtree(out, ignore_errors=True)
        raise
    where = f" at levels {', '.join(map(str, stats['levels']))} of {stats['axis']}" if "axis" in stats else ""
    console.print(f"\nrecorded {stats['episodes']} episodes ({stats['frames']} frames) of {a.scene} "
                  f"{', '.join(stats['tasks'])}{where} into {out}; oracle keep rate {100 * stats['success_rate']:.0f}% "
                  f"({stats['episodes']} of {stats['attempts']} attempts, pooled over tasks and levels)")  # fmt: skip
    if "axis" in stats:
        console.print("kept per task and level: " + ", ".join(
            f"{c['task']} {c['level']}: {c['kept']}/{c['attempts']}" for c in stats["cells"]))  # fmt: skip
    return 0
