"""``CertifyConfig``: what ``indgen certify`` does, in four frozen sections validated on construction (``plan``: which
levels of which scene, task and axis, resolved as ``evaluate`` resolves them; ``rule``: the certification rule and
its seed blocks; ``run``: where it runs and writes; ``check``: the command's other modes, ``--audit`` and
``--evaluation-states``). Every field's ``option`` metadata is its flag, its API keyword and its flat key
(``indgen_vla.app.config_fields``); where the idea is evaluate's (scene, task, axis, levels, step, axes preset,
episode length, the scene family's options) the field is evaluate's own (``option_like``)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from indgen_vla.app.config_fields import check_types, from_args, option, option_like, section
from indgen_vla.app.engine.config import PlanConfig, levels_text
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef

THRESHOLD = (
    0.95  # scenes.certificates.THRESHOLD (a test keeps them equal; this module stays light for --help)
)
FIRST_BLOCK = 1  # scenes.heldout.FIRST_BLOCK: the first seed block an attempt may draw
AUDIT_EPISODES = 20  # --audit's episodes per level when --episodes is not given
COMMAND = "certify"
# the flags in the order 'indgen certify --help' has always listed them
FLAG_ORDER = ("scene", "task", "axes", "levels", "step", "axes_preset", "episodes", "threshold", "seed", "audit",
              "evaluation_states", "run_dir", "held_out", "max_steps", "workers", "split", "obj_registries", "out")  # fmt: skip


def _axes(value: Any) -> tuple[str, ...]:
    """``--axis`` as given (a name, a comma list, or a sequence of names) as a tuple of names."""
    if value is None:
        return ()
    if isinstance(value, str | AxisRef):
        value = str(value).split(",")
    return tuple(str(a).strip() for a in value if str(a).strip())


@dataclass(frozen=True, kw_only=True)
class CertifyPlan:
    """Which levels of which (scene, task, axis) are certified, resolved as ``evaluate`` resolves them."""

    scene: str | None = option_like(PlanConfig, "scene", None, "scene to certify (see 'indgen scenes'); with --audit, "
                                    "a filter (a comma list)")  # fmt: skip
    task: str | None = option_like(
        PlanConfig, "task", help="task of the scene, or 'all' (default: the first task)"
    )
    axes: tuple[str, ...] = option_like(PlanConfig, "axes", (), "axis or composition, e.g. pick_y or "
                                        "pick_y+distractor (one per command)")  # fmt: skip
    levels: str | None = option_like(PlanConfig, "levels", help="inclusive range like -3:3 or list like 0,1,2 "
                                     "(default: the axis range)")  # fmt: skip
    step: float | None = option_like(PlanConfig, "step")
    axes_preset: str | None = option_like(PlanConfig, "axes_preset")
    max_steps: int | None = option_like(PlanConfig, "max_steps")
    split: str | None = option_like(PlanConfig, "split")
    obj_registries: str | None = option_like(PlanConfig, "obj_registries")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        object.__setattr__(self, "axes", _axes(self.axes))
        object.__setattr__(self, "levels", levels_text(self.levels))
        if len(self.axes) > 1:
            raise ConfigError(f"certify takes one axis or composition, got {len(self.axes)} "
                              f"({', '.join(self.axes)}); run certify once per axis")  # fmt: skip
        for a in self.axes:
            AxisRef.parse(a)  # a malformed name: one line, before any scene lookup
        if self.step is not None and not self.step > 0:
            raise ConfigError(f"--step must be positive, got {self.step}")
        if self.max_steps is not None and self.max_steps < 1:
            raise ConfigError(f"--max-steps must be >= 1, got {self.max_steps}")

    @property
    def axis(self) -> AxisRef | None:
        """The one axis (or composition) certified, parsed; None when none is given (``--audit``)."""
        return AxisRef.parse(self.axes[0]) if self.axes else None

    def scene_options(self) -> dict[str, str | None]:
        """The scene family's options (``Scene.scene_options``; None: the family's default)."""
        return {"split": self.split, "obj_registries": self.obj_registries}


@dataclass(frozen=True, kw_only=True)
class CertifyRule:
    """The rule a level is certified under and the seed blocks its attempts draw (scenes/certification/README.md)."""

    episodes: int | None = option(None, "most episodes per level (default: the 59 the rule needs; with --audit, 20)",
                                  type=int)  # fmt: skip
    threshold: float = option(THRESHOLD, "oracle success rate to certify (default 0.95)", type=float)
    seed: int = option(FIRST_BLOCK, "first seed block an attempt may draw (default 1; block 0 is burnt, and each "
                       "attempt takes a block the level never used: scenes/certification/README.md)",
                       type=int)  # fmt: skip
    held_out: bool = option(
        False, "also re-run, on a fresh seed block, the levels certified only in-sample (tuned)"
    )

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if self.episodes is not None and (isinstance(self.episodes, bool) or self.episodes < 1):
            raise ConfigError(f"--episodes must be >= 1, got {self.episodes}")
        if not 0 < self.threshold < 1:
            raise ConfigError(f"--threshold must be in (0, 1), got {self.threshold}; e.g. 0.95")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"--seed must be a seed block >= 0, got {self.seed!r}")
        if not isinstance(self.held_out, bool):
            raise ConfigError(f"held_out must be true or false, got {self.held_out!r}")


@dataclass(frozen=True, kw_only=True)
class CertifyRun:
    """Where the episodes run and the certificates go: none of it changes a certificate."""

    workers: int = option(1, "processes, one level each (physics only)", type=int)
    out: str | None = option(None, "folder for certify.json (default: where evaluate looks; resumes there)")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if isinstance(self.workers, bool) or not isinstance(self.workers, int) or self.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {self.workers!r}")
        if self.out is not None:
            object.__setattr__(self, "out", str(self.out))  # a Path from the API


@dataclass(frozen=True, kw_only=True)
class CertifyCheck:
    """The command's other modes: audit shipped certificates, or play the oracle on an evaluate run's states."""

    audit: int | None = option(None, "re-run N shipped certified levels drawn at random (--seed draws them) on fresh "
                               "held-out seeds, --episodes each (default 20), and say whether each still holds; "
                               "writes --out/audit.json if --out", type=int, metavar="N")  # fmt: skip
    evaluation_states: bool = option(False, "with --run DIR: play the oracle on the exact initial states of that "
                                     "evaluate run's episodes (--episodes n: episodes 0..n-1) and write "
                                     "DIR/oracle_states.json; 'indgen report DIR' then splits the policy's failures "
                                     "by whether the oracle solved the state")  # fmt: skip
    run_dir: str | None = option(None, "an evaluate run directory (--evaluation-states)", flag="run")

    def __post_init__(self) -> None:
        check_types(self)  # the API's and YAML's values: one line, not a TypeError below
        if self.audit is not None and (isinstance(self.audit, bool) or self.audit < 1):
            raise ConfigError(f"--audit must be >= 1 levels, got {self.audit}")
        if self.evaluation_states and not self.run_dir:
            raise ConfigError(
                "--evaluation-states needs --run DIR, the evaluate run whose initial states to play"
            )
        if self.evaluation_states and self.audit is not None:
            raise ConfigError("--audit and --evaluation-states are two modes; give one of them")


@dataclass(frozen=True, kw_only=True)
class CertifyConfig:
    """Everything ``indgen certify`` needs, in four sections; validated on construction."""

    plan: CertifyPlan = section(CertifyPlan)
    rule: CertifyRule = section(CertifyRule)
    run: CertifyRun = section(CertifyRun)
    check: CertifyCheck = section(CertifyCheck)

    def __post_init__(self) -> None:
        for name, cls in (
            ("plan", CertifyPlan),
            ("rule", CertifyRule),
            ("run", CertifyRun),
            ("check", CertifyCheck),
        ):
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"CertifyConfig {name} must be a {cls.__name__}, got "
                                  f"{type(getattr(self, name)).__name__}; build it with {cls.__name__}(...)")  # fmt: skip
        if self.mode == "certify" and (not self.plan.scene or not self.plan.axes):
            raise ConfigError(
                "indgen certify needs --scene and --axis (or --audit N to check shipped certificates)"
            )

    @property
    def mode(self) -> str:
        """``certify`` (levels of one axis), ``audit`` (shipped certificates) or ``evaluation_states``."""
        if self.check.audit is not None:
            return "audit"
        return "evaluation_states" if self.check.evaluation_states else "certify"

    @property
    def audit_episodes(self) -> int:
        """Episodes per audited level: ``--episodes``, else ``AUDIT_EPISODES``."""
        return self.rule.episodes or AUDIT_EPISODES

    @property
    def audit_scenes(self) -> list[str] | None:
        """``--scene`` as ``--audit``'s filter: a comma list of scene names (None: every scene)."""
        return [s.strip() for s in self.plan.scene.split(",") if s.strip()] if self.plan.scene else None


def certify_config(config: CertifyConfig | None = None, **options: Any) -> CertifyConfig:
    """The API's road to a ``CertifyConfig``: ``config`` (or the defaults) with the options given (flat names or
    flags, e.g. ``axis``, ``held_out``; None: not given) replacing its values; a name that is no option is one line."""
    if config is not None and not isinstance(config, CertifyConfig):
        raise ConfigError(f"config must be a CertifyConfig, got {type(config).__name__}; or pass the options as "
                          "keywords")  # fmt: skip
    return from_args(CertifyConfig, options, command=COMMAND, base=config)
