"""``indgen mimicgen``: MimicGen-style augmentation of T0 demonstrations (Mandlekar et al., 2023).

Each source demonstration is split into object-centric subtask segments: the grasp (approach, close, lift)
relative to the pick object and the place (transport, lower, release) relative to the receptacle. For a fresh
T0 initial state every segment's end-effector target poses are moved rigidly with their reference object
(``T_new_obj @ inv(T_src_obj) @ T_eef``), joined by a linear + slerp interpolation from the current pose,
and driven with robosuite OSC_POSE delta actions; only episodes the scene's success predicate accepts are
kept. The output is a LeRobotDataset with exactly the features, fps, cameras and task strings of the source.
A source recorded at levels of an axis (``indgen demos --axis A --levels 0:2``) is augmented level by level:
each episode is generated at its sources' level, from sources of that level only.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from indgen_vla.errors import ConfigError
from indgen_vla.interface import ACTION_DIM, STATE_DIM, Observation
from indgen_vla.regimes import quiet_datasets
from indgen_vla.regimes.demos import (
    ENV_STATE,
    EPISODES_SIDECAR,
    FPS,
    LEVEL_FEATURES,
    append_episode_sidecar,
    features,
    level_columns,
    read_episode_sidecar,
    rounded_poses,
    save_episode,
)
from indgen_vla.regimes.se3 import (
    interpolate_poses,
    pose_from_pq,
    pose_from_state,
    pose_to_action,
    target_poses,
    transform_segment,
)
from indgen_vla.seeding import episode_seed, held_out_seeds
from scenes.poses import object_poses

SUBTASKS = (("grasp", "pick"), ("place", "goal"))  # (segment name, reference object) in execution order
SELECTIONS = ("nearest", "random")
STATS_FILE = "mimicgen_stats.json"
LEVEL_KEYS = ("axis", "step", "axes_preset")  # sidecar keys that rebuild a source's level beside "level"


def split_subtasks(
    states: np.ndarray, actions: np.ndarray, lift_frac: float = 0.9
) -> list[tuple[int, int]] | None:
    """Frame ranges of the grasp and place segments, or None when the demo has no single grasp and release.

    The grasp segment runs from the start through the gripper closing to ``lift_frac`` of the lift height
    (so the switch to the receptacle frame happens in the air); the place segment runs to the end.
    """
    closed = np.asarray(actions)[:, -1] > 0
    closes = np.flatnonzero(closed & ~np.concatenate([[False], closed[:-1]]))
    if len(closes) != 1:
        return None
    c = int(closes[0])
    opens = np.flatnonzero(~closed[c:])
    if len(opens) == 0:
        return None
    r = c + int(opens[0])
    z = np.asarray(states)[:, 2]
    top = z[c:r].max()
    above = np.flatnonzero(z[c + 1 : r] >= z[c] + lift_frac * (top - z[c]) - 1e-9)
    e = c + 1 + int(above[0]) if len(above) else r
    return [(0, e), (e, len(states))]


# ---- sources --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SourceDemo:
    """One source demonstration with its subtask split and the reference-object poses it was recorded with."""

    index: int
    scene: str
    task: str
    seed: int
    targets: np.ndarray  # (T, 4, 4) controller goal poses
    gripper: np.ndarray  # (T,) gripper actions
    refs: dict[str, np.ndarray]  # object name -> (T, 7) per-frame world pose
    bounds: tuple[tuple[int, int], ...]
    level: int = 0
    # the sidecar's LEVEL_KEYS that rebuild its level, and its axis parameter; empty for T0 without --axis
    where: tuple[tuple[str, object], ...] = ()
    param: float | None = None

    @property
    def cell(self) -> tuple:
        """What its generated episodes share: scene, task and level (generation never leaves the level)."""
        return (self.scene, self.task, self.level, self.where)

    def segment(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(targets, gripper actions, reference object pose at the segment start) of subtask ``k``."""
        lo, hi = self.bounds[k]
        return self.targets[lo:hi], self.gripper[lo:hi], pose_from_pq(self.refs[SUBTASKS[k][1]][lo])


def load_sources(root: Path, lift_frac: float = 0.9) -> tuple[dict, list[SourceDemo], int]:
    """(lerobot info.json, usable source demos, number skipped) of a dataset written by ``indgen demos``."""
    info = json.loads((root / "meta" / "info.json").read_text())
    feats = info.get("features", {})
    if feats.get("observation.state", {}).get("shape") not in ([STATE_DIM], (STATE_DIM,)) or feats.get(
        "action", {}
    ).get("shape") not in ([ACTION_DIM], (ACTION_DIM,)):
        raise ConfigError(f"--source {root} lacks the {STATE_DIM}-d observation.state and {ACTION_DIM}-d action "
                          "of `indgen demos` datasets; record one with `indgen demos`")  # fmt: skip
    records = {r["episode_index"]: r for r in read_episode_sidecar(root)}
    if not records or not all("object_poses" in r for r in records.values()):
        raise ConfigError(f"--source {root} has no {EPISODES_SIDECAR} with per-episode seeds and object poses; "
                          "record the source with `indgen demos` (this version or newer)")  # fmt: skip
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    # only parquet columns are read: pyav spares the torchcodec probe (and its warning) when FFmpeg is missing
    ds = LeRobotDataset(info.get("repo_id", "local/indgen_demos"), root=root, video_backend="pyav")
    cols = ds.hf_dataset.select_columns(["observation.state", "action", "episode_index"]).with_format("numpy")
    ep_idx = np.asarray(cols["episode_index"]).reshape(-1)
    states, actions = np.stack(cols["observation.state"]), np.stack(cols["action"])
    demos, skipped = [], 0
    for i in sorted(set(ep_idx.tolist())):
        rec = records.get(int(i))
        rows = np.flatnonzero(ep_idx == i)
        if rec is None or any(len(rec["object_poses"].get(k, ())) != len(rows) for _, k in SUBTASKS):
            skipped += 1
            continue
        s, a = states[rows], actions[rows]
        bounds = split_subtasks(s, a, lift_frac)
        if bounds is None or any(hi - lo < 2 for lo, hi in bounds):
            skipped += 1  # regrasps or no release: no clean object-centric split
            continue
        refs = {k: np.asarray(v, dtype=float) for k, v in rec["object_poses"].items()}
        where = tuple((k, rec[k]) for k in LEVEL_KEYS if k in rec)
        demos.append(SourceDemo(int(i), rec["scene"], rec["task"], int(rec["seed"]), target_poses(s, a),
                                a[:, -1].astype(float), refs, tuple(bounds), int(rec.get("level", 0)), where,
                                rec.get("param")))  # fmt: skip
    return info, demos, skipped


def select_source(demos: list[SourceDemo], k: int, new_ref: np.ndarray, rng: np.random.Generator,
                  strategy: str = "nearest", nn_k: int = 3) -> SourceDemo:  # fmt: skip
    """MimicGen's per-subtask source choice: uniform, or uniform among the ``nn_k`` nearest reference poses."""
    if strategy == "random" or len(demos) == 1:
        return demos[int(rng.integers(len(demos)))]
    d = []
    for demo in demos:
        src = demo.segment(k)[2]
        angle = np.linalg.norm(Rotation.from_matrix(src[:3, :3].T @ new_ref[:3, :3]).as_rotvec())
        d.append(np.linalg.norm(src[:3, 3] - new_ref[:3, 3]) + 0.05 * angle)  # 5 cm per radian
    return demos[int(rng.choice(np.argsort(d, kind="stable")[:nn_k]))]


# ---- configuration and execution ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MimicGenConfig:
    """What ``indgen mimicgen`` generates and how.

    Attributes:
        source: a LeRobotDataset written by ``indgen demos`` (with its per-episode sidecar).
        out: the new dataset's root (must not exist or be empty).
        n: attempts per task (and level, for a source recorded at levels); with ``guarantee`` the number of
            successful episodes instead.
        seed: generation seed (new initial states, source choice, action noise).
        guarantee: keep attempting until ``n`` successes per task and level (at most ``max_attempts``).
        max_attempts: cap on attempts per task and level in ``guarantee`` mode (default 5 n).
        selection: per-subtask source choice, ``nearest`` (reference pose) or ``random``.
        nn_k: ``nearest`` picks uniformly among this many nearest sources.
        interp_steps: minimum interpolation steps before each segment.
        max_step_m: interpolation moves at most this far per step (metres), so the arm can follow.
        action_noise: std of Gaussian noise on the 6 motion dims of executed actions (MimicGen's 0.05).
        lift_frac: the grasp segment ends at this fraction of the source's lift height.
        settle_steps: steps holding the last pose after the plan, for the object to come to rest.
    """

    source: Path
    out: Path
    n: int
    seed: int = 0
    guarantee: bool = False
    max_attempts: int | None = None
    selection: str = "nearest"
    nn_k: int = 3
    interp_steps: int = 5
    max_step_m: float = 0.02
    action_noise: float = 0.05
    lift_frac: float = 0.9
    settle_steps: int = 25
    repo_id: str = "local/indgen_mimicgen"

    def __post_init__(self) -> None:
        object.__setattr__(self, "source", Path(self.source))
        object.__setattr__(self, "out", Path(self.out))
        if self.n < 1:
            raise ConfigError(f"--n must be >= 1, got {self.n}")
        if self.max_attempts is not None and self.max_attempts < self.n:
            raise ConfigError(f"--max-attempts ({self.max_attempts}) must be >= --n ({self.n})")
        if self.selection not in SELECTIONS:
            raise ConfigError(f"--selection must be one of {', '.join(SELECTIONS)}, got {self.selection!r}")
        if self.nn_k < 1 or self.interp_steps < 1 or self.settle_steps < 0 or self.max_step_m <= 0:
            raise ConfigError("nn_k and interp_steps must be >= 1, settle_steps >= 0 and max_step_m > 0")
        if self.action_noise < 0 or not 0 < self.lift_frac <= 1:
            raise ConfigError(f"action_noise must be >= 0 and lift_frac in (0, 1]; got {self.action_noise}, "
                              f"{self.lift_frac}")  # fmt: skip
        if not (self.source / "meta" / "info.json").is_file():
            raise ConfigError(f"--source {self.source} is not a LeRobotDataset (no meta/info.json); point it at "
                              "the output of `indgen demos`")  # fmt: skip
        if self.out.exists() and (not self.out.is_dir() or any(self.out.iterdir())):
            raise ConfigError(f"--out {self.out} already exists and is not empty; choose a new directory")
        if self.out.resolve() == self.source.resolve():
            raise ConfigError("--out must differ from --source")


def _n_interp(start: np.ndarray, end: np.ndarray, cfg: MimicGenConfig) -> int:
    dist = float(np.linalg.norm(end[:3, 3] - start[:3, 3]))
    angle = float(np.linalg.norm(Rotation.from_matrix(end[:3, :3] @ start[:3, :3].T).as_rotvec()))
    return max(cfg.interp_steps, math.ceil(dist / cfg.max_step_m), math.ceil(angle / 0.2))


def generate_episode(env, demos: list[SourceDemo], seed: int, rng: np.random.Generator, cfg: MimicGenConfig,
                     used: list[int]) -> Iterator[tuple[Observation, np.ndarray, dict, dict]]:  # fmt: skip
    """Yield (observation, executed action, info, object poses) of one generated episode from T0 seed ``seed``.

    The source demo chosen for each subtask is appended to ``used``.
    """
    obs, _ = env.reset(seed=seed)
    priv = env.privileged_state()
    last, grip = pose_from_state(obs.state), float(demos[0].gripper[0])
    for k, (_, ref) in enumerate(SUBTASKS):
        new_ref = pose_from_pq(
            object_poses(priv)[ref]
        )  # the reference object's pose now, at the segment start
        demo = select_source(demos, k, new_ref, rng, cfg.selection, cfg.nn_k)
        used.append(demo.index)
        targets, grips, src_ref = demo.segment(k)
        seg = transform_segment(targets, src_ref, new_ref)
        path = interpolate_poses(last, seg[0], _n_interp(last, seg[0], cfg))
        plan = [(p, grip) for p in path] + list(zip(seg, grips, strict=True))
        for target, g in plan:
            a = pose_to_action(target, pose_from_state(obs.state), g)
            if cfg.action_noise > 0:
                a[:6] = np.clip(a[:6] + rng.normal(0.0, cfg.action_noise, 6), -1.0, 1.0)
            a = a.astype(np.float32)
            next_obs, _, terminated, truncated, info = env.step(a)
            yield obs, a, info, object_poses(priv)
            obs, priv = next_obs, env.privileged_state()
            if terminated or truncated:
                return
        last, grip = seg[-1], float(grips[-1])
    for _ in range(cfg.settle_steps):
        a = pose_to_action(last, pose_from_state(obs.state), grip).astype(np.float32)
        next_obs, _, terminated, truncated, info = env.step(a)
        yield obs, a, info, object_poses(priv)
        obs, priv = next_obs, env.privileged_state()
        if terminated or truncated:
            return


def _new_seed(
    cfg: MimicGenConfig, scene: str, task: str, attempt: int, taken: set[int], level: tuple = ()
) -> int:
    """A fresh seed for one attempt, never one of the source's seeds nor one ``evaluate`` uses (``taken``);
    ``level``: (axis, level) of a level other than T0, which draws its own seeds."""
    bump = 0
    while (s := episode_seed(cfg.seed, "mimicgen", scene, task, *level, attempt, bump)) in taken:
        bump += 1
    return s


def _level_env(scene: str, task: str, level: int, where: dict, cams: tuple[str, ...], size: tuple[int, int]):
    """The env of one source level: T0 as ``indgen demos`` builds it, or level ``level`` of the recorded axis."""
    import scenes

    if where.get("axis") is None:
        return scenes.make_env(scene, task=task, level=0, cameras=cams, image_size=size)
    return scenes.make_env(scene, task=task, axis=where["axis"], level=level, step=where.get("step"),
                           preset=where.get("axes_preset"), cameras=cams, image_size=size)  # fmt: skip


def generate(cfg: MimicGenConfig, progress=None) -> dict:
    """Generate episodes from ``cfg.source`` into ``cfg.out``; return (and write) the generation stats."""
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    t0 = time.perf_counter()
    info, demos, skipped = load_sources(cfg.source, cfg.lift_frac)
    if not demos:
        raise ConfigError(f"--source {cfg.source} has no demo with one clean grasp and release to split; "
                          "record more with `indgen demos`")  # fmt: skip
    feats = info["features"]
    cams = tuple(k.removeprefix("observation.images.") for k in feats if k.startswith("observation.images."))
    shape = feats[f"observation.images.{cams[0]}"]["shape"] if cams else [96, 96, 3]
    size = (int(shape[0]), int(shape[1]))
    use_videos = any(feats[f"observation.images.{c}"]["dtype"] == "video" for c in cams)
    objects = ENV_STATE in feats  # the source records object poses: so do the generated episodes
    # the source records its levels per frame: so does the output
    levels = all(k in feats for k in LEVEL_FEATURES)
    by_cell: dict[tuple, list[SourceDemo]] = {}
    for d in demos:
        by_cell.setdefault(d.cell, []).append(d)
    taken = {d.seed for d in demos} | {int(r["seed"]) for r in read_episode_sidecar(cfg.source)}
    if cfg.out.exists():
        cfg.out.rmdir()
    cfg.out.parent.mkdir(parents=True, exist_ok=True)
    ds = LeRobotDataset.create(repo_id=cfg.repo_id, fps=int(info.get("fps", FPS)), root=cfg.out,
                               features=features(cams, size, use_videos, objects, levels),
                               robot_type=info.get("robot_type", "panda"), use_videos=use_videos,
                               video_backend="pyav")  # fmt: skip
    stats = {"source": str(cfg.source), "out": str(cfg.out), "seed": cfg.seed, "attempts": 0, "successes": 0,
             "frames": 0, "source_demos": len(demos), "source_skipped": skipped, "tasks": {}}  # fmt: skip
    writer = _Writer(ds, cfg, cams, objects, levels)
    try:
        for pool in by_cell.values():
            # the scene's own episode budget: a generated episode must succeed within the evaluation horizon
            src = pool[0]
            env = _level_env(src.scene, src.task, src.level, dict(src.where), cams, size)
            try:
                label, ok, attempt, frames = writer.cell(env, pool, taken, progress)
            finally:
                env.close()
            stats["tasks"][label] = {"attempts": attempt, "successes": ok, "rate": ok / max(attempt, 1)}
            stats["attempts"] += attempt
            stats["successes"] += ok
            stats["frames"] += frames
    except BaseException:
        ds.finalize()
        raise
    ds.finalize()
    stats["rate"] = stats["successes"] / max(stats["attempts"], 1)
    stats["wall_s"] = round(time.perf_counter() - t0, 2)
    stats["config"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()}
    (cfg.out / STATS_FILE).write_text(json.dumps(stats, indent=2) + "\n")
    return stats


@dataclass
class _Writer:
    """Generates one source level's episodes and writes the successful ones (frames, level columns, sidecar)."""

    ds: Any
    cfg: MimicGenConfig
    cams: tuple[str, ...]
    objects: bool
    levels: bool

    def cell(self, env, pool: list[SourceDemo], taken: set[int], progress) -> tuple[str, int, int, int]:
        """Attempt one level of one task from its sources ``pool``; return (label, successes, attempts, frames)."""
        cfg, src = self.cfg, pool[0]
        where = dict(src.where)
        at = () if src.level == 0 else (where.get("axis"), src.level)  # T0 keeps the seeds it always had
        label = src.task if where.get("axis") is None else f"{src.task} {where['axis']} level {src.level}"
        avoid = taken | held_out_seeds(src.scene, src.task, also=(cfg.seed,))
        per_cell = (cfg.max_attempts or 5 * cfg.n) if cfg.guarantee else cfg.n
        ok = attempt = total = 0
        while attempt < per_cell and not (cfg.guarantee and ok >= cfg.n):
            seed = _new_seed(cfg, src.scene, src.task, attempt, avoid, at)
            rng = np.random.default_rng(
                episode_seed(cfg.seed, "mimicgen-rng", src.scene, src.task, *at, attempt)
            )
            attempt += 1
            used: list[int] = []
            frames, success = [], False
            for obs, a, step_info, poses in generate_episode(env, pool, seed, rng, cfg, used):
                frames.append((obs, a, poses))
                success = bool(step_info.get("success", False))
            if success:
                self._save(src, seed, frames, used)
                ok += 1
                total += len(frames)
            if progress is not None:
                progress(label, ok, attempt, per_cell)
        return label, ok, attempt, total

    def _save(self, src: SourceDemo, seed: int, frames: list, used: list[int]) -> None:
        where = dict(src.where)
        per_level = level_columns(src.level, where.get("axis"), src.param) if self.levels else {}
        save_episode(self.ds, frames, self.cams, self.objects, per_level)
        record = {"episode_index": self.ds.num_episodes - 1, "regime": "mimicgen", "scene": src.scene,
                  "task": src.task, "seed": seed, "level": src.level}  # fmt: skip
        if where:
            record.update(where, param=src.param)
        record.update(
            frames=len(frames), source_episodes=used, object_poses=rounded_poses([p for _, _, p in frames])
        )
        append_episode_sidecar(self.cfg.out, record)


def mimicgen_main(args: argparse.Namespace) -> int:
    """CLI handler for ``indgen mimicgen`` (its own parser over the passthrough arguments)."""
    from indgen_vla.cli import IndgenParser

    p = IndgenParser(
        prog="indgen mimicgen",
        description="MimicGen-style augmentation of `indgen demos` demonstrations, level by level (LeRobotDataset)",
    )
    p.add_argument("--source", required=True, help="dataset written by `indgen demos`")
    p.add_argument(
        "--n",
        type=int,
        required=True,
        help="generation attempts per task and level (successes with --guarantee)",
    )
    p.add_argument("--out", required=True, help="new dataset root directory (must not exist)")
    p.add_argument("--seed", type=int, default=0, help="seed of the new initial states and the source choice")
    p.add_argument("--guarantee", action="store_true", help="attempt until --n successes per task and level")
    p.add_argument(
        "--max-attempts", type=int, default=None, help="attempt cap per task and level with --guarantee (5 n)"
    )
    p.add_argument("--selection", choices=SELECTIONS, default="nearest", help="per-subtask source choice")
    p.add_argument("--action-noise", type=float, default=0.05, help="std of motion noise on executed actions")
    p.add_argument(
        "--repo-id", default="local/indgen_mimicgen", help="LeRobotDataset repo id stored in the dataset"
    )
    a = p.parse_args(args.rest)
    cfg = MimicGenConfig(source=a.source, out=a.out, n=a.n, seed=a.seed, guarantee=a.guarantee,
                         max_attempts=a.max_attempts, selection=a.selection, action_noise=a.action_noise,
                         repo_id=a.repo_id)  # fmt: skip
    quiet_datasets()
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    console = Console(stderr=True)
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    try:
        with Progress(*columns, console=console, transient=True) as bar:
            bars: dict[str, object] = {}

            def progress(task, ok, attempt, total):
                if task not in bars:
                    bars[task] = bar.add_task(task, total=total)
                bar.update(bars[task], completed=attempt, description=f"{task}: {ok} ok")

            stats = generate(cfg, progress)
    except KeyboardInterrupt:
        shutil.rmtree(cfg.out, ignore_errors=True)
        raise
    console.print(f"generated {stats['successes']}/{stats['attempts']} attempts succeeded "
                  f"({100 * stats['rate']:.1f} %) → {cfg.out}")  # fmt: skip
    return 0 if stats["successes"] else 1
