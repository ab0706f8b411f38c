"""``indgen mimicgen``: MimicGen-style augmentation of T0 demonstrations (Mandlekar et al., 2023).

Each source demonstration is split into object-centric subtask segments: the grasp (approach, close, lift)
relative to the pick object and the place (transport, lower, release) relative to the receptacle. For a fresh
T0 initial state every segment's end-effector target poses are moved rigidly with their reference object
(``T_new_obj @ inv(T_src_obj) @ T_eef``), joined by a linear + slerp interpolation from the current pose,
and driven with robosuite OSC_POSE delta actions; only episodes the scene's success predicate accepts are
kept. The output is a LeRobotDataset with exactly the features, fps, cameras and task strings of the source.
A source recorded at levels of an axis (``indgen demos --axis A --levels 0:2``) is augmented level by level:
each episode is generated at its sources' level, from sources of that level only. Every kept episode is saved as
it ends (``journal``, as ``indgen demos`` does), so a killed run resumes after its last saved episode when the same
command is rerun.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from indgen_vla.app.config_fields import check_types, option
from indgen_vla.app.regimes.demos import (
    ENV_STATE,
    FPS,
    LEVEL_FEATURES,
    features,
    level_columns,
    read_episode_sidecar,
    rounded_poses,
    save_episode,
)
from indgen_vla.app.regimes.journal import JournaledDataset, drop_journal, read_record
from indgen_vla.app.regimes.mimicgen_sources import SUBTASKS, SourceDemo, load_sources, select_source
from indgen_vla.app.regimes.resume import INPUTS, check_same_run, dataset_size, out_state
from indgen_vla.app.regimes.se3 import (
    interpolate_poses,
    pose_from_pq,
    pose_from_state,
    pose_to_action,
    transform_segment,
)
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import Observation
from indgen_vla.core.protocol.seeding import episode_seed, held_out_seeds
from indgen_vla.core.runs.records import atomic_write_json
from scenes.family import Scene
from scenes.planning import resolve_scene_plan, scene_levels
from scenes.poses import object_poses

SELECTIONS = ("nearest", "random")
STATS_FILE = "mimicgen_stats.json"  # written last: the mark of a finished dataset
RECORD = (
    "meta/indgen_mimicgen.json"  # the run's arguments, its generation time so far and whether it is complete
)
CLI_FLAGS = ("source", "n", "seed", "guarantee", "max_attempts", "selection", "action_noise", "repo_id")
FLAGS = ("source", "n", "out", *CLI_FLAGS[2:])  # the flags in --help's order


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

    source: Path = option(help="dataset written by `indgen demos`", required=True)
    out: Path = option(help="dataset root: new, or an unfinished one to resume with the same arguments",
                       required=True)  # fmt: skip
    n: int = option(help="generation attempts per task and level (successes with --guarantee)", type=int,
                    required=True)  # fmt: skip
    seed: int = option(0, "seed of the new initial states and the source choice", type=int)
    guarantee: bool = option(False, "attempt until --n successes per task and level")
    max_attempts: int | None = option(None, "attempt cap per task and level with --guarantee (5 n)", type=int)
    selection: str = option("nearest", "per-subtask source choice", choices=SELECTIONS)
    nn_k: int = option(3)
    interp_steps: int = option(5)
    max_step_m: float = option(0.02)
    action_noise: float = option(0.05, "std of motion noise on executed actions", type=float)
    lift_frac: float = option(0.9)
    settle_steps: int = option(25)
    repo_id: str = option("local/indgen_mimicgen", "LeRobotDataset repo id stored in the dataset")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
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


def _level_env(
    scene: Scene, task: str, level: int, where: dict, cams: tuple[str, ...], size: tuple[int, int]
):
    """The env of one source level: T0 as ``indgen demos`` builds it, or level ``level`` of the recorded axis resolved
    as ``evaluate`` resolves it (``scenes.planning.resolve_scene_plan``), both through the builder."""
    if where.get("axis") is None:
        axis, level = scene.default_axis, 0
        builder = scene_levels(scene, (axis,), tasks=(task,))
    else:
        axis = where["axis"]
        plan = resolve_scene_plan(scene, task, (axis,), [level], where.get("step"), where.get("axes_preset"))
        builder = plan.builder
    builder.check_ready()
    return builder.make_env(task, axis, level, cameras=cams, image_size=size, max_steps=None)


def generate(cfg: MimicGenConfig, scenes: Mapping[str, Scene], progress=None, say=None) -> dict:
    """Generate episodes from ``cfg.source`` into ``cfg.out`` in ``scenes`` (by name: the source's, resolved by the
    caller); return (and write) the generation stats.

    Every kept episode is saved as it ends (``journal``): an unfinished ``cfg.out`` made with the same arguments
    resumes after its last saved episode (``say`` is told), a finished one is returned as it is, other arguments
    are refused in one line.
    """
    run = run_identity(cfg)
    state = out_state(cfg.out, STATS_FILE, "mimicgen", run_file=RECORD)
    if state == "finished":
        return _finished(cfg, run, say)
    recorded = read_record(cfg.out, RECORD) if state == "unfinished" else None
    if recorded is not None:
        check_same_run(cfg.out, recorded["run"], run, "mimicgen", CLI_FLAGS, finished=recorded["complete"])
        if recorded["complete"]:  # killed between marking the dataset complete and writing the stats
            atomic_write_json(cfg.out / STATS_FILE, recorded["stats"])
            return _finished(cfg, run, say)
    info, demos, skipped = load_sources(cfg.source, cfg.lift_frac)
    if not demos:
        raise ConfigError(f"--source {cfg.source} has no demo with one clean grasp and release to split; "
                          "record more with `indgen demos`")  # fmt: skip
    layout = _Layout.of(info)
    by_cell: dict[tuple, list[SourceDemo]] = {}
    for d in demos:
        by_cell.setdefault(d.cell, []).append(d)
    taken = {d.seed for d in demos} | {int(r["seed"]) for r in read_episode_sidecar(cfg.source)}
    dataset = _open(cfg, run, recorded, info, layout)
    if dataset.episodes and say is not None:
        say(f"mimicgen: resuming {cfg.out}: {dataset.episodes} episodes already saved")
    prior, t0 = (recorded or {}).get("wall_s", 0.0), time.perf_counter()
    writer = _Writer(dataset, cfg, layout, lambda: round(prior + time.perf_counter() - t0, 2), scenes)
    with dataset.recording():
        tally: dict[str, tuple[int, int]] = {}
        for pool in by_cell.values():
            tally.update(writer.cell(pool, taken, progress))
    stats = _stats(cfg, tally, read_episode_sidecar(cfg.out), len(demos), skipped, run)
    stats["wall_s"] = writer.clock()  # every session's
    dataset.complete({"stats": stats})
    atomic_write_json(cfg.out / STATS_FILE, stats)  # written last: the mark of a finished dataset
    return stats


def _open(
    cfg: MimicGenConfig, run: dict, recorded: dict | None, info: dict, layout: _Layout
) -> JournaledDataset:
    """A new dataset at ``cfg.out`` with the source's fps, robot and features, or the unfinished one reopened."""
    kw = {"repo_id": cfg.repo_id, "record": RECORD, "write": _EpisodeWriter(layout)}
    if recorded is not None:
        return JournaledDataset.reopen(cfg.out, **kw)
    feats = features(layout.cams, layout.size, layout.use_videos, layout.objects, layout.levels)
    lerobot = {"repo_id": cfg.repo_id, "fps": int(info.get("fps", FPS)), "robot_type": info.get("robot_type", "panda"),
               "features": feats, "use_videos": layout.use_videos, "video_backend": "pyav"}  # fmt: skip
    args = {"command": "indgen mimicgen", "run": run, "wall_s": 0.0}
    return JournaledDataset.create(cfg.out, args, lerobot, **kw)


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
    drop_journal(cfg.out)  # a kill between marking the dataset complete and this cleanup
    if say is not None:
        say(f"mimicgen: {cfg.out} is already complete ({stats['successes']} episodes); nothing to do")
    return stats


def _stats(cfg: MimicGenConfig, tally: dict[str, tuple[int, int]], episodes: list[dict], n_demos: int,
           skipped: int, run: dict) -> dict:  # fmt: skip
    """Generation stats from the (successes, attempts) per task and level and the saved episodes (the same whether
    or not the run was resumed)."""
    stats = {"source": str(cfg.source), "out": str(cfg.out), "seed": cfg.seed,
             "attempts": sum(a for _, a in tally.values()), "successes": len(episodes),
             "frames": sum(e["frames"] for e in episodes), "source_demos": n_demos, "source_skipped": skipped,
             "tasks": {label: {"attempts": a, "successes": ok, "rate": ok / max(a, 1)}
                       for label, (ok, a) in tally.items()}}  # fmt: skip
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


@dataclass(frozen=True)
class _EpisodeWriter:
    """Saves one kept episode (frames, per-frame level columns) into the dataset; returns its sidecar record."""

    layout: _Layout

    def __call__(self, ds, kept: dict) -> dict:
        frames, where = kept["frames"], kept["where"]
        per_level = (
            level_columns(kept["level"], where.get("axis"), kept["param"]) if self.layout.levels else {}
        )
        save_episode(ds, frames, self.layout.cams, self.layout.objects, per_level)
        record = {"episode_index": ds.num_episodes - 1, "regime": "mimicgen", "scene": kept["scene"],
                  "task": kept["task"], "seed": kept["seed"], "level": kept["level"]}  # fmt: skip
        if where:
            record.update(where, param=kept["param"])
        record.update(frames=len(frames), source_episodes=kept["used"],
                      object_poses=rounded_poses([p for _, _, p in frames]))  # fmt: skip
        return record


@dataclass
class _Writer:
    """Generates one source level's episodes and adds the kept ones to the dataset."""

    dataset: JournaledDataset
    cfg: MimicGenConfig
    layout: _Layout
    clock: Callable[[], float]  # seconds generating, over every session
    scenes: Mapping[str, Scene]  # the source's scenes by name

    def cell(self, pool: list[SourceDemo], taken: set[int], progress) -> dict[str, tuple[int, int]]:
        """Attempt the level/task of the sources ``pool``, after its last saved episode (the attempts between that
        one and the interruption are run again: each is a pure function of its seeds); return {label: (successes,
        attempts)}."""
        cfg, src = self.cfg, pool[0]
        where = dict(src.where)
        at = () if src.level == 0 else (where.get("axis"), src.level)  # T0 keeps the seeds it always had
        label = src.task if where.get("axis") is None else f"{src.task} {where['axis']} level {src.level}"
        avoid = taken | held_out_seeds(src.scene, src.task, also=(cfg.seed,))
        per_cell = (cfg.max_attempts or 5 * cfg.n) if cfg.guarantee else cfg.n
        seeds = [_new_seed(cfg, src.scene, src.task, a, avoid, at) for a in range(per_cell)]
        saved = [seeds.index(r["seed"]) for r in read_episode_sidecar(self.dataset.out)
                 if (r["scene"], r["task"], r["level"]) == (src.scene, src.task, src.level)]  # fmt: skip
        attempt, ok = (max(saved) + 1 if saved else 0), len(saved)
        if progress is not None and attempt:
            progress(label, ok, attempt, per_cell)
        env = None
        try:
            while attempt < per_cell and not (cfg.guarantee and ok >= cfg.n):
                if env is None:  # the scene's own episode budget: a generated episode must succeed in time
                    env = _level_env(
                        self.scenes[src.scene], src.task, src.level, where, self.layout.cams, self.layout.size
                    )
                ok += self._attempt(env, pool, attempt, seeds[attempt], at)
                attempt += 1
                if progress is not None:
                    progress(label, ok, attempt, per_cell)
        finally:
            if env is not None:
                env.close()
        return {label: (ok, attempt)}

    def _attempt(self, env, pool: list[SourceDemo], attempt: int, seed: int, at: tuple) -> bool:
        """Run one attempt from T0 seed ``seed``; when it succeeds, add it to the dataset and return True."""
        src = pool[0]
        rng = np.random.default_rng(
            episode_seed(self.cfg.seed, "mimicgen-rng", src.scene, src.task, *at, attempt)
        )
        used: list[int] = []
        frames, success = [], False
        for obs, a, step_info, poses in generate_episode(env, pool, seed, rng, self.cfg, used):
            frames.append((obs, a, poses))
            success = bool(step_info.get("success", False))
        if not success:
            return False
        self.dataset.add({"scene": src.scene, "task": src.task, "level": src.level, "where": dict(src.where),
                          "param": src.param, "seed": seed, "used": used, "frames": frames})  # fmt: skip
        path = self.dataset.out / RECORD  # the generation time so far, for the stats of a resumed run
        atomic_write_json(path, {**json.loads(path.read_text()), "wall_s": self.clock()})
        return True
