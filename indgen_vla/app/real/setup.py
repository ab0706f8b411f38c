"""The real set-up's YAML: the task, what stays fixed, and per axis what the operator changes at each level.

An axis is given either as a uniform step (``start``, ``step``, ``max_level`` and a ``setup`` text template) or
as an explicit list of levels (``levels: [{param, setup}, ...]``) when the physical objects come in a series
(a set of bowls). Either way level k's parameter must lie strictly beyond every easier level's (the paper's
condition 2), and ``change: cheap|slow`` says whether levels may be interleaved or must be run in blocks.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.resources import config_dir
from indgen_vla.core.stats.sprt import MODES

CHANGES = ("cheap", "slow")  # cheap: interleave levels (counters drift); slow: run each level as one block
ORDERS = ("interleaved", "blocked")
_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
_TOP_KEYS = {"name", "task", "instruction", "robot", "base", "placements", "axes", "stopping"}
_AXIS_KEYS = {"description", "unit", "change", "start", "step", "max_level", "setup", "setup_at", "levels"}


def _where(source: str) -> str:
    return f"set-up {source}"


@dataclass(frozen=True)
class RealLevel:
    """One level of a real axis: its physical parameter and what the operator sets up."""

    level: int
    param: float
    setup: str


@dataclass(frozen=True)
class RealAxis:
    """A physical axis: levels 0..K with strictly increasing parameters in ``unit``."""

    name: str
    description: str
    unit: str
    levels: tuple[RealLevel, ...]
    change: str = "cheap"

    def __post_init__(self) -> None:
        if not _NAME.match(self.name or ""):
            raise ConfigError(f"axis name {self.name!r} must be letters, digits, '_', '.' or '-'")
        if self.change not in CHANGES:
            raise ConfigError(f"axis {self.name}: change must be 'cheap' or 'slow', got {self.change!r}")
        if not self.unit:
            raise ConfigError(f"axis {self.name}: give its unit (e.g. unit: in)")
        if len(self.levels) < 2:
            raise ConfigError(f"axis {self.name}: needs level 0 and at least one harder level")
        for i, lv in enumerate(self.levels):
            if lv.level != i:
                raise ConfigError(
                    f"axis {self.name}: levels must be numbered 0, 1, 2, ... (got {lv.level} at {i})"
                )
            if not math.isfinite(lv.param):
                raise ConfigError(
                    f"axis {self.name}: level {i}'s param must be a finite number, got {lv.param}"
                )
            if not lv.setup.strip():
                raise ConfigError(f"axis {self.name}: level {i} needs a set-up text (what the operator does)")
            if i and not lv.param > self.levels[i - 1].param:
                raise ConfigError(
                    f"axis {self.name}: level {i}'s param {lv.param:g} must exceed level {i - 1}'s "
                    f"{self.levels[i - 1].param:g} (each level strictly harder, paper condition 2)"
                )

    @property
    def max_level(self) -> int:
        return len(self.levels) - 1

    def level(self, k: int) -> RealLevel:
        if not 0 <= k <= self.max_level:
            raise ConfigError(f"level {k} is outside axis {self.name}'s range 0..{self.max_level}")
        return self.levels[k]

    def param_text(self, k: int) -> str:
        return f"{self.levels[k].param:g} {self.unit}"

    def as_axis_dict(self) -> dict[str, Any]:
        """The manifest's ``axes`` entry, the shape ``indgen report`` reads (one-sided; base and mean step)."""
        p0, pk = self.levels[0].param, self.levels[-1].param
        return {
            "name": self.name, "description": self.description, "field": "real", "unit": self.unit,
            "step": (pk - p0) / self.max_level, "signed": False, "max_level": self.max_level, "base": p0,
            "params": {str(lv.level): lv.param for lv in self.levels},
        }  # fmt: skip


@dataclass(frozen=True)
class RealSetup:
    """A real task: instruction, fixed conditions, episode placements, and its axes."""

    name: str
    task: str
    instruction: str
    axes: tuple[RealAxis, ...]
    robot: str = ""
    base: str = ""
    placements: tuple[str, ...] = ()
    # ``indgen real plan``'s default --adaptive (the paper's presets: until-failure)
    stopping: str | None = None
    source: str = ""
    text: str = field(default="", repr=False)  # the YAML as written, recorded in the manifest

    def __post_init__(self) -> None:
        for what in ("name", "task"):
            if not _NAME.match(getattr(self, what) or ""):
                raise ConfigError(
                    f"{_where(self.source)}: {what} {getattr(self, what)!r} must be letters, digits, '_', '.' or '-'"
                )
        if not self.instruction.strip():
            raise ConfigError(f"{_where(self.source)}: give the task's instruction (what the policy is told)")
        if not self.axes:
            raise ConfigError(f"{_where(self.source)}: define at least one axis under 'axes:'")
        if any(not p.strip() for p in self.placements):
            raise ConfigError(f"{_where(self.source)}: placements must be non-empty texts")
        if self.stopping is not None and self.stopping not in MODES:
            raise ConfigError(f"{_where(self.source)}: stopping must be one of {', '.join(MODES)} (or left out: "
                              f"every level's episodes), got {self.stopping!r}")  # fmt: skip

    def axis(self, name: str | None) -> RealAxis:
        """The named axis; with None, the only one (or a one-line error listing them)."""
        names = [a.name for a in self.axes]
        if name is None:
            if len(names) > 1:
                raise ConfigError(f"set-up {self.name} has axes {', '.join(names)}; choose one with --axis")
            return self.axes[0]
        for a in self.axes:
            if a.name == name:
                return a
        raise UnknownNameError(f"axis of set-up {self.name}", name, names)

    def placement(self, episode: int) -> str:
        """Episode i's start placement (the same at every level and in every run: a paired design)."""
        return self.placements[episode % len(self.placements)] if self.placements else ""


def presets() -> list[str]:
    """Names of the shipped set-ups (``configs/real/*.yaml``)."""
    d = config_dir("real")
    return sorted(p.stem for p in d.glob("*.yaml")) if d.exists() else []


def load_setup(name_or_path: str) -> RealSetup:
    """Read a set-up YAML from a path, or a shipped preset by name (``stack``, ``scale``)."""
    import yaml

    p = Path(name_or_path)
    if not p.exists() and not p.suffix and (config_dir("real") / f"{name_or_path}.yaml").exists():
        p = config_dir("real") / f"{name_or_path}.yaml"
    if not p.is_file():
        raise ConfigError(
            f"--setup {name_or_path}: no such file; give a YAML path or a preset ({', '.join(presets()) or 'none'})"
        )
    text = p.read_text()
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ConfigError(f"--setup {p}: invalid YAML ({type(e).__name__}); fix the file") from None
    return setup_from_dict(data, source=str(p), text=text)


def _unknown(keys: set[str], known: set[str], where: str) -> None:
    bad = sorted(keys - known)
    if bad:
        import difflib

        hints = [
            f"{b} (did you mean {m[0]}?)" if (m := difflib.get_close_matches(b, known, 1)) else b for b in bad
        ]
        raise ConfigError(f"{where}: unknown key(s) {', '.join(hints)}")


def _text(value: Any, where: str) -> str:
    if value is None:
        return ""
    if not isinstance(value, str | int | float):
        raise ConfigError(f"{where} must be text, got {type(value).__name__}")
    return str(value).strip()


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{where} must be a number, got {value!r}")
    return float(value)


def _axis_from_dict(name: str, d: Any, source: str) -> RealAxis:
    where = f"{_where(source)}: axis {name}"
    if not isinstance(d, Mapping):
        raise ConfigError(f"{where} must be a mapping (description, unit, change, and start/step or levels)")
    _unknown(set(d), _AXIS_KEYS, where)
    if "levels" in d and ("step" in d or "start" in d):
        raise ConfigError(f"{where}: give either 'levels' (a list) or 'start'/'step'/'max_level', not both")
    if "levels" in d:
        raw = d["levels"]
        if not isinstance(raw, list):
            raise ConfigError(f"{where}: 'levels' must be a list of {{param, setup}}")
        levels = []
        for k, item in enumerate(raw):
            if not isinstance(item, Mapping) or set(item) - {"param", "setup"} or "param" not in item:
                raise ConfigError(f"{where}: level {k} must be a mapping with 'param' and 'setup'")
            levels.append(RealLevel(k, _number(item["param"], f"{where} level {k} param"),
                                    _text(item.get("setup"), f"{where} level {k} setup")))  # fmt: skip
    else:
        for key in ("step", "max_level", "setup"):
            if key not in d:
                raise ConfigError(f"{where}: missing '{key}' (or list the levels under 'levels:')")
        start, step = _number(d.get("start", 0.0), f"{where} start"), _number(d["step"], f"{where} step")
        if not step > 0:
            raise ConfigError(f"{where}: step must be positive, got {step:g}")
        kmax = d["max_level"]
        if isinstance(kmax, bool) or not isinstance(kmax, int) or kmax < 1:
            raise ConfigError(f"{where}: max_level must be an integer >= 1, got {kmax!r}")
        at = d.get("setup_at") or {}
        if not isinstance(at, Mapping) or any(not isinstance(k, int) or not 0 <= k <= kmax for k in at):
            raise ConfigError(f"{where}: setup_at must map levels 0..{kmax} to texts")
        template = _text(d["setup"], f"{where} setup")
        levels = []
        for k in range(kmax + 1):
            param = round(start + k * step, 12)
            if k in at:
                txt = _text(at[k], f"{where} setup_at {k}")
            else:
                try:
                    txt = template.format(level=k, param=param, unit=_text(d.get("unit"), "unit"), step=step)
                except (KeyError, IndexError, ValueError) as e:
                    raise ConfigError(
                        f"{where}: setup template {template!r} is invalid ({e}); use {{level}}, {{param}}, "
                        "{unit} or {step}"
                    ) from None
            levels.append(RealLevel(k, param, txt))
    return RealAxis(name=str(name), description=_text(d.get("description"), f"{where} description"),
                    unit=_text(d.get("unit"), f"{where} unit"), levels=tuple(levels),
                    change=_text(d.get("change", "cheap"), f"{where} change"))  # fmt: skip


def setup_from_dict(data: Any, source: str = "<dict>", text: str = "") -> RealSetup:
    """Validate a parsed set-up YAML into a ``RealSetup`` (one clear line per problem)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"{_where(source)}: expected a mapping with name, task, instruction and axes")
    _unknown(set(data), _TOP_KEYS, _where(source))
    for key in ("name", "task", "instruction", "axes"):
        if key not in data:
            raise ConfigError(f"{_where(source)}: missing '{key}'")
    if not isinstance(data["axes"], Mapping) or not data["axes"]:
        raise ConfigError(f"{_where(source)}: 'axes' must map axis names to their levels")
    placements = data.get("placements") or []
    if not isinstance(placements, list):
        raise ConfigError(
            f"{_where(source)}: 'placements' must be a list of texts (episode i uses item i mod n)"
        )
    return RealSetup(
        name=_text(data["name"], "name"), task=_text(data["task"], "task"),
        instruction=_text(data["instruction"], "instruction"),
        axes=tuple(_axis_from_dict(str(n), d, source) for n, d in data["axes"].items()),
        robot=_text(data.get("robot"), "robot"), base=_text(data.get("base"), "base"),
        placements=tuple(_text(p, "placement") for p in placements), source=source, text=text,
        stopping=data.get("stopping"),
    )  # fmt: skip
