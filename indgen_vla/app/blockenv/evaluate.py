"""Roll learners (and the oracle) out on BlockEnv levels, batched over episodes."""

from __future__ import annotations

import numpy as np

from indgen_vla.app.blockenv.data import make_demos
from indgen_vla.app.blockenv.env import BlockEnv, BlockEnvConfig, oracle_actions, sample_grids
from indgen_vla.app.blockenv.fit import _tensors, adapt


def initial_grids(level: int, episodes: int, cfg: BlockEnvConfig, seed: int) -> np.ndarray:
    """Episode i of level k always starts from the same grid (seeded by (seed, k, i) alone)."""
    return np.concatenate([sample_grids(np.array([level]), cfg, np.random.default_rng([seed, level, i]))
                           for i in range(episodes)])  # fmt: skip


def decode(out: dict, obs_last, model) -> np.ndarray:
    """Greedy (r, c, θ) from the last time step's logits (after the model's inference gate, if it has one)."""
    import torch

    if "joint" in out:
        if hasattr(model, "gate"):
            logits = model.gate({k: v[:, -1] for k, v in out.items()}, obs_last)
        else:
            logits = out["joint"][:, -1]
        g = logits.shape[-2]
        flat = logits.flatten(1).argmax(-1)
        return torch.stack([flat // 2 // g, flat // 2 % g, flat % 2], dim=-1).numpy()
    return torch.stack([out[k][:, -1].argmax(-1) for k in ("rows", "cols", "theta")], dim=-1).numpy()


def rollout(model, method: str, level: int, episodes: int, cfg: BlockEnvConfig, seed: int,
            params: dict | None = None) -> np.ndarray:  # fmt: skip
    """Success (episodes,) bool of ``model`` at ``level``; ``params`` are MAML's adapted weights."""
    import torch
    from torch.func import functional_call

    env = BlockEnv(cfg)
    env.reset(np.full(episodes, level), grids=initial_grids(level, episodes, cfg, seed))
    lv = torch.full((episodes,), level)
    history, prev = [], [np.zeros((episodes, 3), np.int64)]
    with torch.no_grad():
        while not env.done.all():
            history.append(env.grids.copy())
            use_hist = getattr(model, "history", False)
            obs = torch.as_tensor(np.stack(history if use_hist else history[-1:], 1), dtype=torch.long)
            pa = torch.as_tensor(np.stack(prev[-obs.shape[1] :], 1))
            out = functional_call(model, params, (obs, lv, pa)) if params else model(obs, lv, pa)
            a = decode(out, obs[:, -1], model)
            env.step(a)
            prev.append(a)
    return env.success.copy()


def oracle_rollout(level: int, episodes: int, cfg: BlockEnvConfig, seed: int) -> np.ndarray:
    env = BlockEnv(cfg)
    env.reset(np.full(episodes, level), grids=initial_grids(level, episodes, cfg, seed))
    arms = np.random.default_rng([seed, level, 99]).integers(0, 2, episodes)
    while not env.done.all():
        env.step(oracle_actions(env.grids, arms))
    return env.success.copy()


def evaluate_model(model, method: str, levels, episodes: int, cfg: BlockEnvConfig, seed: int,
                   train_cfg=None) -> dict[int, tuple[int, int]]:  # fmt: skip
    """{level: (successes, n)}; MAML first adapts on a few oracle demos of the evaluated level."""
    out = {}
    for k in levels:
        params = None
        if method == "maml":
            support = make_demos([k], train_cfg.maml_support, cfg, seed=20_000 + seed + k)
            params = adapt(model, _tensors(*support.steps()), train_cfg.maml_inner_lr)
        s = rollout(model, method, k, episodes, cfg, seed, params)
        out[k] = (int(s.sum()), episodes)
    return out
