"""Evaluation configs: a frozen, validated ``EvalConfig`` and its YAML presets (``EpisodeJob`` lives in
``indgen_vla.core.protocol.plan`` and is imported here for the backends)."""

from __future__ import annotations

import argparse
import dataclasses
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import COMPILE_MODES, CUDA_GRAPH_COMPILE_MODES, PRECISIONS
from indgen_vla.core.protocol.plan import EpisodeJob, plan_jobs
from indgen_vla.core.protocol.progression import expand_axes
from indgen_vla.core.resources import config_dir

DEFAULT_EPISODES = 50
PRESET_DIR = config_dir("paper")


@dataclass(frozen=True)
class EvalConfig:
    """Everything ``indgen evaluate`` needs; validated on construction, never rewritten silently."""

    policy: str
    scene: str
    axes: tuple[str, ...]
    out: str
    task: str | None = None
    levels: str | None = None
    step: float | None = None
    axes_preset: str | None = None  # preset NAME (configs/axes) or YAML PATH: steps, level ranges
    episodes: int = DEFAULT_EPISODES
    workers: int | str = 1  # "auto" (Ray backend): as many simulator actors as the cluster's CPUs hold
    backend: str = "local"
    pipeline: bool = False  # local backend: two environments per worker, stepping overlapped with inference
    seed: int = 0
    max_steps: int | None = None
    replan_steps: int | None = None
    warmup_steps: int = 0
    image_size: int | None = None
    video: bool = False
    video_per_level: int = 1
    data_regime: str = ""
    gamma: float = 0.2
    allow_infeasible: bool = False
    smoke: bool = (
        False  # run an image policy on placeholder assets anyway: the manifest says "not a measurement"
    )
    trust_remote_code: bool = False
    allow_protocol_mismatch: bool = (
        False  # resume a run under a protocol that changes outcomes (manifest lists it)
    )
    max_retries: int = 2
    device: str = "cpu"  # where in-process policies run: cpu, cuda, cuda:N
    precision: str = "fp32"  # "bf16": autocast forward, for policies that support it (lerobot:)
    compile: str = "off"  # torch.compile mode of the policy's per-call forward (lerobot:), cached on disk
    server_patience: float = 600.0  # seconds a remote policy server may stay unreachable before the run stops
    adaptive: str | None = None  # "kstar" | "curve" | "until-failure": the stopping rule (docs/adaptive.md)
    adaptive_delta: float = 0.1  # indifference half-width around gamma
    adaptive_alpha: float = 0.025  # stated error rate of each verdict (alpha = beta)
    round_size: int = 5  # episodes between two looks of the sequential rule
    # run level 0 once per task for the axes whose level 0 is one environment (plan.shared_t0, engine/share.py)
    share_t0: bool = True
    preregistered: str | None = None  # a plan.lock (indgen budget --write): refuse any deviation from it

    def __post_init__(self) -> None:
        if not self.policy:
            raise ConfigError("--policy is required, e.g. --policy standin:oracle or --policy lerobot:HUB_ID")
        if not self.scene:
            raise ConfigError("--scene is required; list scenes with 'indgen scenes'")
        if not self.axes or not all(self.axes):
            raise ConfigError(
                "--axis is required, e.g. --axis pick_y or --axis pick_y,scale; see 'indgen axes'"
            )
        if not self.out:
            raise ConfigError("--out is required: the run directory (re-run the same command to resume)")
        if self.episodes < 1:
            raise ConfigError(f"--episodes must be >= 1, got {self.episodes}")
        if self.workers == "auto":
            if self.backend != "ray":
                raise ConfigError("--workers auto follows a Ray cluster's CPUs: use it with --backend ray, or give "
                                  "a number of worker processes")  # fmt: skip
        elif isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1:
            raise ConfigError(
                f"--workers must be a number >= 1 or auto (--backend ray), got {self.workers!r}"
            )
        if self.backend not in ("local", "ray"):
            raise ConfigError(f"--backend must be 'local' or 'ray', got {self.backend!r}")
        for name in ("pipeline", "share_t0"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if self.pipeline and self.backend == "ray":
            raise ConfigError(
                "--pipeline is for --backend local; with Ray, overlap by running 2 simulator actors per CPU "
                "(INDGEN_RAY_CPUS_PER_SIM=0.5)"
            )
        for name in ("max_steps", "replan_steps", "image_size"):
            v = getattr(self, name)
            if v is not None and v < 1:
                raise ConfigError(f"--{name.replace('_', '-')} must be >= 1, got {v}")
        if self.step is not None and not self.step > 0:
            raise ConfigError(f"--step must be positive, got {self.step}")
        if self.axes_preset is not None:
            from scenes.axes import load_preset as load_axes_preset  # yaml only; raises one clear line

            load_axes_preset(self.axes_preset)
        if self.warmup_steps < 0 or self.max_retries < 0 or self.video_per_level < 0:
            raise ConfigError("warmup_steps, max_retries and video_per_level must be >= 0")
        if not 0 < self.gamma <= 1:
            raise ConfigError(f"--gamma must be in (0, 1], got {self.gamma}")
        if not (self.device in ("cpu", "cuda", "mps") or re.fullmatch(r"cuda:\d+", self.device)):
            raise ConfigError(f"--device must be cpu, cuda, cuda:N or mps, got {self.device!r}")
        if self.precision not in PRECISIONS:
            raise ConfigError(f"--precision must be one of {', '.join(PRECISIONS)}, got {self.precision!r}")
        if self.compile not in COMPILE_MODES:
            raise ConfigError(f"--compile must be one of {', '.join(COMPILE_MODES)}, got {self.compile!r}")
        if self.compile in CUDA_GRAPH_COMPILE_MODES and not self.device.startswith("cuda"):
            raise ConfigError(
                f"--compile {self.compile} captures CUDA graphs and needs --device cuda (got {self.device!r}); "
                "use --compile default on CPU"
            )
        if not self.server_patience >= 0:
            raise ConfigError(f"--server-patience must be >= 0 seconds, got {self.server_patience}")
        if self.adaptive is not None:
            self.sequential_rule()  # validates mode and rule parameters in one clear line each

    def policy_options(self) -> dict[str, str]:
        """The spec options the run adds to ``--policy`` (only those not at their default, so families that
        do not take them still load)."""
        out = {"precision": self.precision} if self.precision != "fp32" else {}
        return out | ({"compile": self.compile} if self.compile != "off" else {})

    def sequential_rule(self):
        """The rule of an ``--adaptive`` run (its cap, or until-failure's episodes per level, is ``--episodes``)."""
        from indgen_vla.core.stats.sprt import make_rule

        return make_rule(self.adaptive, self.gamma, self.adaptive_delta, self.adaptive_alpha, self.round_size,
                         self.episodes)  # fmt: skip

    def plan_dict(
        self, tasks: list[str], levels: dict[str, list[int]], max_steps: int | None,
        task_steps: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """The part of the config that fixes which episodes exist and how they run (resume must match);
        ``task_steps``: each task's steps of an axis whose family resolves them per task (``ScenePlan``)."""
        plan = {
            "policy": self.policy, "scene": self.scene, "tasks": tasks, "axes": list(self.axes),
            "levels": {a: levels[a] for a in self.axes}, "step": self.step, "episodes": self.episodes,
            "seed": self.seed, "max_steps": max_steps, "replan_steps": self.replan_steps,
            "warmup_steps": self.warmup_steps, "image_size": self.image_size, "data_regime": self.data_regime,
        }  # fmt: skip
        if self.axes_preset is not None:  # only when set, so runs made before the option still resume
            plan["axes_preset"] = self.axes_preset
        if task_steps:  # only where a family's steps differ by task: a run made at other steps never resumes
            plan["task_steps"] = {
                a: {t: dict(v) for t, v in by_task.items()} for a, by_task in task_steps.items()
            }
        if self.adaptive is not None:
            from indgen_vla.core.stats.sprt import plan_entry

            plan["adaptive"] = plan_entry(self.adaptive, self.sequential_rule())
        return plan


FLAG_FIELDS = {f.name for f in dataclasses.fields(EvalConfig)}
# --no-pipeline / --no-share-t0 (False) override a preset; other False flags are "not given"
EXPLICIT_FALSE = {"pipeline", "share_t0"}


def load_config_preset(path: str) -> dict[str, Any]:
    """Read a YAML preset; a bare name like ``libero_object`` is looked up in the shipped configs/paper/."""
    import yaml

    p = Path(path)
    if not p.exists() and not p.suffix and (PRESET_DIR / f"{path}.yaml").exists():
        p = PRESET_DIR / f"{path}.yaml"
    if not p.exists():
        known = sorted(x.stem for x in PRESET_DIR.glob("*.yaml")) if PRESET_DIR.exists() else []
        raise ConfigError(f"--config {path}: no such file; presets shipped: {', '.join(known) or 'none'}")
    try:
        data = yaml.safe_load(p.read_text()) or {}
    except yaml.YAMLError as e:
        raise ConfigError(f"--config {p}: invalid YAML ({e.__class__.__name__}); fix the file") from None
    if not isinstance(data, dict):
        raise ConfigError(f"--config {p}: expected a mapping of option: value")
    data = {k.replace("-", "_"): v for k, v in data.items()}
    if "axis" in data:
        data["axes"] = data.pop("axis")
    unknown = sorted(set(data) - FLAG_FIELDS)
    if unknown:
        import difflib

        hints = [f"{u} (did you mean {m[0]}?)" if (m := difflib.get_close_matches(u, FLAG_FIELDS, 1)) else u
                 for u in unknown]  # fmt: skip
        raise ConfigError(f"--config {p}: unknown option(s) {', '.join(hints)}")
    return data


def config_from_args(args: argparse.Namespace) -> EvalConfig:
    """Merge a YAML preset (if any) with the flags; flags given on the command line win."""
    return config_from_values(vars(args), getattr(args, "config", None))


def config_from_values(
    given: Mapping[str, Any], config: str | None = None, *, strict: bool = False
) -> EvalConfig:
    """The one road from option values (parsed flags, or the Python API's keyword arguments, named like the flags)
    and an optional preset to an ``EvalConfig``: a preset is read first, then every value that is set wins.
    ``strict`` refuses names that are no option (the API's keywords; argparse has already refused bad flags)."""
    values: dict[str, Any] = load_config_preset(config) if config else {}
    flag_map = {"axis": "axes"}
    if strict:
        unknown = sorted(k for k in given if flag_map.get(k, k) not in FLAG_FIELDS)
        if unknown:
            import difflib

            names = sorted(FLAG_FIELDS - {"axes"} | {"axis"})
            hints = [f"{u} (did you mean {m[0]}?)" if (m := difflib.get_close_matches(u, names, 1)) else u
                     for u in unknown]  # fmt: skip
            raise ConfigError(f"unknown option(s) {', '.join(hints)}; the options are evaluate's flags: "
                              "see 'indgen evaluate --help'")  # fmt: skip
    for key, value in given.items():
        name = flag_map.get(key, key)
        if name in FLAG_FIELDS and value is not None and (value is not False or name in EXPLICIT_FALSE):
            values[name] = value
    axes = values.get("axes")
    if isinstance(axes, str):
        values["axes"] = expand_axes([a.strip() for a in axes.split(",") if a.strip()])
    elif isinstance(axes, list | tuple):
        values["axes"] = expand_axes([str(a) for a in axes])  # A@B=i:j: one held axis per level of B
    levels = values.get("levels")
    if isinstance(levels, list | tuple | range):
        values["levels"] = ",".join(str(x) for x in levels)
    if isinstance(values.get("out"), os.PathLike):
        values["out"] = os.fspath(values["out"])
    values.setdefault("workers", os.cpu_count() or 1)
    for name in ("policy", "scene", "out"):
        values.setdefault(name, "")
    values.setdefault("axes", ())
    return EvalConfig(**values)


def plan_episodes(
    cfg: EvalConfig, tasks: list[str], levels: dict[str, list[int]], params: dict[tuple[str, str, int], float]
) -> list[EpisodeJob]:
    """``cfg``'s episodes over the given tasks, levels and parameters (``indgen_vla.core.protocol.plan.plan_jobs``), for callers
    that drive a backend without a resolved plan (benchmarks, tests); ``evaluate`` builds them with its plan."""
    return list(plan_jobs(cfg.scene, tasks, {a: levels[a] for a in cfg.axes}, params, cfg.episodes, cfg.seed,
                          cfg.video, cfg.video_per_level))  # fmt: skip
