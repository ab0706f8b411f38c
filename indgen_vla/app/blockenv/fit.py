"""Behaviour cloning on oracle demonstrations from the training levels (L0–L2), per method."""

from __future__ import annotations

import copy
import json
import pickle
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from indgen_vla.app.blockenv.data import Demos, legality_targets, make_demos
from indgen_vla.app.blockenv.env import BlockEnvConfig
from indgen_vla.app.blockenv.methods import METHODS, check_options
from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.runs.records import atomic_write_bytes, atomic_write_text


@dataclass(frozen=True)
class FitConfig:
    """Hyper-parameters of one training run (one method, one seed)."""

    method: str
    seed: int = 0
    grid_size: int = 12
    train_levels: tuple[int, ...] = (0, 1, 2)
    demos_per_level: int = 300
    steps: int = 1200
    batch: int = 64
    lr: float = 1e-3
    hidden: int = 128
    maml_inner_lr: float = 0.05
    maml_support: int = 5
    schedule: str = "cosine"
    extra: dict = field(default_factory=dict)  # the method's variant options (methods.OPTIONS)

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise UnknownNameError("BlockEnv method", self.method, [*METHODS, "oracle"])
        if self.steps < 1 or self.batch < 1 or self.demos_per_level < 1 or not self.lr > 0:
            raise ConfigError("steps, batch and demos_per_level must be >= 1 and lr > 0")
        if self.schedule not in ("cosine", "constant"):
            raise ConfigError(f"schedule must be 'cosine' or 'constant', got {self.schedule!r}")
        BlockEnvConfig(grid_size=self.grid_size).check_level(max(self.train_levels))
        check_options(self.method, self.extra)


def _untrained(cfg: FitConfig):
    """The method's model, freshly initialised (torch loads here, not when a config is checked)."""
    from indgen_vla.app.blockenv.models import build_model  # lazy: start-up (torch, seconds)

    return build_model(cfg.method, cfg.grid_size, cfg.hidden, cfg.extra)


def _tensors(obs, actions, levels):
    import torch

    return torch.as_tensor(obs, dtype=torch.long), torch.as_tensor(actions), torch.as_tensor(levels)


def bc_loss(
    out: dict, actions, mask=None, legal=None, legal_weight: float = 1.0, legal_pos_weight: float = 1.0
):
    """Cross-entropy on the taken action (factored heads or joint logits) + Ind's legality BCE (mean over cells
    and θ, legal cells weighted ``legal_pos_weight``, the whole term ``legal_weight``)."""
    import torch
    from torch.nn import functional as F  # noqa: N812

    if "joint" in out:
        j = out["joint"]
        g = j.shape[-2]
        target = (actions[..., 0] * g + actions[..., 1]) * 2 + actions[..., 2]
        ce = F.cross_entropy(j.flatten(-3).flatten(0, -2), target.flatten(), reduction="none")
    else:
        ce = sum(F.cross_entropy(out[k].flatten(0, -2), actions[..., i].flatten(), reduction="none")
                 for i, k in enumerate(("rows", "cols", "theta")))  # fmt: skip
    m = torch.ones_like(ce) if mask is None else mask.flatten()
    loss = (ce * m).sum() / m.sum()
    if legal is not None and "legal" in out:
        pw = None if legal_pos_weight == 1.0 else torch.tensor(legal_pos_weight)
        bce = F.binary_cross_entropy_with_logits(out["legal"], legal, reduction="none", pos_weight=pw)
        loss = loss + legal_weight * (bce.mean((-3, -2, -1)).flatten() * m).sum() / m.sum()
    return loss


def _update(opt, loss):
    """One optimiser update on ``loss``; returns it detached for progress reports."""
    opt.zero_grad()
    loss.backward()
    opt.step()
    return loss.detach()


def _batches(n: int, batch: int, rng: np.random.Generator):
    while True:
        yield rng.choice(n, size=min(batch, n), replace=n < batch)


def train(cfg: FitConfig, progress: Callable[[int, float], None] | None = None):
    """Train one method; returns (model, demos) — demos are reused for MAML's support sets."""
    import torch

    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    env_cfg = BlockEnvConfig(grid_size=cfg.grid_size)
    demos = make_demos(list(cfg.train_levels), cfg.demos_per_level, env_cfg, seed=10_000 + cfg.seed)
    model = _untrained(cfg)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.lr)
    if cfg.schedule == "cosine":  # decays to 0 over cfg.steps optimiser updates, whichever path makes them
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=cfg.steps)
        opt.register_step_post_hook(lambda *_: sched.step())
    if cfg.method == "maml":
        _train_maml(model, opt, demos, cfg, rng, progress)
    elif cfg.method == "trm":
        _train_trm(model, opt, demos, cfg, rng, progress)
    elif getattr(model, "history", False):
        obs, act, mask, lv = (torch.as_tensor(demos.obs, dtype=torch.long), torch.as_tensor(demos.actions),
                              torch.as_tensor(demos.mask), torch.as_tensor(demos.levels))  # fmt: skip
        legal = torch.as_tensor(legality_targets(demos.obs)) if cfg.method == "ind" else None
        lw = {k: v for k, v in cfg.extra.items() if k in ("legal_weight", "legal_pos_weight")}
        prev = torch.cat([torch.zeros_like(act[:, :1]), act[:, :-1]], dim=1)
        for i, idx in zip(range(cfg.steps), _batches(len(demos), cfg.batch, rng), strict=False):
            out = model(obs[idx], lv[idx], prev[idx])
            loss = _update(
                opt, bc_loss(out, act[idx], mask[idx], None if legal is None else legal[idx], **lw)
            )
            if progress:
                progress(i, float(loss.detach()))
    else:
        obs, act, lv = _tensors(*demos.steps())
        for i, idx in zip(range(cfg.steps), _batches(len(obs), cfg.batch * 4, rng), strict=False):
            loss = _update(opt, bc_loss(model(obs[idx][:, None], lv[idx]), act[idx][:, None]))
            if progress:
                progress(i, float(loss.detach()))
    model.eval()
    return model, demos


def _train_trm(model, opt, demos: Demos, cfg: FitConfig, rng, progress) -> None:
    """Deep supervision: n_sup optimiser steps per batch, carrying (y, z) detached between them.

    ``cfg.steps`` counts optimiser updates, as for every other method, so a batch gives n_sup of them.
    """
    from torch.nn import functional as F  # noqa: N812

    obs, act, lv = _tensors(*demos.steps())
    g = cfg.grid_size
    target = (act[:, 0] * g + act[:, 1]) * 2 + act[:, 2]
    done = 0
    for idx in _batches(len(obs), cfg.batch, rng):
        y = z = None
        for _ in range(model.n_sup):
            x = model.embed(obs[idx], lv[idx])  # after each update: the previous graph is freed by backward
            if y is None:
                y, z = model.init_carry(x)
            (y, z), logits, halt = model.deep_recursion(x, y, z)
            flat = logits.flatten(1)
            correct = (flat.argmax(-1) == target[idx]).float()
            loss = _update(
                opt, F.cross_entropy(flat, target[idx]) + F.binary_cross_entropy_with_logits(halt, correct)
            )
            if progress:
                progress(done, float(loss.detach()))
            done += 1
            if done >= cfg.steps:
                return


def _level_steps(demos: Demos, level: int):
    keep = demos.levels == level
    return _tensors(*demos.subset(keep).steps())


def adapt(model, support: tuple, inner_lr: float):
    """One inner SGD step on a support set (MAML's adaptation), returning adapted parameters."""
    import torch
    from torch.func import functional_call

    params = dict(model.named_parameters())
    obs, act, lv = support
    loss = bc_loss(functional_call(model, params, (obs[:, None], lv)), act[:, None])
    grads = torch.autograd.grad(loss, list(params.values()))
    return {k: (p - inner_lr * gr).detach() for (k, p), gr in zip(params.items(), grads, strict=True)}


def _train_maml(model, opt, demos: Demos, cfg: FitConfig, rng, progress) -> None:
    """First-order MAML: tasks are the training levels; support/query sets are disjoint step samples."""
    import torch
    from torch.func import functional_call

    per_level = {k: _level_steps(demos, k) for k in cfg.train_levels}
    for i in range(cfg.steps):
        opt.zero_grad()
        total = 0.0
        for k, (obs, act, lv) in per_level.items():
            idx = rng.permutation(len(obs))
            s, q = idx[: cfg.maml_support * (k + 1)], idx[cfg.maml_support * (k + 1) :][: cfg.batch]
            fast = adapt(model, (obs[s], act[s], lv[s]), cfg.maml_inner_lr)
            fast = {n: p.requires_grad_() for n, p in fast.items()}
            loss = bc_loss(functional_call(model, fast, (obs[q][:, None], lv[q])), act[q][:, None])
            grads = torch.autograd.grad(loss, list(fast.values()))
            for p, gr in zip(model.parameters(), grads, strict=True):  # first-order: grads at θ' applied to θ
                p.grad = gr if p.grad is None else p.grad + gr
            total += float(loss.detach())
        opt.step()
        if progress:
            progress(i, total / len(per_level))


def save_checkpoint(model, cfg: FitConfig, out: Path) -> Path:
    """state_dict (torch.save) + config JSON; load with ``load_checkpoint`` (weights_only=True). Each file is
    written whole or not at all, config.json last and the old one removed first: a save cut short (Ctrl-C, a
    kill, a full disk) over an older checkpoint never leaves its config beside other weights."""
    import io

    import torch

    out.mkdir(parents=True, exist_ok=True)
    (out / "config.json").unlink(missing_ok=True)
    weights = io.BytesIO()
    torch.save(model.state_dict(), weights)
    atomic_write_bytes(out / "model.pt", weights.getvalue())
    atomic_write_text(out / "config.json", json.dumps(asdict(cfg), indent=2))
    return out


def load_checkpoint(path: Path):
    import torch

    try:
        raw = json.loads((path / "config.json").read_text())
    except (OSError, json.JSONDecodeError):
        raise ConfigError(
            f"{path} is not a BlockEnv checkpoint (no readable config.json); train one first"
        ) from None
    raw["train_levels"] = tuple(raw["train_levels"])
    cfg = FitConfig(**raw)
    model = _untrained(cfg)
    try:
        state = torch.load(path / "model.pt", weights_only=True)
    except (OSError, EOFError, RuntimeError, pickle.UnpicklingError):
        raise ConfigError(
            f"{path / 'model.pt'} is missing or unreadable (a save cut short?); train again"
        ) from None
    model.load_state_dict(state)
    model.eval()
    return model, cfg


def clone(model):
    return copy.deepcopy(model)
