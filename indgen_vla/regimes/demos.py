"""``indgen demos``: record T0 demonstrations with the scripted oracle plus human-like noise and pauses,
written with lerobot's own ``LeRobotDataset`` API so lerobot's training code reads them unchanged."""

from __future__ import annotations

import argparse
import json
import shutil
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from indgen_vla.errors import ConfigError
from indgen_vla.interface import ACTION_DIM, OBJECT_DIM, OBJECT_NAMES, STATE_DIM, Observation
from indgen_vla.regimes import quiet_datasets
from indgen_vla.seeding import episode_seed
from scenes.poses import object_poses, object_vector
from scenes.privileged import privileged_of, with_privileged

FPS = 20  # robosuite control frequency used by every scene
STATE_NAMES = ["eef_x", "eef_y", "eef_z", "eef_ax", "eef_ay", "eef_az", "gripper_l", "gripper_r"]
ACTION_NAMES = ["dx", "dy", "dz", "drx", "dry", "drz", "gripper"]
# per-episode sidecar beside lerobot's own metadata: episode seed and per-frame object poses (MimicGen's source)
EPISODES_SIDECAR = "meta/indgen_episodes.jsonl"
ENV_STATE = "observation.environment_state"


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
    cameras: tuple[str, ...], image_size: tuple[int, int], use_videos: bool, objects: bool = False
) -> dict:
    """LeRobotDataset feature spec: one image per camera, 8-d state, 7-d action (+ object poses if asked)."""
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
    return feats


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


def record_demos(
    scene: str, out: Path, n: int, task: str | None = None, seed: int = 0, image_size: int = 96,
    cameras: tuple[str, ...] = ("agentview", "wrist"), noise: HumanNoise | None = None,
    repo_id: str = "local/indgen_demos", use_videos: bool = False, max_attempts_factor: int = 3, progress=None,
    objects: bool = False,
) -> dict:  # fmt: skip
    """Record ``n`` successful T0 episodes per task into a LeRobotDataset at ``out``; return stats.

    ``objects`` adds the pick and target poses per frame as ``observation.environment_state``.
    """
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    import scenes

    noise = noise or HumanNoise()
    if n < 1:
        raise ConfigError(f"--n must be >= 1, got {n}")
    if out.exists() and any(out.iterdir()):
        raise ConfigError(f"--out {out} already exists and is not empty; choose a new directory")
    tasks = scenes.select_tasks(scene, task)
    out.parent.mkdir(parents=True, exist_ok=True)
    if out.exists():
        out.rmdir()
    ds = LeRobotDataset.create(repo_id=repo_id, fps=FPS, features=features(cameras, (image_size, image_size), use_videos, objects),
                               root=out, robot_type="panda", use_videos=use_videos,
                               video_backend="pyav")  # fmt: skip
    stats = {"scene": scene, "tasks": tasks, "episodes": 0, "attempts": 0, "frames": 0}
    try:
        for t in tasks:
            env = scenes.make_env(
                scene, task=t, level=0, cameras=cameras, image_size=(image_size, image_size)
            )
            try:
                kept, attempt = 0, 0
                while kept < n:
                    if attempt >= max_attempts_factor * n:
                        raise ConfigError(f"only {kept}/{n} noisy oracle demos of {scene}/{t} succeeded in "
                                          f"{attempt} attempts; lower the noise")  # fmt: skip
                    ep_seed = episode_seed(seed, "demos", scene, t, attempt)
                    attempt += 1
                    frames, success = [], False
                    for obs, a, info in noisy_oracle_episode(env, ep_seed, noise):
                        frames.append((obs, a))
                        success = bool(info.get("success", False))
                    if not success:
                        continue  # keep only successful demonstrations, like a human operator's keepers
                    poses = [object_poses(privileged_of(obs, "indgen demos")) for obs, _ in frames]
                    for (obs, a), pose in zip(frames, poses, strict=True):
                        frame = {f"observation.images.{c}": obs.images[c] for c in cameras}
                        frame.update({"observation.state": obs.state.astype(np.float32), "action": a,
                                      "task": obs.instruction})  # fmt: skip
                        if objects:
                            frame[ENV_STATE] = object_vector(pose)
                        ds.add_frame(frame)
                    ds.save_episode()
                    append_episode_sidecar(out, {
                        "episode_index": ds.num_episodes - 1, "regime": "demos", "scene": scene, "task": t,
                        "seed": ep_seed, "level": 0, "frames": len(frames),
                        "object_poses": {k: [[round(v, 6) for v in p[k]] for p in poses] for k in poses[0]},
                    })  # fmt: skip
                    kept += 1
                    stats["frames"] += len(frames)
                    if progress is not None:
                        progress(t, kept, attempt)
                stats["episodes"] += kept
                stats["attempts"] += attempt
            finally:
                env.close()
    except BaseException:
        ds.finalize()
        raise
    ds.finalize()
    stats["success_rate"] = stats["episodes"] / max(stats["attempts"], 1)
    return stats


def demos_main(args: argparse.Namespace) -> int:
    """CLI handler for ``indgen demos`` (its own parser over the passthrough arguments)."""
    p = argparse.ArgumentParser(
        prog="indgen demos", description="record T0 demonstrations as a LeRobotDataset"
    )
    p.add_argument("--scene", required=True, help="built-in scene to record (see `indgen scenes`)")
    p.add_argument("--task", default=None, help="task name or 'all' (default: the scene's first task)")
    p.add_argument("--n", type=int, required=True, help="successful episodes per task")
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
    quiet_datasets()
    from rich.console import Console

    console = Console(stderr=True)

    def progress(task, kept, attempt):
        console.print(f"  {task}: {kept}/{a.n} kept ({attempt} attempts)", end="\r")

    out = Path(a.out)
    try:
        stats = record_demos(a.scene, out, a.n, a.task, a.seed, a.image_size,
                             noise=HumanNoise(sigma=a.noise, pause_prob=a.pause_prob), repo_id=a.repo_id,
                             use_videos=a.videos, progress=progress, cameras=cams, objects=a.objects)  # fmt: skip
    except KeyboardInterrupt:
        shutil.rmtree(out, ignore_errors=True)
        raise
    console.print(f"\nrecorded {stats['episodes']} episodes ({stats['frames']} frames) of {a.scene} "
                  f"{', '.join(stats['tasks'])} into {out}; oracle keep rate {100 * stats['success_rate']:.0f}%")  # fmt: skip
    return 0
