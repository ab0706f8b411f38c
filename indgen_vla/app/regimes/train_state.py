"""The resumable state of ``indgen train``: a batch order that is a pure function of (seed, step), and the state saved
every ``--save-every`` steps (weights, lerobot's own optimizer / scheduler / RNG state files, the loss log), so a
killed run resumes and ends with the checkpoint an uninterrupted run writes, bit for bit."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

from indgen_vla.app.regimes.resume import INPUTS, dataset_size, last_state, save_state
from indgen_vla.core.protocol.seeding import episode_seed

MODEL_FILE = "model.safetensors"
LOG_FILE = "log.json"
NOT_IN_RUN = ("save_every", "cache")  # TrainRecipe fields that never change the checkpoint
CLI_FLAGS = ("policy", "steps", "batch_size", "lr", "seed", "cameras", "objects", "chunk_size", "n_action_steps",
             "data_regime", "repo_id", "datasets")  # fmt: skip


def batch_indices(n: int, batch_size: int, seed: int, step: int, perm_cache: dict | None = None) -> list[int]:
    """Sample indices of update ``step``: epoch ``step // (n // batch_size)`` is a permutation seeded by (seed,
    epoch), cut into whole batches (the remainder is dropped, as ``drop_last``)."""
    import torch

    per_epoch = n // batch_size
    epoch, b = divmod(step, per_epoch)
    cache = perm_cache if perm_cache is not None else {}
    if epoch not in cache:
        cache.clear()
        gen = torch.Generator().manual_seed(episode_seed(seed, "train-order", epoch))
        cache[epoch] = torch.randperm(n, generator=gen)
    return cache[epoch][b * batch_size : (b + 1) * batch_size].tolist()


class StepBatches:
    """Batch sampler of updates ``start``..``stop - 1`` (a resumed run reads exactly the batches it would have)."""

    def __init__(self, n: int, batch_size: int, seed: int, start: int, stop: int):
        self.n, self.batch_size, self.seed, self.start, self.stop = n, batch_size, seed, start, stop

    def __iter__(self):
        cache: dict = {}
        for step in range(self.start, self.stop):
            yield batch_indices(self.n, self.batch_size, self.seed, step, cache)

    def __len__(self) -> int:
        return self.stop - self.start


@dataclass
class LossLog:
    """The loss record ``train_info.json`` keeps, carried across a resume: ``window`` holds the losses since the
    last logged mean; ``train_s`` the training seconds of earlier sessions."""

    losses: list[float] = field(default_factory=list)
    window: list[float] = field(default_factory=list)
    first_loss: float = math.nan
    train_s: float = 0.0

    def add(self, step: int, loss: float, every: int, last: int) -> bool:
        """Record update ``step``'s (1-based) loss; True when a mean was logged."""
        if step == 1:
            self.first_loss = loss
        self.window.append(loss)
        if step % every and step != last:
            return False
        self.losses.append(sum(self.window) / len(self.window))
        self.window = []
        return True


def run_identity(cfg, dirs: list[Path], repo_id: str, data_regime: str) -> dict:
    """Everything that decides the checkpoint: compared when a rerun finds an unfinished or finished ``--out``."""
    config = {k: v for k, v in asdict(cfg).items() if k not in NOT_IN_RUN}
    paths = [str(d.resolve()) for d in dirs]
    return {"config": config, "datasets": paths, "repo_id": repo_id, "data_regime": data_regime,
            INPUTS: {p: dataset_size(Path(p)) for p in paths}}  # fmt: skip


def save_train_state(root: Path, step: int, steps: int, policy, optimizer, scheduler, log: LossLog) -> None:
    """State after update ``step`` in ``root``/step_<step> (replacing the previous one atomically)."""
    from lerobot.common.train_utils import get_step_identifier, save_training_state
    from safetensors.torch import save_model

    def write(d: Path) -> None:
        save_model(policy, str(d / MODEL_FILE))
        save_training_state(d, step, optimizer, scheduler)
        (d / LOG_FILE).write_text(json.dumps(asdict(log)) + "\n")

    save_state(root, f"step_{get_step_identifier(step, steps)}", write)


def load_train_state(root: Path, policy, optimizer, scheduler) -> tuple[int, LossLog]:
    """(step, loss log) of the last saved state, loaded into ``policy``, ``optimizer``, ``scheduler`` and the RNGs;
    (0, empty log) when none was saved yet."""
    from lerobot.common.train_utils import load_training_state
    from safetensors.torch import load_model

    d = last_state(root)
    if d is None:
        return 0, LossLog()
    load_model(policy, str(d / MODEL_FILE))
    step, _, _ = load_training_state(d, optimizer, scheduler)
    log = LossLog(**json.loads((d / LOG_FILE).read_text()))
    return step, log
