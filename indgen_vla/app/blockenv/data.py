"""Oracle demonstrations for behaviour cloning: padded episode tensors from levels 0..2."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from indgen_vla.app.blockenv.env import BlockEnv, BlockEnvConfig, legal_grasps, oracle_actions


@dataclass
class Demos:
    """Episodes as padded arrays: obs (N, T, G, G) int8, actions (N, T, 3), mask (N, T), levels (N,)."""

    obs: np.ndarray
    actions: np.ndarray
    mask: np.ndarray
    levels: np.ndarray

    def __len__(self) -> int:
        return len(self.levels)

    def steps(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flatten to single steps: (grids, actions, levels) of every valid time step."""
        idx = self.mask.astype(bool)
        lv = np.broadcast_to(self.levels[:, None], self.mask.shape)[idx]
        return self.obs[idx], self.actions[idx], lv

    def subset(self, keep: np.ndarray) -> Demos:
        return Demos(self.obs[keep], self.actions[keep], self.mask[keep], self.levels[keep])


def rollout_oracle(levels: np.ndarray, cfg: BlockEnvConfig, rng: np.random.Generator) -> Demos:
    """Run the oracle on each level once; record the observation before every grasp."""
    env = BlockEnv(cfg)
    env.reset(levels, rng)
    arms = rng.integers(0, 2, len(levels))
    t_max = int(levels.max()) + 1
    g = cfg.grid_size
    obs = np.zeros((len(levels), t_max, g, g), np.int8)
    acts = np.zeros((len(levels), t_max, 3), np.int64)
    mask = np.zeros((len(levels), t_max), np.float32)
    t = 0
    while not env.done.all():
        live = ~env.done
        a = oracle_actions(env.grids, arms)
        obs[live, t] = env.grids[live]
        acts[live, t] = a[live]
        mask[live, t] = 1
        env.step(a)
        t += 1
    return Demos(obs, acts, mask, np.asarray(levels))


def make_demos(train_levels: list[int], per_level: int, cfg: BlockEnvConfig, seed: int) -> Demos:
    """``per_level`` oracle episodes at each training level (the paper: L0–L2)."""
    rng = np.random.default_rng(seed)
    levels = np.repeat(np.asarray(train_levels), per_level)
    return rollout_oracle(levels, cfg, rng)


def legality_targets(grids: np.ndarray) -> np.ndarray:
    """Analytic per-cell, per-orientation legality (Ind's auxiliary head target)."""
    return legal_grasps(grids).astype(np.float32)
