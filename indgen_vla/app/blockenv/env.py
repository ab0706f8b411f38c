"""BlockEnv (paper appendix A): a vectorised numpy grid world whose levels follow an inductive rule.

Level k: the goal plus two chains of k distractors grown from it; a grasp needs both neighbours along
its approach axis free, so the chains must be peeled from their tips before the goal is graspable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import ConfigError

EMPTY, DISTRACTOR, GOAL = 0, 1, 2
TOP_BOTTOM, LEFT_RIGHT = 0, 1  # θ: approach axis of the grasp


def chain_offsets(k: int) -> tuple[np.ndarray, np.ndarray]:
    """Cell offsets (row, col) from the goal of the forward and flipped chains at level k.

    Forward block i is one column left of block i-1 when i is odd, one row down when i is even; the
    flipped chain is its reflection in the diagonal through the goal (row and column swapped).
    """
    fwd = np.zeros((k, 2), dtype=np.int64)
    r = c = 0
    for i in range(1, k + 1):
        if i % 2:
            c -= 1
        else:
            r += 1
        fwd[i - 1] = (r, c)
    return fwd, fwd[:, ::-1].copy()


def footprint(k: int) -> tuple[int, int, int, int]:
    """(min_row, max_row, min_col, max_col) offsets of the level-k structure around the goal."""
    fwd, flip = chain_offsets(k)
    cells = np.vstack([np.zeros((1, 2), np.int64), fwd, flip])
    return int(cells[:, 0].min()), int(cells[:, 0].max()), int(cells[:, 1].min()), int(cells[:, 1].max())


def legal_grasps(grids: np.ndarray) -> np.ndarray:
    """(..., G, G, 2) bool: the cell is occupied and both neighbours along the approach axis are free.

    Off-grid neighbours count as free.
    """
    occ = grids != EMPTY
    pad = np.pad(occ, [(0, 0)] * (occ.ndim - 2) + [(1, 1), (1, 1)], constant_values=False)
    up, down = pad[..., :-2, 1:-1], pad[..., 2:, 1:-1]
    left, right = pad[..., 1:-1, :-2], pad[..., 1:-1, 2:]
    return np.stack([occ & ~up & ~down, occ & ~left & ~right], axis=-1)


@dataclass(frozen=True)
class BlockEnvConfig:
    """Grid size, step budget and strictness of the toy benchmark.

    Attributes:
        grid_size: G of the G×G grid; every evaluated level must fit ((k+1)×(k+1) cells).
        budget_factor: episodes fail after budget_factor·(k+1) grasps (the optimum is k+1).
        strict: a blocked or empty grasp ends the episode in failure instead of wasting a step.
    """

    grid_size: int = 12
    budget_factor: int = 2
    strict: bool = False

    def __post_init__(self) -> None:
        if self.grid_size < 1:
            raise ConfigError(f"grid_size must be >= 1, got {self.grid_size}")
        if self.budget_factor < 1:
            raise ConfigError(f"budget_factor must be >= 1, got {self.budget_factor}")

    @property
    def max_level(self) -> int:
        return self.grid_size - 1

    def check_level(self, k: int) -> None:
        if k < 0:
            raise ConfigError(f"BlockEnv levels are >= 0, got {k}")
        if k > self.max_level:
            raise ConfigError(
                f"level {k} needs a {k + 1}x{k + 1} footprint but the grid is {self.grid_size}x{self.grid_size}; "
                f"pass --grid-size {k + 1} or more"
            )


def sample_grids(levels: np.ndarray, cfg: BlockEnvConfig, rng: np.random.Generator) -> np.ndarray:
    """Initial grids for a batch of levels, each structure translated uniformly where it fits."""
    levels = np.asarray(levels, dtype=np.int64)
    for k in np.unique(levels):
        cfg.check_level(int(k))
    g = cfg.grid_size
    grids = np.zeros((len(levels), g, g), dtype=np.int8)
    for i, k in enumerate(levels):
        r0, r1, c0, c1 = footprint(int(k))
        gr = rng.integers(-r0, g - r1)
        gc = rng.integers(-c0, g - c1)
        fwd, flip = chain_offsets(int(k))
        cells = np.vstack([fwd, flip]) + (gr, gc)
        grids[i, cells[:, 0], cells[:, 1]] = DISTRACTOR
        grids[i, gr, gc] = GOAL
    return grids


class BlockEnv:
    """A batch of BlockEnv episodes stepped together with numpy."""

    def __init__(self, cfg: BlockEnvConfig | None = None):
        self.cfg = cfg or BlockEnvConfig()

    def reset(
        self, levels, rng: np.random.Generator | None = None, grids: np.ndarray | None = None
    ) -> np.ndarray:
        """Start one episode per level, from ``grids`` when given (fixed initial states), else sampled with ``rng``."""
        self.levels = np.asarray(levels, dtype=np.int64)
        if grids is None:
            if rng is None:
                raise ValueError("BlockEnv.reset needs rng or grids")
            grids = sample_grids(self.levels, self.cfg, rng)
        assert grids.shape == (len(self.levels), self.cfg.grid_size, self.cfg.grid_size)
        self.grids = np.array(grids, copy=True)
        self.initial = self.grids.copy()
        n = len(self.levels)
        self.steps = np.zeros(n, np.int64)
        self.budget = self.cfg.budget_factor * (self.levels + 1)
        self.success = np.zeros(n, bool)
        self.done = np.zeros(n, bool)
        return self.grids.copy()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Apply (B, 3) actions (r, c, θ) to the episodes still running; return (grids, success, done)."""
        a = np.asarray(actions, dtype=np.int64)
        g = self.cfg.grid_size
        live = ~self.done
        r, c, th = a[:, 0], a[:, 1], a[:, 2]
        inside = (r >= 0) & (r < g) & (c >= 0) & (c < g) & ((th == 0) | (th == 1))
        idx = np.nonzero(live & inside)[0]
        legal = np.zeros(len(a), bool)
        if len(idx):
            legal[idx] = legal_grasps(self.grids[idx])[np.arange(len(idx)), r[idx], c[idx], th[idx]]
        cell = np.where(
            inside, self.grids[np.arange(len(a)), np.clip(r, 0, g - 1), np.clip(c, 0, g - 1)], EMPTY
        )
        took_goal = live & legal & (cell == GOAL)
        took_block = live & legal & (cell == DISTRACTOR)
        self.grids[np.nonzero(took_block)[0], r[took_block], c[took_block]] = EMPTY
        self.steps += live
        self.success |= took_goal
        failed = live & ~legal & self.cfg.strict
        self.done |= took_goal | failed | (self.steps >= self.budget)
        return self.grids.copy(), self.success.copy(), self.done.copy()


def oracle_actions(grids: np.ndarray, arms: np.ndarray) -> np.ndarray:
    """The inductive heuristic: peel the chosen arm from its tip inwards, then grasp the exposed goal.

    Args:
        grids: (B, G, G) current grids.
        arms: (B,) 0 = forward chain, 1 = flipped chain (drawn uniformly once per episode).
    """
    legal = legal_grasps(grids)
    out = np.zeros((len(grids), 3), np.int64)
    for i, grid in enumerate(grids):
        goal = np.argwhere(grid == GOAL)[0]
        ok = np.argwhere(legal[i, goal[0], goal[1]])
        if len(ok):
            out[i] = (goal[0], goal[1], ok[0, 0])
            continue
        fwd, flip = chain_offsets(grid.shape[0])
        chain = (fwd if arms[i] == 0 else flip) + goal
        for cell in chain[::-1]:  # tip-most remaining block of the arm
            rr, cc = cell
            if 0 <= rr < grid.shape[0] and 0 <= cc < grid.shape[1] and grid[rr, cc] == DISTRACTOR:
                th = np.argwhere(legal[i, rr, cc])
                out[i] = (rr, cc, th[0, 0] if len(th) else 0)
                break
    return out
