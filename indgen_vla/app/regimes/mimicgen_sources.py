"""The sources of ``indgen mimicgen``: source demonstrations split into object-centric subtask segments (grasp
relative to the pick object, place relative to the receptacle) and MimicGen's per-subtask source choice."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from indgen_vla.app.regimes.demos import EPISODES_SIDECAR, read_episode_sidecar
from indgen_vla.app.regimes.se3 import pose_from_pq, target_poses
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import ACTION_DIM, STATE_DIM

SUBTASKS = (("grasp", "pick"), ("place", "goal"))  # (segment name, reference object) in execution order
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


def source_scenes(root: Path) -> list[str]:
    """The scenes a source dataset's episodes were recorded in (its sidecar), which generation builds."""
    return sorted({r["scene"] for r in read_episode_sidecar(root)})
