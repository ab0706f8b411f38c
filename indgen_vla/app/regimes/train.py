"""Train small LeRobot policies (ACT, Diffusion) on one or more indgen LeRobotDatasets, on CPU.

A compact loop over lerobot's own ``LeRobotDataset`` (delta timestamps from the policy config) and the
policy's own pre/post processors, normalised with statistics aggregated over every dataset given (e.g.
human demos + MimicGen demos). The output directory is a LeRobot checkpoint that ``--policy lerobot:<dir>``
loads exactly like a Hub checkpoint. Until the run completes it also holds ``resume/``, the state saved every
``save_every`` steps: rerunning the same command resumes from it (``train_state``).
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from indgen_vla.app.config_fields import check_types, option, section
from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.regimes.demos import ENV_STATE, read_episode_sidecar
from indgen_vla.app.regimes.resume import RESUME_DIR, RUN_FILE, check_same_run, out_state, start_run
from indgen_vla.app.regimes.train_state import (
    CLI_FLAGS,
    LossLog,
    StepBatches,
    load_train_state,
    run_identity,
    save_train_state,
)
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import OBJECT_DIM
from indgen_vla.core.protocol.training_support import (
    cells_from_records,
    cells_to_json,
)
from indgen_vla.core.runs.records import atomic_write_json

POLICIES = ("act", "diffusion")
DEFAULT_REPO_ID = "local/indgen_demos"
INFO_FILE = "train_info.json"


@dataclass(frozen=True)
class TrainRecipe:
    """Policy size, optimisation and input selection: what decides the checkpoint (``train_info.json``'s config).

    Attributes:
        policy: lerobot policy type, ``act`` or ``diffusion``.
        steps, batch_size, lr, weight_decay, grad_clip, seed: optimisation (AdamW, cosine decay to 10 %).
        cameras: dataset cameras the policy reads (``agentview``, ``wrist``); empty = state-only, in which
            case the proprioceptive state is also fed as lerobot's environment-state input (see
            ``policy_wrappers.lerobot_steps``) because ACT/Diffusion need an image or an environment state.
        objects: low-dim policy that also observes the pick and target poses (the datasets'
            ``observation.environment_state``, recorded by ``indgen demos --objects``); no cameras.
        chunk_size, n_action_steps: ACT's predicted chunk and how much of it the evaluator executes.
        dim_model, n_heads, dim_feedforward, n_encoder_layers, n_decoder_layers, use_vae: ACT size.
        horizon, n_obs_steps, down_dims, num_inference_steps: Diffusion size.
        cache: keep decoded samples in memory after their first use (default: only when state-only).
        log_every: steps between loss log lines.
        save_every: steps between resumable states in ``<out>/resume`` (default: every 10 % of ``steps``).
    """

    policy: str = option("act", "lerobot policy type to train", choices=POLICIES)
    steps: int = option(3000, "optimiser updates", type=int)
    batch_size: int = option(64, "frames per update", type=int)
    lr: float = option(1e-3, "learning rate", type=float)
    weight_decay: float = option(1e-4)
    grad_clip: float = option(10.0)
    seed: int = option(0, "training seed (init and batch order)", type=int)
    cameras: tuple[str, ...] = option((), "comma-separated cameras to read; empty = state-only")
    objects: bool = option(False, "also read the recorded object poses (low-dim; no cameras)")
    chunk_size: int = option(20, "actions predicted per chunk", type=int)
    n_action_steps: int = option(10, "actions executed per chunk", type=int)
    dim_model: int = option(128)
    n_heads: int = option(4)
    dim_feedforward: int = option(512)
    n_encoder_layers: int = option(2)
    n_decoder_layers: int = option(1)
    use_vae: bool = option(False)
    horizon: int = option(16)
    n_obs_steps: int = option(2)
    down_dims: tuple[int, ...] = option((64, 128, 256))
    num_inference_steps: int = option(10)
    cache: bool | None = option(None)
    log_every: int = option(100)
    save_every: int | None = option(None, "steps between resumable states in OUT/resume (default: every 10%% of "
                                    "--steps)", type=int)  # fmt: skip

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if isinstance(self.cameras, str):  # the flag's text
            object.__setattr__(self, "cameras", tuple(c for c in self.cameras.split(",") if c))
        if self.policy not in POLICIES:
            raise ConfigError(f"policy {self.policy!r} is not trainable here; choose one of {list(POLICIES)}")
        for name in ("steps", "batch_size", "chunk_size", "n_action_steps", "dim_model", "n_heads", "horizon",
                     "n_obs_steps", "num_inference_steps", "log_every"):  # fmt: skip
            if int(getattr(self, name)) < 1:
                raise ConfigError(f"train: {name} must be >= 1, got {getattr(self, name)}")
        if self.save_every is not None and self.save_every < 1:
            raise ConfigError(f"train: --save-every must be >= 1 step, got {self.save_every}")
        if self.n_action_steps > self.chunk_size:
            raise ConfigError(
                f"train: n_action_steps {self.n_action_steps} exceeds chunk_size {self.chunk_size}"
            )
        if not (self.lr > 0 and self.weight_decay >= 0 and self.grad_clip > 0):
            raise ConfigError(f"train: lr and grad_clip must be > 0 and weight_decay >= 0 (lr={self.lr})")
        if self.dim_model % self.n_heads:
            raise ConfigError(
                f"train: dim_model {self.dim_model} must be divisible by n_heads {self.n_heads}"
            )
        if self.objects and self.cameras:
            raise ConfigError("train: --objects trains a low-dimensional policy; drop --cameras")
        bad = [c for c in self.cameras if c not in ("agentview", "wrist")]
        if bad:
            raise ConfigError(
                f"train: unknown camera(s) {bad}; cameras are agentview, wrist (or none: state-only)"
            )

    @property
    def every(self) -> int:
        """Steps between saved states: ``save_every``, or 10 % of ``steps``."""
        return self.save_every or max(1, math.ceil(self.steps / 10))


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """What ``indgen train`` trains: a policy by ``recipe`` on ``datasets`` into the checkpoint ``out``, the labels
    stored with it, and ``evaluation``'s protocol run on the weights in memory every ``eval_every`` updates."""

    datasets: tuple[str, ...] = option()  # DATASETS...: LeRobotDataset roots (positional)
    out: str = option(help="checkpoint directory: new, or an unfinished one to resume with the same arguments",
                      required=True)  # fmt: skip
    recipe: TrainRecipe = section(TrainRecipe)
    data_regime: str = option("", "label stored with the checkpoint (e.g. human, human+mimicgen)")
    repo_id: str = option(DEFAULT_REPO_ID, "repo id stored in the checkpoint config")
    eval_every: int | None = option(None, "evaluate the weights in memory every N updates (and after the last), "
                                    "with --eval's flags", type=int, metavar="N")  # fmt: skip
    # --eval's protocol (the command parses its flags; API: an EvalConfig); its policy and out are set per step
    evaluation: EvalConfig | None = option(None)
    eval_out: str | None = option(None, "where the runs and series.md go (default: OUT_evals)")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        datasets = (self.datasets,) if isinstance(self.datasets, str | os.PathLike) else self.datasets
        object.__setattr__(self, "datasets", tuple(os.fspath(d) for d in datasets))
        object.__setattr__(self, "out", os.fspath(self.out))
        if not self.datasets:
            raise ConfigError("train: give at least one dataset directory")
        if not self.out:
            raise ConfigError("train: --out is required: the checkpoint directory")
        if (self.eval_every is None) != (self.evaluation is None):
            raise ConfigError("--eval-every N and --eval 'FLAGS' go together, e.g. --eval-every 500 --eval='--scene "
                              "pick_place --axis pick_y --levels -2:2 --episodes 10'")  # fmt: skip
        if self.eval_every is not None and self.eval_every < 1:
            raise ConfigError(f"--eval-every must be >= 1 update, got {self.eval_every}")
        if self.evaluation is not None and not isinstance(self.evaluation, EvalConfig):
            raise ConfigError(
                f"train: evaluation must be an EvalConfig, got {type(self.evaluation).__name__}"
            )

    @property
    def eval_root(self) -> Path:
        """Where the ``--eval-every`` runs and series report go (``eval_root``)."""
        return eval_root(self.out, self.eval_out)


def eval_root(out: str, eval_out: str | None) -> Path:
    """Where ``--eval-every``'s runs and series report go: ``--eval-out``, or ``OUT_evals``."""
    return Path(eval_out) if eval_out else Path(out).parent / f"{Path(out).name}_evals"


# the flags of ``indgen train`` in its --help order, around the command's own --eval
FLAGS_BEFORE_EVAL = ("out", "policy", "steps", "batch_size", "lr", "seed", "cameras", "objects", "chunk_size",
                     "n_action_steps", "data_regime", "repo_id", "save_every", "eval_every")  # fmt: skip
FLAGS_AFTER_EVAL = ("eval_out",)


def _policy_config(cfg: TrainRecipe, input_features: dict, output_features: dict):
    """The lerobot policy config for ``cfg`` (no pretrained weights: nothing is downloaded)."""
    from lerobot.configs.types import NormalizationMode

    norm = {"VISUAL": NormalizationMode.MEAN_STD, "STATE": NormalizationMode.MEAN_STD,
            "ENV": NormalizationMode.MEAN_STD, "ACTION": NormalizationMode.MEAN_STD}  # fmt: skip
    if cfg.policy == "act":
        from lerobot.policies.act.configuration_act import ACTConfig

        return ACTConfig(input_features=input_features, output_features=output_features,
                         pretrained_backbone_weights=None, chunk_size=cfg.chunk_size,
                         n_action_steps=cfg.n_action_steps, dim_model=cfg.dim_model, n_heads=cfg.n_heads,
                         dim_feedforward=cfg.dim_feedforward, n_encoder_layers=cfg.n_encoder_layers,
                         n_decoder_layers=cfg.n_decoder_layers, use_vae=cfg.use_vae, latent_dim=16,
                         n_vae_encoder_layers=2, dropout=0.1, optimizer_lr=cfg.lr, optimizer_lr_backbone=cfg.lr,
                         optimizer_weight_decay=cfg.weight_decay, normalization_mapping=norm,
                         device="cpu")  # fmt: skip
    from lerobot.policies.diffusion.configuration_diffusion import DiffusionConfig

    n_action = min(cfg.n_action_steps, cfg.horizon - cfg.n_obs_steps + 1)
    return DiffusionConfig(input_features=input_features, output_features=output_features,
                           pretrained_backbone_weights=None, n_obs_steps=cfg.n_obs_steps, horizon=cfg.horizon,
                           n_action_steps=n_action, down_dims=cfg.down_dims, crop_shape=None,
                           use_group_norm=True, num_inference_steps=cfg.num_inference_steps,
                           optimizer_lr=cfg.lr, optimizer_weight_decay=cfg.weight_decay,
                           normalization_mapping={**norm, "STATE": NormalizationMode.MIN_MAX,
                                                  "ENV": NormalizationMode.MIN_MAX,
                                                  "ACTION": NormalizationMode.MIN_MAX}, device="cpu")  # fmt: skip


def video_backend() -> str:
    """lerobot's own choice (torchcodec where it loads, else pyav), made without its ~200-line torchcodec
    traceback, logged as a warning on every machine lacking FFmpeg's shared libraries."""
    try:
        import torchcodec  # noqa: F401

        return "torchcodec"
    except (ImportError, OSError, RuntimeError):
        return "pyav"


def _require_datasets(dirs: Sequence[Path]) -> None:
    for d in dirs:
        if not (Path(d) / "meta" / "info.json").is_file():
            raise ConfigError(
                f"train: {str(d)!r} is not a LeRobotDataset (no meta/info.json); record one with "
                "`indgen demos` or `indgen mimicgen`"
            )


def _open_datasets(dirs: Sequence[Path], repo_id: str, delta_timestamps=None) -> list:
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    _require_datasets(dirs)
    backend = video_backend()
    out = []
    for d in dirs:
        out.append(
            LeRobotDataset(repo_id, root=Path(d), delta_timestamps=delta_timestamps, video_backend=backend)
        )
    return out


def _features(datasets: list, cameras: tuple[str, ...], objects: bool = False) -> tuple[dict, dict]:
    """Input/output policy features shared by every dataset (state, action, the chosen cameras or object poses)."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.utils.feature_utils import dataset_to_policy_features

    first = dataset_to_policy_features(datasets[0].meta.features)
    for ds in datasets[1:]:
        other = dataset_to_policy_features(ds.meta.features)
        for key in ("observation.state", "action", *(f"observation.images.{c}" for c in cameras)):
            if key in first and key in other and tuple(first[key].shape) != tuple(other[key].shape):
                raise ConfigError(f"train: datasets disagree on {key}: {tuple(first[key].shape)} vs "
                                  f"{tuple(other[key].shape)} ({ds.root})")  # fmt: skip
        if ds.meta.fps != datasets[0].meta.fps:
            raise ConfigError(f"train: datasets have different fps ({datasets[0].meta.fps} vs {ds.meta.fps})")
    if "observation.state" not in first or "action" not in first:
        raise ConfigError("train: datasets need observation.state and action features")
    inputs = {"observation.state": first["observation.state"]}
    for cam in cameras:
        key = f"observation.images.{cam}"
        if not all(key in dataset_to_policy_features(ds.meta.features) for ds in datasets):
            raise ConfigError(
                f"train: camera {cam!r} is missing from a dataset; record it or train state-only"
            )
        inputs[key] = first[key]
    if objects:
        feats = [dataset_to_policy_features(ds.meta.features) for ds in datasets]
        shapes = {tuple(f[ENV_STATE].shape) if ENV_STATE in f else None for f in feats}
        if shapes != {(OBJECT_DIM,)}:
            raise ConfigError(
                f"train: --objects needs {ENV_STATE} of shape ({OBJECT_DIM},) in every dataset (found "
                f"{sorted(shapes, key=str)}); record them with 'indgen demos --objects'"
            )
        inputs[ENV_STATE] = first[ENV_STATE]
    elif not cameras:  # ACT/Diffusion need a non-proprio input: the preprocessor copies the state into it
        inputs["observation.environment_state"] = PolicyFeature(
            FeatureType.ENV, tuple(first["observation.state"].shape)
        )
    return inputs, {"action": first["action"]}


def _stats(datasets: list, inputs: dict, objects: bool = False) -> dict:
    """Normalisation statistics aggregated over every dataset, restricted to the policy's features."""
    from lerobot.datasets.compute_stats import aggregate_stats

    stats = aggregate_stats([ds.meta.stats for ds in datasets])
    keep = {k: v for k, v in stats.items() if k in inputs or k == "action"}
    if "observation.environment_state" in inputs and not objects:  # the proprio copy: normalised like it
        keep["observation.environment_state"] = dict(stats["observation.state"])
    return keep


class _Samples:
    """Map-style view over concatenated datasets that keeps only the training keys, optionally cached."""

    def __init__(self, datasets: list, keys: tuple[str, ...], cache: bool):
        import torch

        self._data = torch.utils.data.ConcatDataset(datasets)
        self._keys, self._cache = keys, ({} if cache else None)

    def __len__(self) -> int:
        return len(self._data)

    def __getitem__(self, i: int) -> dict:
        if self._cache is not None and i in self._cache:
            return self._cache[i]
        item = self._data[i]
        out = {k: item[k] for k in self._keys if k in item}
        if self._cache is not None:
            self._cache[i] = out
        return out


def training_levels(dirs: Sequence[Path], datasets: list) -> list[dict] | None:
    """The (scene, task, axis, level, parameter) cells of every episode, from the datasets' ``indgen demos`` /
    ``mimicgen`` sidecars; None when a dataset has none or its sidecar does not cover its episodes."""
    records = []
    for d, ds in zip(dirs, datasets, strict=True):
        own = read_episode_sidecar(d)
        if not own or len(own) != ds.num_episodes:
            return None
        records += own
    return cells_to_json(cells_from_records(records))


def _seed_all(seed: int) -> None:
    import random

    import numpy as np
    import torch

    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def train_policy(
    config: TrainConfig, *, progress: Callable[[int, float], None] | None = None,
    say: Callable[[str], None] | None = None, after_step: Callable[[int, Any], None] | None = None,
) -> Path:  # fmt: skip
    """Train a lerobot policy on ``config.datasets`` by ``config.recipe`` and save it (weights + processors) to
    ``config.out``.

    An unfinished ``out`` made with the same arguments is resumed from its last saved state (``say`` is told
    from which step); a finished one is returned unchanged; other arguments are refused in one line.
    ``after_step(step, model)``: called after every update with the model (``policy``, ``pre``, ``post``) in train
    mode, to evaluate it in memory (``indgen train --eval-every``: ``train_eval.make_hook``); it must hand the model
    back as it found it.
    """
    cfg, repo_id, data_regime = config.recipe, config.repo_id, config.data_regime
    dirs = [Path(d) for d in config.datasets]
    _require_datasets(dirs)
    out, run = Path(config.out), run_identity(cfg, dirs, repo_id, data_regime)
    state = out_state(out, INFO_FILE, "train")
    if state == "finished":
        _check_finished(out, run)
        shutil.rmtree(out / RESUME_DIR, ignore_errors=True)  # a kill between the checkpoint and this cleanup
        if say is not None:
            say(f"train: {out} is already complete ({cfg.steps} steps); nothing to do")
        return out
    if state == "unfinished":
        saved = json.loads((out / RESUME_DIR / RUN_FILE).read_text())
        check_same_run(out, saved, run, "train", CLI_FLAGS, finished=False)
    _seed_all(cfg.seed)
    model = _build(cfg, dirs, repo_id)
    root = start_run(out, run)
    log, train_s = _fit(cfg, model, root, progress, say, after_step)
    model.policy.eval()
    for obj in (model.policy, model.pre, model.post):
        obj.save_pretrained(str(out))
    info = {"config": asdict(cfg), "datasets": [str(d) for d in dirs], "data_regime": data_regime,
            "episodes": sum(ds.num_episodes for ds in model.datasets), "frames": len(model.samples),
            "train_s": round(train_s, 1), "first_loss": round(log.first_loss, 5), "loss_every": cfg.log_every,
            "losses": [round(x, 5) for x in log.losses],
            "params": sum(p.numel() for p in model.policy.parameters()),
            "levels": training_levels(dirs, model.datasets), "run": run}  # fmt: skip
    atomic_write_json(out / INFO_FILE, info)  # written last: the mark of a finished checkpoint
    shutil.rmtree(root, ignore_errors=True)
    return out


def _check_finished(out: Path, run: dict) -> None:
    saved = json.loads((out / INFO_FILE).read_text()).get("run")
    if saved is None:
        raise ConfigError(f"train: --out {out} holds a checkpoint from before training could resume; choose a "
                          "new directory")  # fmt: skip
    check_same_run(out, saved, run, "train", CLI_FLAGS, finished=True)


@dataclass
class _Model:
    """A policy with its processors and the samples it trains on."""

    policy: Any
    pre: Any
    post: Any
    datasets: list
    samples: _Samples


def _build(cfg: TrainRecipe, dirs: list[Path], repo_id: str) -> _Model:
    """The freshly initialised policy, its processors (dataset statistics) and the training samples."""
    from lerobot.datasets.factory import resolve_delta_timestamps
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    from policy_wrappers.lerobot_steps import ObjectPosesStep, ProprioAsEnvStateStep  # lazy: optional lerobot

    datasets = _open_datasets(dirs, repo_id)
    inputs, outputs = _features(datasets, cfg.cameras, cfg.objects)
    policy_cfg = _policy_config(cfg, inputs, outputs)
    delta = resolve_delta_timestamps(policy_cfg, datasets[0].meta)
    datasets = _open_datasets(dirs, repo_id, delta)
    stats = _stats(datasets, inputs, cfg.objects)
    policy = get_policy_class(policy_cfg.type)(policy_cfg)
    pre, post = make_pre_post_processors(policy_cfg, dataset_stats=stats)
    if not cfg.cameras:  # before normalisation: copy proprio into the environment-state input, or mark poses
        at = next(i for i, s in enumerate(pre.steps) if type(s).__name__.startswith("Normalizer"))
        pre.steps.insert(at, ObjectPosesStep() if cfg.objects else ProprioAsEnvStateStep())
    keys = (*inputs, "action", "action_is_pad")
    cache = cfg.cache if cfg.cache is not None else not cfg.cameras
    copied = () if cfg.objects else ("observation.environment_state",)  # filled by ProprioAsEnvStateStep
    samples = _Samples(datasets, tuple(k for k in keys if k not in copied), cache)
    if len(samples) < cfg.batch_size:
        raise ConfigError(f"train: {len(samples)} samples is fewer than one batch of {cfg.batch_size}")
    return _Model(policy, pre, post, datasets, samples)


def _fit(
    cfg: TrainRecipe, model: _Model, root: Path, progress, say, after_step=None
) -> tuple[LossLog, float]:
    """AdamW with warm-up and cosine decay from the last saved state in ``root`` (or step 0) to ``cfg.steps``,
    saving the state every ``cfg.every`` steps and after the last; (loss log, training seconds over sessions)."""
    import torch

    policy = model.policy
    optimizer = torch.optim.AdamW(policy.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    warmup = min(100, cfg.steps // 10)

    def lr_at(step: int) -> float:
        if step < warmup:
            return (step + 1) / warmup
        t = (step - warmup) / max(cfg.steps - warmup, 1)
        return 0.1 + 0.9 * 0.5 * (1 + math.cos(math.pi * t))

    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lr_at)
    step, log = load_train_state(root, policy, optimizer, scheduler)
    if step and say is not None:
        say(f"train: resuming {root.parent} from step {step} of {cfg.steps}")
    batches = StepBatches(len(model.samples), cfg.batch_size, cfg.seed, step, cfg.steps)
    # its own generator: a loader draws a worker base seed at each iteration start, from torch's global RNG otherwise
    loader = torch.utils.data.DataLoader(model.samples, batch_sampler=batches, num_workers=0,
                                         generator=torch.Generator().manual_seed(cfg.seed))  # fmt: skip
    policy.train()
    before, t0 = log.train_s, time.perf_counter()
    for batch in loader:
        loss, _ = policy.forward(model.pre(batch))
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(policy.parameters(), cfg.grad_clip)
        optimizer.step()
        scheduler.step()
        step += 1
        if log.add(step, float(loss.detach()), cfg.log_every, cfg.steps) and progress is not None:
            progress(step, log.losses[-1])
        if step % cfg.every == 0 or step == cfg.steps:
            log.train_s = before + time.perf_counter() - t0
            save_train_state(root, step, cfg.steps, policy, optimizer, scheduler, log)
        if after_step is not None:
            after_step(step, model)
    return log, before + time.perf_counter() - t0
