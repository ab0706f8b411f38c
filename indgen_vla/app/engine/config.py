"""Evaluation configs: ``EvalConfig``, four frozen sections each validated on construction (``plan``: which episodes
exist and how they are judged; ``policy``: what runs and how it is fed; ``run``: where and how the episodes execute;
``adaptive``: the stopping rule). Every field carries its ``indgen evaluate`` flag in its metadata (``option``), from
which the command line, the Python API's keywords and the YAML presets' keys are all made (``config_values``).

Options have flat names (``episodes``, ``adaptive_delta``, ``policy``): the flags, the API's keywords, a preset's
flat keys and the manifest's ``config`` use them; ``EvalConfig.flat``/``from_flat`` convert."""

from __future__ import annotations

import argparse
import dataclasses
import numbers
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from indgen_vla.app.config_fields import Option, check_types, option, typed_value
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.plan import EpisodeJob, plan_jobs
from indgen_vla.core.protocol.policy_options import COMPILE_MODES, CUDA_GRAPH_COMPILE_MODES, PRECISIONS
from indgen_vla.core.protocol.progression import expand_axes
from indgen_vla.core.resources import config_dir

DEFAULT_EPISODES = 50
# the scene options' help lines (evaluate's flags, and certify's and preview's: cli/options.add_scene_options)
SPLIT_HELP = ("RoboCasa365's split T0 is drawn from: pretrain (default; layouts and styles 11..60), target (its ten "
              "kitchens), all; wins over $INDGEN_ROBOCASA_SPLIT")  # fmt: skip
REGISTRIES_HELP = ("RoboCasa's object registries, a comma list of objaverse, aigen, lightwheel (default "
                   "objaverse,lightwheel); wins over $INDGEN_ROBOCASA_OBJ_REGISTRIES")  # fmt: skip
PRESET_DIR = config_dir("paper")
ADAPTIVE_MODES = ("kstar", "curve", "until-failure")  # core.stats.sprt.MODES (a test keeps them equal)


def workers_value(text: str) -> int | str:
    """``--workers``: a number, or ``auto`` (the Ray backend follows its cluster's CPUs)."""
    if text == "auto":
        return text
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number or auto, got {text!r}") from None


def levels_text(value: Any) -> str | None:
    """``--levels`` as text from what the Python API and YAML give: the text itself, one level (``levels=2``) or a
    list, tuple or range of them; anything else is one ``ConfigError`` line."""
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return str(int(value))
    try:
        items = list(value)
    except TypeError:
        items = None
    if (
        items is None
        or not items
        or not all(isinstance(k, numbers.Integral) and not isinstance(k, bool) for k in items)
    ):
        raise ConfigError(
            f"--levels must be a range like '-3:3', a list of levels or one level, got {value!r}"
        )
    return ",".join(str(int(k)) for k in items)


def _at_least(value: int | float | None, low: int, flag: str) -> None:
    if value is not None and value < low:
        raise ConfigError(f"{flag} must be >= {low}, got {value}")


def _boolean(section: Any, name: str) -> None:
    if not isinstance(getattr(section, name), bool):
        raise ConfigError(f"{name} must be true or false, got {getattr(section, name)!r}")


@dataclass(frozen=True, kw_only=True)
class PlanConfig:
    """Which episodes exist, how long they run and how they are judged: what a resume must match."""

    scene: str = option(help="scene name (see 'indgen scenes')")
    task: str | None = option(None, "task of the scene, or 'all' (default: the scene's first task)")
    axes: tuple[str, ...] = option(help="axis or comma list of axes (see 'indgen axes')", flag="axis")
    levels: str | None = option(None, "inclusive range like -3:3 or list like 0,1,2 ({levels_default})")
    step: float | None = option(None, "override the axis's atomic step size", type=float)
    axes_preset: str | None = option(None, "shipped axes preset (paper, quick) or YAML path: steps and level ranges, "
                                     "compositions' components too", metavar="NAME|PATH")  # fmt: skip
    episodes: int = option(
        DEFAULT_EPISODES, "episodes per level (default 50; the cap with --adaptive)", type=int
    )
    seed: int = option(0, "run seed (default 0)", type=int)
    max_steps: int | None = option(None, "override the scene's episode length", type=int)
    data_regime: str = option("", "label of the training data regime, e.g. h-only or h+mg")
    gamma: float = option(0.2, "break threshold for the report (default 0.2)", type=float)
    allow_infeasible: bool = option(False, "evaluate levels the oracle did not certify")
    # level 0 shared by the axes whose level 0 is one environment: plan.shared_t0, engine/share.py
    share_t0: bool = option(True, "run level 0 once per task for the axes whose level 0 is the same environment; each "
                            "such axis reports those episodes as its own (episodes.parquet shared_from; default on, "
                            "--adaptive too)", action=argparse.BooleanOptionalAction)  # fmt: skip
    preregistered: str | None = option(None, "a plan.lock written by 'indgen budget --write': refuse to run anything "
                                       "that deviates from it", metavar="LOCK")  # fmt: skip
    # the scene family's options (Scene.scene_options), checked where the command's edge looks the family up
    split: str | None = option(None, SPLIT_HELP, metavar="{pretrain,target,all}")
    obj_registries: str | None = option(None, REGISTRIES_HELP, metavar="A,B")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        object.__setattr__(self, "levels", levels_text(self.levels))
        if not self.scene:
            raise ConfigError("--scene is required; list scenes with 'indgen scenes'")
        if not self.axes or not all(self.axes):
            raise ConfigError(
                "--axis is required, e.g. --axis pick_y or --axis pick_y,scale; see 'indgen axes'"
            )
        _at_least(self.episodes, 1, "--episodes")
        _boolean(self, "share_t0")
        _at_least(self.max_steps, 1, "--max-steps")
        if self.step is not None and not self.step > 0:
            raise ConfigError(f"--step must be positive, got {self.step}")
        if self.axes_preset is not None:
            from scenes.axes import load_preset as load_axes_preset  # lazy: start-up (scenes: numpy, 0.4 s)

            load_axes_preset(self.axes_preset)
        if not 0 < self.gamma <= 1:
            raise ConfigError(f"--gamma must be in (0, 1], got {self.gamma}")

    def scene_options(self) -> dict[str, str | None]:
        """The scene family's options the run sets (None: the family's default; ``Scene.scene_options``): the edge
        (CLI, API) configures the family with them once and hands it on."""
        return {"split": self.split, "obj_registries": self.obj_registries}


@dataclass(frozen=True, kw_only=True)
class PolicyConfig:
    """What runs and how: the policy spec, where it runs, how it is compiled, fed and reached."""

    spec: str = option(
        help="policy spec, e.g. lerobot:HUB_ID, openpi:ws://HOST:PORT, standin:oracle", name="policy"
    )
    device: str = option("cpu", "where in-process policies run: cpu, cuda, cuda:N (default cpu)")
    precision: str = option("fp32", "bf16: autocast forward (lerobot: policies)", choices=list(PRECISIONS))
    compile: str = option("off", "torch.compile the policy's per-call forward (lerobot: policies; reduce-overhead = "
                          "CUDA graphs, needs --device cuda); the first call compiles, ~/.cache/indgen/inductor keeps "
                          "it for the next run", choices=list(COMPILE_MODES))  # fmt: skip
    replan_steps: int | None = option(None, "actions executed per chunk (default: the policy's)", type=int)
    warmup_steps: int = option(0)  # control steps before the policy's first observation (API and YAML only)
    image_size: int | None = option(None, "rendered image side in pixels (default: the policy's)", type=int)
    trust_remote_code: bool = option(False, "allow checkpoints that ship their own code")
    server_patience: float = option(600.0, "seconds to keep reconnecting to an unreachable policy server before "
                                    "stopping (default 600)", type=float)  # fmt: skip

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if not self.spec:
            raise ConfigError("--policy is required, e.g. --policy standin:oracle or --policy lerobot:HUB_ID")
        _at_least(self.replan_steps, 1, "--replan-steps")
        _at_least(self.image_size, 1, "--image-size")
        if self.warmup_steps < 0:
            raise ConfigError("warmup_steps, max_retries and video_per_level must be >= 0")
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

    def options(self) -> dict[str, str]:
        """The spec options the run adds to ``--policy`` (only those not at their default, so families that
        do not take them still load)."""
        out = {"precision": self.precision} if self.precision != "fp32" else {}
        return out | ({"compile": self.compile} if self.compile != "off" else {})


@dataclass(frozen=True, kw_only=True)
class RunConfig:
    """Where and how the episodes execute and what the run keeps: none of it changes an episode's outcome."""

    out: str = option(help="run directory (re-run the same command to resume)")
    # 1 here; the command and the API default to the number of cores (config_from_values)
    workers: int | str = option(1, "worker processes (default: number of cores); with --backend ray the simulator "
                                "actors, or auto: as many as the cluster's CPUs hold, following nodes that join or "
                                "leave", type=workers_value)  # fmt: skip
    backend: str = option("local", "local worker processes or Ray (default local)", choices=["local", "ray"])
    pipeline: bool = option(False, "two environments per worker: one steps while the policy computes the other's "
                            "chunk (default off)", action=argparse.BooleanOptionalAction)  # fmt: skip
    max_retries: int = option(2)  # tries again of an episode that raised, before it is recorded as an error
    video: bool = option(False, "write mp4 videos of episodes")
    video_per_level: int = option(1, "videos per level when --video (default 1)", type=int)
    smoke: bool = option(False, "run an image policy on placeholder assets (RoboCasa's boxes) anyway; recorded as not "
                         "a measurement")  # fmt: skip
    allow_protocol_mismatch: bool = option(False, "resume a run although its protocol fingerprint changed in a field "
                                           "that changes outcomes (simulator versions, assets, horizon, cameras, "
                                           "render backend, policy conventions); the manifest lists it")  # fmt: skip

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if not self.out:
            raise ConfigError("--out is required: the run directory (re-run the same command to resume)")
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
        _boolean(self, "pipeline")
        if self.pipeline and self.backend == "ray":
            raise ConfigError(
                "--pipeline is for --backend local; with Ray, overlap by running 2 simulator actors per CPU "
                "(INDGEN_RAY_CPUS_PER_SIM=0.5)"
            )
        if self.max_retries < 0 or self.video_per_level < 0:
            raise ConfigError("warmup_steps, max_retries and video_per_level must be >= 0")


@dataclass(frozen=True, kw_only=True)
class AdaptiveConfig:
    """The stopping rule of an adaptive run (docs/adaptive.md); off when ``mode`` is None. Its cap, and
    until-failure's episodes per level, is the plan's ``episodes``, so ``EvalConfig`` checks the whole rule."""

    # "kstar" | "curve" | "until-failure": the stopping rule (docs/adaptive.md)
    mode: str | None = option(None, "run episodes in rounds and stop a level once a sequential test decides it (kstar: "
                              "also skip levels past a decided break; curve: decide every level); until-failure: the "
                              "paper's real-robot design, --episodes per level, levels in order until the first "
                              "observed rate < γ (no test); docs/adaptive.md", name="adaptive",
                              choices=list(ADAPTIVE_MODES))  # fmt: skip
    # indifference half-width around gamma
    delta: float = option(0.1, "indifference half-width around γ (default 0.1)", name="adaptive_delta",
                          type=float)  # fmt: skip
    # stated error rate of each verdict (alpha = beta)
    alpha: float = option(0.025, "error rate of each verdict, α = β (default 0.025)", name="adaptive_alpha",
                          type=float)  # fmt: skip
    round_size: int = option(5, "episodes between two looks (default 5)", type=int)

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if self.mode is not None and self.mode not in ADAPTIVE_MODES:
            raise ConfigError(f"--adaptive must be one of {', '.join(ADAPTIVE_MODES)}, got {self.mode!r}")


SECTIONS: dict[str, type] = {
    "plan": PlanConfig,
    "policy": PolicyConfig,
    "run": RunConfig,
    "adaptive": AdaptiveConfig,
}


OPTIONS: dict[str, Option] = {
    o.name: o
    for section, cls in SECTIONS.items()
    for f in dataclasses.fields(cls)
    for o in [Option(f.metadata["name"] or f.name, (section,), f)]
}
FLAG_FIELDS = set(OPTIONS)  # the flat names
# a flag's dest -> its option's flat name, where they differ (axis -> axes)
FLAG_NAMES = {o.flag: n for n, o in OPTIONS.items() if o.flag and o.flag != n}
# the manifest's "config" keys in the order runs have always recorded them (options added later follow)
RECORD_ORDER = ("policy", "scene", "axes", "out", "task", "levels", "step", "axes_preset", "episodes", "workers",
                "backend", "pipeline", "seed", "max_steps", "replan_steps", "warmup_steps", "image_size", "video",
                "video_per_level", "data_regime", "gamma", "allow_infeasible", "smoke", "trust_remote_code",
                "allow_protocol_mismatch", "max_retries", "device", "precision", "compile", "server_patience",
                "adaptive", "adaptive_delta", "adaptive_alpha", "round_size", "share_t0", "preregistered", "split",
                "obj_registries")  # fmt: skip
FLAT_DEFAULTS = {n: o.field.default for n, o in OPTIONS.items()}


@dataclass(frozen=True)
class EvalConfig:
    """Everything ``indgen evaluate`` needs, in four sections; validated on construction, never rewritten silently."""

    plan: PlanConfig
    policy: PolicyConfig
    run: RunConfig
    adaptive: AdaptiveConfig = field(default_factory=AdaptiveConfig)

    def __post_init__(self) -> None:
        for name, cls in SECTIONS.items():
            if not isinstance(getattr(self, name), cls):
                got = type(getattr(self, name)).__name__
                raise ConfigError(f"EvalConfig {name} must be a {cls.__name__}, got {got}; build it with "
                                  f"{cls.__name__}(...), or the whole config with EvalConfig.from_flat(...)")  # fmt: skip
        if self.adaptive.mode is not None:
            self.sequential_rule()  # validates the rule's parameters against the plan in one clear line each

    @classmethod
    def from_flat(cls, **values: Any) -> EvalConfig:
        """A config from flat option names (``policy``, ``scene``, ``axes``, ``adaptive_delta``...), each section's
        defaults for the rest; as ``dataclasses.asdict`` of the old flat config, e.g. a manifest's ``config``."""
        unknown = sorted(set(values) - FLAG_FIELDS)
        if unknown:
            raise ConfigError(f"unknown option(s) {', '.join(unknown)}; the options are evaluate's flags: see "
                              "'indgen evaluate --help'")  # fmt: skip
        by_section: dict[str, dict[str, Any]] = {name: {} for name in SECTIONS}
        for name, value in values.items():
            o = OPTIONS[name]
            by_section[o.section][o.field.name] = value
        # built in this order so that a config missing everything names --policy first, as the command always has
        policy = PolicyConfig(**by_section["policy"])
        plan = PlanConfig(**by_section["plan"])
        return cls(plan=plan, policy=policy, run=RunConfig(**by_section["run"]),
                   adaptive=AdaptiveConfig(**by_section["adaptive"]))  # fmt: skip

    def flat(self) -> dict[str, Any]:
        """Every option under its flat name, in the order manifests record them (the manifest's ``config``)."""
        values = {n: getattr(getattr(self, o.section), o.field.name) for n, o in OPTIONS.items()}
        order = [*RECORD_ORDER, *(n for n in values if n not in RECORD_ORDER)]
        return {n: values[n] for n in order}

    def override(self, **values: Any) -> EvalConfig:
        """This config with some options (flat names) changed, validated again."""
        return EvalConfig.from_flat(**{**self.flat(), **values})

    def policy_options(self) -> dict[str, str]:
        """The spec options the run adds to ``--policy`` (``PolicyConfig.options``)."""
        return self.policy.options()

    def sequential_rule(self):
        """The rule of an ``--adaptive`` run (its cap, or until-failure's episodes per level, is ``--episodes``)."""
        from indgen_vla.core.stats.sprt import make_rule  # lazy: start-up (numpy, scipy: 0.26 s)

        a = self.adaptive
        return make_rule(a.mode, self.plan.gamma, a.delta, a.alpha, a.round_size, self.plan.episodes)

    def plan_dict(
        self, tasks: list[str], levels: dict[str, list[int]], max_steps: int | None,
        task_steps: Mapping[str, Mapping[str, Mapping[str, float]]] | None = None,
    ) -> dict[str, Any]:  # fmt: skip
        """The part of the config that fixes which episodes exist and how they run (resume must match);
        ``task_steps``: each task's steps of an axis whose family resolves them per task (``ScenePlan``)."""
        p, pol = self.plan, self.policy
        plan = {
            "policy": pol.spec, "scene": p.scene, "tasks": tasks, "axes": list(p.axes),
            "levels": {a: levels[a] for a in p.axes}, "step": p.step, "episodes": p.episodes,
            "seed": p.seed, "max_steps": max_steps, "replan_steps": pol.replan_steps,
            "warmup_steps": pol.warmup_steps, "image_size": pol.image_size, "data_regime": p.data_regime,
        }  # fmt: skip
        if p.axes_preset is not None:  # only when set, so runs made before the option still resume
            plan["axes_preset"] = p.axes_preset
        if task_steps:  # only where a family's steps differ by task: a run made at other steps never resumes
            plan["task_steps"] = {
                a: {t: dict(v) for t, v in by_task.items()} for a, by_task in task_steps.items()
            }
        if self.adaptive.mode is not None:
            from indgen_vla.core.stats.sprt import plan_entry  # lazy: start-up (numpy, scipy)

            plan["adaptive"] = plan_entry(self.adaptive.mode, self.sequential_rule())
        return plan


def _did_you_mean(unknown: list[str], names: set[str] | list[str]) -> str:
    import difflib

    return ", ".join(f"{u} (did you mean {m[0]}?)" if (m := difflib.get_close_matches(u, names, 1)) else u
                     for u in unknown)  # fmt: skip


def _section_values(section: str, value: Any, where: str) -> dict[str, Any]:
    """A section given whole (a ``PlanConfig``..., or a preset's ``plan:`` mapping of its fields) as flat values."""
    cls = SECTIONS[section]
    if isinstance(value, cls):
        return {o.name: getattr(value, o.field.name) for o in OPTIONS.values() if o.section == section}
    if not isinstance(value, Mapping):
        raise ConfigError(f"{where}{section} must be a {cls.__name__} or a mapping of its fields, got "
                          f"{type(value).__name__}")  # fmt: skip
    # a section's keys: its field names (adaptive: mode, delta...) or the flat names (adaptive_delta, axis)
    names = {o.field.name: n for n, o in OPTIONS.items() if o.section == section}
    names |= {n: n for n in names.values()} | {
        f: n for f, n in FLAG_NAMES.items() if OPTIONS[n].section == section
    }
    keys = {str(k).replace("-", "_"): v for k, v in value.items()}
    unknown = sorted(k for k in keys if k not in names)
    if unknown:
        raise ConfigError(f"{where}unknown option(s) in {section}: {_did_you_mean(unknown, list(names))}")
    return {names[k]: v for k, v in keys.items()}


def _is_section(key: str, value: Any) -> bool:
    """``plan``/``run`` always name a section; ``policy``/``adaptive`` only when given whole (else the spec, the mode)."""
    return key in ("plan", "run") or (
        key in SECTIONS and (isinstance(value, Mapping) or dataclasses.is_dataclass(value))
    )


def load_config_preset(path: str) -> dict[str, Any]:
    """Read a YAML preset (flat ``option: value`` keys, or sections ``plan:``, ``policy:``, ``run:``,
    ``adaptive:``) as flat values; a bare name like ``libero_object`` is looked up in the shipped configs/paper/."""
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
    values: dict[str, Any] = {}
    for key, value in ((str(k).replace("-", "_"), v) for k, v in data.items()):
        if _is_section(key, value):
            values |= _section_values(key, value, f"--config {p}: ")
        else:
            values[FLAG_NAMES.get(key, key)] = value
    unknown = sorted(set(values) - FLAG_FIELDS)
    if unknown:
        raise ConfigError(f"--config {p}: unknown option(s) {_did_you_mean(unknown, FLAG_FIELDS)}")
    _check_numbers(values, p)
    return values


def _check_numbers(values: Mapping[str, Any], path: Path) -> None:
    """A preset's ``episodes: five`` is one line naming the file and the option (``typed_value``), as argparse's
    ``type`` checks a flag, instead of a TypeError traceback from a comparison below."""
    for name, value in values.items():
        if name in OPTIONS:
            try:
                typed_value(OPTIONS[name].field, value)
            except ConfigError as e:
                raise ConfigError(f"--config {path}: {e}") from None


def config_from_args(args: argparse.Namespace) -> EvalConfig:
    """Merge a YAML preset (if any) with the flags; flags given on the command line win."""
    return config_from_values(vars(args), getattr(args, "config", None))


def config_from_values(
    given: Mapping[str, Any], config: str | EvalConfig | None = None, *, strict: bool = False
) -> EvalConfig:
    """The one road from option values (parsed flags, or the Python API's keyword arguments, named like the flags)
    and an optional preset (a YAML name or path, or an ``EvalConfig``) to an ``EvalConfig``: a preset is read
    first, then every value that is set wins.
    A section given whole (``plan=PlanConfig(...)``, or a mapping of its fields) replaces the preset's, and flat
    values win over it. ``strict`` refuses names that are no option (the API's keywords; argparse has already
    refused bad flags)."""
    if isinstance(config, EvalConfig):
        values = config.flat()
    else:
        values = load_config_preset(config) if config else {}
    if strict:
        unknown = sorted(k for k in given if FLAG_NAMES.get(k, k) not in FLAG_FIELDS and k not in SECTIONS)
        if unknown:
            names = sorted(FLAG_FIELDS - set(FLAG_NAMES.values()) | set(FLAG_NAMES) | {"plan", "run"})
            raise ConfigError(f"unknown option(s) {_did_you_mean(unknown, names)}; the options are evaluate's flags: "
                              "see 'indgen evaluate --help'")  # fmt: skip
    for key, value in given.items():
        if _is_section(key, value):
            values |= _section_values(key, value, "")
    negatable = {n for n, o in OPTIONS.items() if o.negatable}
    for key, value in given.items():
        name = FLAG_NAMES.get(key, key)
        if _is_section(key, value) or name not in FLAG_FIELDS:
            continue
        if value is not None and (value is not False or name in negatable):
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
    return EvalConfig.from_flat(**values)


def plan_episodes(
    cfg: EvalConfig, tasks: list[str], levels: dict[str, list[int]], params: dict[tuple[str, str, int], float]
) -> list[EpisodeJob]:
    """``cfg``'s episodes over the given tasks, levels and parameters (``indgen_vla.core.protocol.plan.plan_jobs``), for callers
    that drive a backend without a resolved plan (benchmarks, tests); ``evaluate`` builds them with its plan."""
    p = cfg.plan
    return list(plan_jobs(p.scene, tasks, {a: levels[a] for a in p.axes}, params, p.episodes, p.seed, cfg.run.video,
                          cfg.run.video_per_level))  # fmt: skip
