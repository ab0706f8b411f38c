"""Inductive axes of the built-in scenes: atomic successors over ``SceneSpec`` and their compositions.

Each axis owns one spec field and a step (the paper's defaults, docs/contracts.md's table). A successor is a
small frozen object: calling it returns a new spec with that field moved one step, nothing else.
Compositions such as ``pick_y+distractor`` apply every component once per level (one-sided
components always step forwards, so level -k of ``pick_y+distractor`` has k distractors). A held axis
``pick_y@distractor=2`` is pick_y's ladder started from T0 moved 2 steps along distractor: one row of the
2-D grid (pick_y level) x (distractor level), which a run covers as a family of such 1-D ladders.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError, UnknownNameError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.protocol.progression import AxisSpec, apply_level, check_strictly_harder
from indgen_vla.core.resources import config_dir
from scenes.spec import SceneSpec

# name -> (description, field, step, unit, signed, max_level)
_AXIS_TABLE: dict[str, tuple[str, str, float, str, bool, int]] = {
    "pick_y": ("translate the pick object along the table's y axis", "pick.y", 0.025, "m", True, 3),
    "goal_y": ("translate the goal receptacle along the table's y axis", "goal.y", 0.0367, "m", True, 3),
    "scale": (
        "uniformly scale the pick object (additive fraction of its size)",
        "pick.scale",
        0.0667,
        "fraction",
        True,
        3,
    ),
    "pick_x": (
        "translate the pick object along x by 1/5 of its valid region (0.20 m)",
        "pick.x",
        0.04,
        "m",
        False,
        5,
    ),
    "fixture_x": (
        "slide the goal fixture (cabinet) along its own x axis, the counter direction",
        "fixture_x",
        0.125,
        "m",
        False,
        3,
    ),
    "horizon": (
        "move the robot base back from the table: a longer reach and horizon",
        "robot_back",
        0.125,
        "m",
        False,
        2,
    ),
    "clutter": ("add one clutter object to the receptacle/cabinet", "clutter", 1.0, "objects", False, 4),
    "stack": (
        "raise the target block by one 0.25 in riser: a taller target stack",
        "stack_in",
        0.25,
        "in",
        False,
        4,
    ),
    "distractor": ("add one visual-only distractor (no collision)", "distractors", 1.0, "objects", False, 4),
}

# Other names of an axis (the name a benchmark's paper or code uses); the registry resolves them to the one axis,
# so a family lists the axis once. RoboCasa365's horizon axis moves the robot base along its y: ``base_y``.
AXIS_ALIASES: dict[str, str] = {"base_y": "horizon"}


def resolve_alias(name: str) -> str:
    """The axis ``name`` stands for (itself unless it is an alias)."""
    return AXIS_ALIASES.get(name, name)


def axis_components(axis: AxisRef) -> list[str]:
    """The single axes ``axis`` moves (aliases resolved): its components, then a held axis's held one."""
    return [resolve_alias(p) for p in axis.axes()]


# Axes that translate a jittered item: their support at level k is param +- spec.jitter.
JITTERED_FIELDS = ("pick.x", "pick.y", "goal.y")
INTEGER_FIELDS = ("clutter", "distractors")


def base_axis_names() -> list[str]:
    return sorted(_AXIS_TABLE)


def _base_axis(name: str) -> AxisSpec:
    name = resolve_alias(name)
    if name not in _AXIS_TABLE:
        raise UnknownNameError("axis", name, list(_AXIS_TABLE))
    desc, fld, step, unit, signed, max_level = _AXIS_TABLE[name]
    return AxisSpec(name, desc, fld, step, unit, signed, max_level)


def get_path(spec: Any, path: str) -> Any:
    """Read a dotted field path of a nested frozen dataclass."""
    obj = spec
    for part in path.split("."):
        obj = getattr(obj, part)
    return obj


def set_path(spec: Any, path: str, value: Any) -> Any:
    """A copy of ``spec`` with one dotted field replaced (the frozen originals are untouched)."""
    head, _, rest = path.partition(".")
    if not rest:
        return dataclasses.replace(spec, **{head: value})
    return dataclasses.replace(spec, **{head: set_path(getattr(spec, head), rest, value)})


@dataclass(frozen=True)
class Shift:
    """The atomic successor of a single axis: move its one field by ``direction`` steps."""

    axis: AxisSpec

    @property
    def fields(self) -> tuple[str, ...]:
        return (self.axis.field,)

    def __call__(self, spec: SceneSpec, direction: int = 1) -> SceneSpec:
        if direction not in (1, -1):
            raise ConfigError(f"axis {self.axis.name}: a successor step is +1 or -1, got {direction}")
        if direction < 0 and not self.axis.signed:
            raise ConfigError(f"axis {self.axis.name} is one-sided: levels run 0..{self.axis.max_level}")
        old = get_path(spec, self.axis.field)
        if self.axis.field in INTEGER_FIELDS:
            new: float | int = int(old) + direction * int(round(self.axis.step))
        else:
            new = round(float(old) + direction * self.axis.step, 9)
        return set_path(spec, self.axis.field, new)


@dataclass(frozen=True)
class Composite:
    """Several axes stepped together: level k applies each component k steps (|k| if one-sided)."""

    axis: AxisSpec
    parts: tuple[Shift, ...]

    @property
    def fields(self) -> tuple[str, ...]:
        return tuple(p.axis.field for p in self.parts)

    def __call__(self, spec: SceneSpec, direction: int = 1) -> SceneSpec:
        for part in self.parts:
            spec = part(spec, direction if part.axis.signed else 1)
        return spec


@dataclass(frozen=True)
class Held:
    """Axis ``inner``'s ladder from T0 moved ``at`` steps along ``held``: level k is held^at, then inner^k.

    Its ``axis`` is inner's (range, sign, step) named ``A@B=j``; a step moves inner's fields only.
    """

    axis: AxisSpec
    inner: Shift | Composite
    held: Shift
    at: int

    @property
    def fields(self) -> tuple[str, ...]:
        return self.inner.fields

    def start(self, base: SceneSpec) -> SceneSpec:
        """This ladder's level 0: the base moved ``at`` steps along the held axis."""
        return apply_level(base, self.held, self.at)

    def __call__(self, spec: SceneSpec, direction: int = 1) -> SceneSpec:
        return self.inner(spec, direction)


Successor = Shift | Composite | Held


def _validate_step(axis: AxisSpec, step: float) -> None:
    if not (isinstance(step, (int, float)) and math.isfinite(step) and step > 0):
        raise ConfigError(f"axis {axis.name}: step must be a positive number, got {step!r}")
    if axis.field in INTEGER_FIELDS and float(step) != round(step):
        raise ConfigError(f"axis {axis.name} counts {axis.unit}; its step must be a whole number, got {step}")


def merge_overrides(
    family: Mapping[str, Mapping] | None, preset: Mapping[str, Mapping] | None
) -> dict[str, dict]:
    """A family's own steps/ranges (``Scene.axis_overrides``) under a preset's: per axis, the preset's keys win."""
    out = {a: dict(v) for a, v in (family or {}).items()}
    for a, v in (preset or {}).items():
        out[a] = {**out.get(a, {}), **v}
    return out


def get_successor(
    axis: AxisRef, step: float | None = None, overrides: Mapping[str, Mapping] | None = None
) -> Successor:
    """The successor of ``axis`` (a single axis, a composition or a held axis), with an optional step override.

    ``overrides`` maps axis names to ``{"step": s, "max_level": K}`` (a YAML preset's ``axes``).
    ``step`` overrides a single axis's step; a composition's components take steps from presets only.
    """
    if axis.held is not None:
        return _held(axis, step, overrides)
    name = axis.name
    overrides = overrides or {}
    names = [resolve_alias(n) for n in axis.components]
    if len(set(names)) != len(names):  # base_y+horizon: one axis under two names
        raise ConfigError(f"axis {name!r} repeats a component")
    parts = []
    for n in names:
        spec = _base_axis(n)
        ov = dict(overrides.get(n, {}))
        if "step" in ov:
            _validate_step(spec, ov["step"])
        spec = dataclasses.replace(
            spec, step=float(ov.get("step", spec.step)), max_level=int(ov.get("max_level", spec.max_level))
        )
        parts.append(Shift(spec))
    if len(parts) == 1:
        if step is not None:
            _validate_step(parts[0].axis, step)
            return Shift(parts[0].axis.with_step(float(step)))
        return parts[0]
    if step is not None:
        raise ConfigError(
            f"axis {name!r} is a composition: --step applies to single axes only; set its components' steps "
            f"with --axes-preset NAME|PATH (a YAML like configs/axes/paper.yaml; shipped: "
            f"{', '.join(preset_names()) or 'none'})"
        )
    signed = any(p.axis.signed for p in parts)
    comp = AxisSpec(
        name=name,
        description="composition: "
        + "; ".join(f"{p.axis.name} ({p.axis.step:g} {p.axis.unit})" for p in parts),
        field="+".join(p.axis.field for p in parts),
        step=1.0,
        unit="level",
        signed=signed,
        max_level=min(p.axis.max_level for p in parts),
    )
    return Composite(comp, tuple(parts))


def _held(axis: AxisRef, step: float | None, overrides: Mapping[str, Mapping] | None) -> Held:
    """``A@B=j``: A's successor (``--step`` applies to it) over T0 moved j steps along B."""
    name, at = axis.name, axis.held_level
    inner_succ = get_successor(axis.ladder, step, overrides)
    held_succ = get_successor(AxisRef(axis.held, (axis.held,)), None, overrides)
    assert isinstance(held_succ, Shift)
    components = {p.axis.name for p in shifts(inner_succ)}
    if held_succ.axis.name in components:
        raise ConfigError(
            f"axis {name!r} holds {held_succ.axis.name}, which its ladder {axis.ladder} already moves; hold another "
            "axis"
        )
    h = held_succ.axis
    if not h.min_level <= at <= h.max_level:
        raise ConfigError(
            f"axis {name!r}: held level {at} is outside axis {h.name}'s range {h.min_level}..{h.max_level}; "
            f"hold it at one of {h.min_level}..{h.max_level}"
        )
    a = inner_succ.axis
    moved, unit = at * h.step, h.unit
    unit = unit[:-1] if abs(moved) == 1 and unit.endswith("s") else unit  # "1 object"
    spec = dataclasses.replace(
        a, name=name, description=f"{a.description}, with {h.name} held at level {at} ({moved:g} {unit})"
    )
    return Held(spec, inner_succ, held_succ, at)


def spec_at_level(base: SceneSpec, successor: Successor, level: int) -> SceneSpec:
    """T_k: the successor applied |k| times to the base spec, after checking k is in range."""
    axis = successor.axis
    if not axis.min_level <= level <= axis.max_level:
        raise ConfigError(
            f"level {level} is outside axis {axis.name}'s range {axis.min_level}..{axis.max_level}"
        )
    if isinstance(successor, Held):
        base = successor.start(base)
    return apply_level(base, successor, level)


def axis_param(spec: SceneSpec, successor: Successor, level: int) -> float:
    """The axis parameter of a level: the field's value (a composition reports its level; a held axis its ladder's)."""
    if isinstance(successor, Held):
        return axis_param(spec, successor.inner, level)
    if isinstance(successor, Composite):
        return float(level)
    return float(get_path(spec, successor.axis.field))


def level_support(spec: SceneSpec, successor: Successor, level: int) -> tuple[float, float]:
    """The closed interval the axis parameter can take at this level, T0 jitter included."""
    if isinstance(successor, Held):
        return level_support(spec, successor.inner, level)
    p = axis_param(spec, successor, level)
    if isinstance(successor, Shift) and successor.axis.field in JITTERED_FIELDS:
        return (p - spec.jitter, p + spec.jitter)
    return (p, p)


def shifts(successor: Successor) -> tuple[Shift, ...]:
    """The atomic successors ``successor`` moves: itself, a composition's components, then a held axis's held one."""
    if isinstance(successor, Held):
        return (*shifts(successor.inner), successor.held)
    return successor.parts if isinstance(successor, Composite) else (successor,)


def successor_steps(successor: Successor) -> dict[str, float]:
    """Each component's step (one entry for a single axis): what a certificate was made at. A held axis adds its
    held axis's step and ``held_level`` (its own certificate: its level 0 is not its ladder axis's T0)."""
    steps = {p.axis.name: float(p.axis.step) for p in shifts(successor)}
    return steps | ({"held_level": float(successor.at)} if isinstance(successor, Held) else {})


def presets_dir() -> Path:
    return config_dir("axes")


def preset_names() -> list[str]:
    d = presets_dir()
    return sorted(p.stem for p in d.glob("*.yaml")) if d.is_dir() else []


def load_preset(preset: str | Path) -> dict[str, dict[str, float]]:
    """Read an axes preset (``configs/axes``) (a name or a path): ``{axis: {"step": s, "max_level": K}}``."""
    import yaml

    path = Path(preset)
    if not path.suffix and not path.is_file():
        path = presets_dir() / f"{preset}.yaml"
        if not path.is_file():
            raise UnknownNameError("--axes-preset", str(preset), preset_names())
    if not path.is_file():
        raise ConfigError(
            f"--axes-preset {str(path)!r}: no such file; give a YAML path or one of: {', '.join(preset_names())}"
        )
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise ConfigError(
            f"axis preset {path}: invalid YAML ({e.__class__.__name__}); fix the file"
        ) from None
    axes = data.get("axes") if isinstance(data, dict) else None
    if not isinstance(axes, dict):
        raise ConfigError(
            f"axis preset {path}: expected a top-level 'axes:' mapping of axis -> {{step, max_level}}"
        )
    out: dict[str, dict[str, float]] = {}
    for name, body in axes.items():
        if str(name) not in _AXIS_TABLE:
            raise UnknownNameError(f"axis in preset {path}:", str(name), base_axis_names())
        axis = _base_axis(str(name))
        if not isinstance(body, dict) or not set(body) <= {"step", "max_level"}:
            raise ConfigError(f"axis preset {path}: axis {name} takes only 'step' and 'max_level'")
        if "step" in body:
            _validate_step(axis, body["step"])
        if "max_level" in body and (not isinstance(body["max_level"], int) or body["max_level"] < 1):
            raise ConfigError(f"axis preset {path}: {name}.max_level must be an integer >= 1")
        out[axis.name] = dict(body)
    return out


def check_progression(base: SceneSpec, successor: Successor) -> dict[int, tuple[float, float]]:
    """Condition 2 (strict: disjoint supports) over the axis's default range, T0 jitter included.

    A composition is checked component by component: each component's field, read off the composed
    spec at every level (jitter included), must leave the easier levels' support on its own. A held axis
    checks its held axis's ladder from T0, then its own ladder from the held level.
    """
    axis = successor.axis
    if isinstance(successor, Held):
        check_progression(base, successor.held)
    specs = {k: spec_at_level(base, successor, k) for k in axis.default_levels()}
    inner = successor.inner if isinstance(successor, Held) else successor
    if isinstance(inner, Composite):
        for part in inner.parts:
            name = f"{axis.name} (component {part.axis.name} at step {part.axis.step:g} {part.axis.unit})"
            check_strictly_harder({k: level_support(s, part, k) for k, s in specs.items()}, name)
    supports = {k: level_support(s, successor, k) for k, s in specs.items()}
    check_strictly_harder(supports, axis.name)
    return supports
