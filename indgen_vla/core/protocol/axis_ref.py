"""An axis as written (``pick_y``, ``pick_y+distractor``, ``pick_y@distractor=2``), parsed once into a frozen object.

Its text stays the axis's key in plans, records, manifests and summaries (``str(ref)``); what the text means (the
components a composition steps, the axis a held ladder holds and at which level) is read off the object, so no later
layer splits the name again. Which axis an alias stands for (``base_y``) is the scene layer's concern.
"""

from __future__ import annotations

from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError

_HELD_EXAMPLE = "e.g. pick_y@distractor=2: pick_y's levels, each with distractor at its level 2"


@dataclass(frozen=True)
class AxisRef:
    """A parsed axis name: the components its ladder steps together and, for ``A@B=j``, the held axis B and j.

    Attributes:
        name: the text as written, the axis's key everywhere (``str(ref)``).
        components: the single axes the ladder steps (one, or a composition's in order), aliases unresolved.
        held: the axis ``A@B=j`` holds (B), None for a plain axis or composition.
        held_level: j, the level B is held at (0 when nothing is held).
    """

    name: str
    components: tuple[str, ...]
    held: str | None = None
    held_level: int = 0

    @classmethod
    def parse(cls, text: str | AxisRef) -> AxisRef:
        """The object of ``text`` (an ``AxisRef`` as it is); one-line ConfigError for a malformed name."""
        if isinstance(text, AxisRef):
            return text
        if not isinstance(text, str) or not text:
            raise ConfigError(
                f"axis {text!r}: name an axis or a composition, e.g. pick_y or pick_y+distractor"
            )
        ladder, held, at = text, None, 0
        if "@" in text:
            ladder, held, at = _split_held(text)
        components = tuple(ladder.split("+"))
        if any(not c for c in components):
            raise ConfigError(f"axis {text!r}: write compositions as 'pick_y+distractor'")
        if len(set(components)) != len(components):
            raise ConfigError(f"axis {text!r} repeats a component")
        return cls(text, components, held, at)

    def __str__(self) -> str:
        return self.name

    @property
    def ladder(self) -> AxisRef:
        """The axis whose levels this one steps: itself, or a held axis's ``A`` on its own."""
        if self.held is None:
            return self
        return AxisRef(self.name.partition("@")[0], self.components)

    def axes(self) -> tuple[str, ...]:
        """Every single axis the name moves: its components, then the held one (aliases unresolved)."""
        return self.components + ((self.held,) if self.held is not None else ())


def _split_held(name: str) -> tuple[str, str, int]:
    """``("pick_y", "distractor", 2)`` of ``pick_y@distractor=2``; one-line ConfigError for a malformed one."""
    inner, _, rest = name.partition("@")
    held, eq, at = rest.partition("=")
    if "@" in rest:
        raise ConfigError(f"axis {name!r}: hold one axis at a time (A@B=j); for more, compose A as 'a+b'")
    if not inner or not held or not eq:
        raise ConfigError(f"axis {name!r}: write a held axis as A@B=j, {_HELD_EXAMPLE}")
    if ":" in at:
        raise ConfigError(
            f"axis {name!r}: the range form A@B=i:j is for --axis and a config's axes (it expands to one axis per "
            f"level); name one held level here, e.g. {inner}@{held}={at.partition(':')[0] or 0}"
        )
    try:
        level = int(at)
    except ValueError:
        raise ConfigError(
            f"axis {name!r}: the held level {at!r} is not an integer; {_HELD_EXAMPLE}"
        ) from None
    if "+" in held:
        raise ConfigError(
            f"axis {name!r}: the held axis must be a single axis, e.g. {inner}@{held.split('+')[0]}={level}"
        )
    return inner, held, level
