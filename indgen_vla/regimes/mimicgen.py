"""``indgen mimicgen``: MimicGen-style augmentation of T0 demonstrations (Mandlekar et al., 2023).

Each source demonstration is split into object-centric subtask segments: the grasp (approach, close, lift)
relative to the pick object and the place (transport, lower, release) relative to the receptacle. For a fresh
T0 initial state every segment's end-effector target poses are moved rigidly with their reference object
(``T_new_obj @ inv(T_src_obj) @ T_eef``), joined by a linear + slerp interpolation from the current pose,
and driven with robosuite OSC_POSE delta actions; only episodes the scene's success predicate accepts are
kept. The output is a LeRobotDataset with exactly the features, fps, cameras and task strings of the source.
A source recorded at levels of an axis (``indgen demos --axis A --levels 0:2``) is augmented level by level:
each episode is generated at its sources' level, from sources of that level only. Every attempt is saved as it
ends (``staging``), so a killed run resumes after its last saved attempt when the same command is rerun.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from indgen_vla.errors import ConfigError
from indgen_vla.interface import Observation
from indgen_vla.records import atomic_write_json
from indgen_vla.regimes import quiet_datasets
from indgen_vla.regimes.demos import (
    ENV_STATE,
    FPS,
    LEVEL_FEATURES,
    append_episode_sidecar,
    features,
    level_columns,
    read_episode_sidecar,
    rounded_poses,
    save_episode,
)
from indgen_vla.regimes.mimicgen_sources import SUBTASKS, SourceDemo, load_sources, select_source
from indgen_vla.regimes.resume import (
    INPUTS,
    RESUME_DIR,
    RUN_FILE,
    check_same_run,
    dataset_size,
    out_state,
    start_run,
)
from indgen_vla.regimes.se3 import (
    interpolate_poses,
    pose_from_pq,
    pose_from_state,
    pose_to_action,
    transform_segment,
)
from indgen_vla.regimes.staging import FrameCapture, Stage
from indgen_vla.seeding import episode_seed, held_out_seeds
from scenes.poses import object_poses

SELECTIONS = ("nearest", "random")
STATS_FILE = "mimicgen_stats.json"
CLI_FLAGS = ("source", "n", "seed", "guarantee", "max_attempts", "selection", "action_noise", "repo_id")


# ---- configuration and execution ---------------------------------------------------------------------------
@dataclass(frozen=True)
class MimicGenConfig:
    """What ``indgen mimicgen`` generates and how.

    Attributes:
        source: a LeRobotDataset written by ``indgen demos`` (with its per-episode sidecar).
        out: the new dataset's root: new, empty, or an unfinished run of the same arguments to resume.
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


def generate(cfg: MimicGenConfig, progress=None, say=None) -> dict:
    """Generate episodes from ``cfg.source`` into ``cfg.out``; return (and write) the generation stats.

    Every attempt is saved as it ends (``staging``) and the dataset is written once all are in: an unfinished
    ``cfg.out`` made with the same arguments resumes after its last saved attempt (``say`` is told), a finished one
    is returned as it is, other arguments are refused in one line.
    """
    run = run_identity(cfg)
    state = out_state(cfg.out, STATS_FILE, "mimicgen")
    if state == "finished":
        return _finished(cfg, run, say)
    if state == "unfinished":
        saved = json.loads((cfg.out / RESUME_DIR / RUN_FILE).read_text())
        check_same_run(cfg.out, saved, run, "mimicgen", CLI_FLAGS, finished=False)
    info, demos, skipped = load_sources(cfg.source, cfg.lift_frac)
    if not demos:
        raise ConfigError(f"--source {cfg.source} has no demo with one clean grasp and release to split; "
                          "record more with `indgen demos`")  # fmt: skip
    layout = _Layout.of(info)
    by_cell: dict[tuple, list[SourceDemo]] = {}
    for d in demos:
        by_cell.setdefault(d.cell, []).append(d)
    taken = {d.seed for d in demos} | {int(r["seed"]) for r in read_episode_sidecar(cfg.source)}
    stage = Stage(start_run(cfg.out, run))
    prior, t0 = (stage.entries[-1]["wall_s"] if stage.entries else 0.0), time.perf_counter()
    if stage.entries and say is not None:
        kept = sum(e["success"] for e in stage.entries)
        say(f"mimicgen: resuming {cfg.out}: {len(stage.entries)} attempts already saved ({kept} kept)")
    writer = _Writer(stage, cfg, layout, lambda: round(prior + time.perf_counter() - t0, 2))
    for k, pool in enumerate(by_cell.values()):
        writer.cell(k, pool, taken, progress)

    def create(root: Path):
        from lerobot.datasets.lerobot_dataset import LeRobotDataset

        return LeRobotDataset.create(repo_id=cfg.repo_id, fps=int(info.get("fps", FPS)), root=root,
                                     features=features(layout.cams, layout.size, layout.use_videos,
                                                       layout.objects, layout.levels),
                                     robot_type=info.get("robot_type", "panda"), use_videos=layout.use_videos,
                                     video_backend="pyav")  # fmt: skip

    def sidecar(root: Path, index: int, record: dict) -> None:
        append_episode_sidecar(root, {"episode_index": index, **record["episode"]})

    stage.write_dataset(cfg.out, create, sidecar, kept=lambda e: e["success"])
    stats = _stats(cfg, stage.entries, len(demos), skipped, run)
    stats["wall_s"] = round(prior + time.perf_counter() - t0, 2)  # every session's, to its last saved attempt
    atomic_write_json(cfg.out / STATS_FILE, stats)  # written last: the mark of a finished dataset
    shutil.rmtree(cfg.out / RESUME_DIR)
    return stats


def run_identity(cfg: MimicGenConfig) -> dict:
    """What decides the generated dataset: the options (not ``out``) and the source's size."""
    config = {
        k: (str(v.resolve()) if isinstance(v, Path) else v) for k, v in asdict(cfg).items() if k != "out"
    }
    return {"config": config, INPUTS: {config["source"]: dataset_size(cfg.source)}}


def _finished(cfg: MimicGenConfig, run: dict, say) -> dict:
    """The stats of a finished ``cfg.out`` made with the same arguments (nothing is generated again)."""
    stats = json.loads((cfg.out / STATS_FILE).read_text())
    if "run" not in stats:
        raise ConfigError(f"mimicgen: --out {cfg.out} holds a dataset from before generation could resume; "
                          "choose a new directory")  # fmt: skip
    check_same_run(cfg.out, stats["run"], run, "mimicgen", CLI_FLAGS, finished=True)
    shutil.rmtree(cfg.out / RESUME_DIR, ignore_errors=True)  # a kill between the stats and this cleanup
    if say is not None:
        say(f"mimicgen: {cfg.out} is already complete ({stats['successes']} episodes); nothing to do")
    return stats


def _stats(cfg: MimicGenConfig, entries: list[dict], n_demos: int, skipped: int, run: dict) -> dict:
    """Generation stats from the saved attempts (the same whether or not the run was resumed)."""
    stats = {"source": str(cfg.source), "out": str(cfg.out), "seed": cfg.seed, "attempts": len(entries),
             "successes": sum(e["success"] for e in entries),
             "frames": sum(e["episode"]["frames"] for e in entries if e["success"]),
             "source_demos": n_demos, "source_skipped": skipped, "tasks": {}}  # fmt: skip
    for e in entries:
        t = stats["tasks"].setdefault(e["label"], {"attempts": 0, "successes": 0})
        t["attempts"] += 1
        t["successes"] += e["success"]
    for t in stats["tasks"].values():
        t["rate"] = t["successes"] / max(t["attempts"], 1)
    stats["rate"] = stats["successes"] / max(stats["attempts"], 1)
    stats["config"] = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()}
    stats["run"] = run
    return stats


@dataclass(frozen=True)
class _Layout:
    """What the generated episodes record, as the source does: cameras, image size, videos, poses, levels."""

    cams: tuple[str, ...]
    size: tuple[int, int]
    use_videos: bool
    objects: bool
    levels: bool

    @classmethod
    def of(cls, info: dict) -> _Layout:
        feats = info["features"]
        cams = tuple(
            k.removeprefix("observation.images.") for k in feats if k.startswith("observation.images.")
        )
        shape = feats[f"observation.images.{cams[0]}"]["shape"] if cams else [96, 96, 3]
        use_videos = any(feats[f"observation.images.{c}"]["dtype"] == "video" for c in cams)
        # the source records object poses / its levels per frame: so do the generated episodes
        return cls(cams, (int(shape[0]), int(shape[1])), use_videos, ENV_STATE in feats,
                   all(k in feats for k in LEVEL_FEATURES))  # fmt: skip


@dataclass
class _Writer:
    """Generates one source level's episodes and stages every attempt (a kept one with its frames and sidecar)."""

    stage: Stage
    cfg: MimicGenConfig
    layout: _Layout
    clock: Callable[[], float]  # seconds generating, over every session

    def cell(self, k: int, pool: list[SourceDemo], taken: set[int], progress) -> None:
        """Attempt level/task ``k`` from its sources ``pool``, after the attempts already saved for it."""
        cfg, src = self.cfg, pool[0]
        where = dict(src.where)
        at = () if src.level == 0 else (where.get("axis"), src.level)  # T0 keeps the seeds it always had
        label = src.task if where.get("axis") is None else f"{src.task} {where['axis']} level {src.level}"
        avoid = taken | held_out_seeds(src.scene, src.task, also=(cfg.seed,))
        per_cell = (cfg.max_attempts or 5 * cfg.n) if cfg.guarantee else cfg.n
        done = [e for e in self.stage.entries if e["cell"] == k]
        attempt, ok = len(done), sum(e["success"] for e in done)
        if progress is not None and attempt:
            progress(label, ok, attempt, per_cell)
        env = None
        try:
            while attempt < per_cell and not (cfg.guarantee and ok >= cfg.n):
                if env is None:  # the scene's own episode budget: a generated episode must succeed in time
                    env = _level_env(
                        src.scene, src.task, src.level, where, self.layout.cams, self.layout.size
                    )
                ok += self._attempt(env, k, label, pool, attempt, _new_seed(cfg, src.scene, src.task, attempt,
                                                                             avoid, at), at)  # fmt: skip
                attempt += 1
                if progress is not None:
                    progress(label, ok, attempt, per_cell)
        finally:
            if env is not None:
                env.close()

    def _attempt(
        self, env, k: int, label: str, pool: list[SourceDemo], attempt: int, seed: int, at: tuple
    ) -> bool:
        """Run one attempt from T0 seed ``seed`` and save it; True when it succeeded (and was kept)."""
        src = pool[0]
        rng = np.random.default_rng(
            episode_seed(self.cfg.seed, "mimicgen-rng", src.scene, src.task, *at, attempt)
        )
        used: list[int] = []
        frames, success = [], False
        for obs, a, step_info, poses in generate_episode(env, pool, seed, rng, self.cfg, used):
            frames.append((obs, a, poses))
            success = bool(step_info.get("success", False))
        entry = {"cell": k, "label": label, "attempt": attempt, "seed": seed, "success": success}
        if not success:
            self.stage.add({**entry, "wall_s": self.clock()})
            return False
        where = dict(src.where)
        per_level = level_columns(src.level, where.get("axis"), src.param) if self.layout.levels else {}
        capture = FrameCapture()
        save_episode(capture, frames, self.layout.cams, self.layout.objects, per_level)
        record = {
            "regime": "mimicgen",
            "scene": src.scene,
            "task": src.task,
            "seed": seed,
            "level": src.level,
        }
        if where:
            record.update(where, param=src.param)
        record.update(
            frames=len(frames), source_episodes=used, object_poses=rounded_poses([p for _, _, p in frames])
        )
        self.stage.add({**entry, "episode": record, "wall_s": self.clock()}, capture.frames)
        return True


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
    p.add_argument("--out", required=True,
                   help="dataset root: new, or an unfinished one to resume with the same arguments")  # fmt: skip
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
    done = (cfg.out / STATS_FILE).is_file()
    with Progress(*columns, console=console, transient=True) as bar:
        bars: dict[str, object] = {}

        def progress(task, ok, attempt, total):
            if task not in bars:
                bars[task] = bar.add_task(task, total=total)
            bar.update(bars[task], completed=attempt, description=f"{task}: {ok} ok")

        stats = generate(cfg, progress, say=console.print)
    if done:
        return 0
    console.print(f"generated {stats['successes']}/{stats['attempts']} attempts succeeded "
                  f"({100 * stats['rate']:.1f} %) → {cfg.out}")  # fmt: skip
    return 0 if stats["successes"] else 1
