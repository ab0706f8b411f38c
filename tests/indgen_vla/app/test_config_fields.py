"""Commands' configs: flags, API keywords and flat records made from one field definition."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass

import pytest

from indgen_vla.app.config_fields import (
    add_flags,
    check_types,
    flat_options,
    from_args,
    from_flat,
    option,
    option_like,
    section,
    to_flat,
)
from indgen_vla.core.errors import ConfigError


@dataclass(frozen=True, kw_only=True)
class Inner:
    episodes: int = option(10, "episodes per level", type=int)
    quiet: bool = option(False, "say less")
    secret: str = option("x")  # no help line: API and YAML only


@dataclass(frozen=True, kw_only=True)
class Outer:
    scene: str = option(help="scene name")
    axes: tuple[str, ...] = option((), "axis list", flag="axis", type=lambda s: tuple(s.split(",")))
    inner: Inner = section(Inner)

    def __post_init__(self) -> None:
        if not self.scene:
            raise ConfigError("--scene is required")


def test_flat_options_walk_sections_in_order():
    opts = flat_options(Outer)
    assert list(opts) == ["scene", "axes", "episodes", "quiet", "secret"]
    assert opts["episodes"].path == ("inner",)
    assert opts["axes"].flag == "axis" and opts["secret"].flag is None


def test_parser_to_config_and_back():
    p = argparse.ArgumentParser()
    add_flags(p, Outer)
    args = p.parse_args(["--scene", "pick_place", "--axis", "a,b", "--episodes", "3"])
    cfg = from_args(Outer, args, command="demo")
    assert cfg == Outer(scene="pick_place", axes=("a", "b"), inner=Inner(episodes=3))
    assert to_flat(cfg) == {
        "scene": "pick_place",
        "axes": ("a", "b"),
        "episodes": 3,
        "quiet": False,
        "secret": "x",
    }
    assert from_flat(Outer, to_flat(cfg), command="demo") == cfg
    with pytest.raises(SystemExit):
        p.parse_args(["--secret", "y"])  # no help line, no flag


def test_api_keywords_are_strict_and_validated():
    assert from_args(Outer, {"scene": "s", "episodes": 2, "quiet": None}, command="demo").inner.episodes == 2
    with pytest.raises(ConfigError, match="unknown option 'episode' for demo; did you mean 'episodes'"):
        from_args(Outer, {"scene": "s", "episode": 2}, command="demo")
    with pytest.raises(ConfigError, match="--scene is required"):
        from_args(Outer, {"scene": ""}, command="demo")
    with pytest.raises(ConfigError, match="unknown option"):
        from_flat(Outer, {"scene": "s", "nope": 1}, command="demo")


def test_a_name_defined_twice_is_refused():
    @dataclass(frozen=True, kw_only=True)
    class Twice:
        episodes: int = option(1, "x")
        inner: Inner = section(Inner)

    with pytest.raises(TypeError, match="option 'episodes' is defined twice"):
        flat_options(Twice)


def test_option_like_is_another_configs_option_with_changes():
    @dataclass(frozen=True, kw_only=True)
    class Other:
        axes: tuple[str, ...] = option_like(Outer, "axes", help="one axis")
        scene: str = option_like(Outer, "scene")
        episodes: int = option_like(Inner, "episodes", 3)

    opts = flat_options(Other)
    assert opts["axes"].flag == "axis" and opts["axes"].field.metadata["help"] == "one axis"
    assert opts["axes"].field.metadata["argparse"] == flat_options(Outer)["axes"].field.metadata["argparse"]
    assert Other(scene="s").episodes == 3 and opts["episodes"].field.metadata["help"] == "episodes per level"
    with pytest.raises(TypeError):
        Other(episodes=1)  # scene has no default, as in Outer: required


@dataclass(frozen=True, kw_only=True)
class Typed:
    n: int = option(3, "episodes", type=int)
    rate: float = option(0.5, "a rate", type=float)
    limit: int | None = option(None, "a cap", type=int)
    retries: int = option(2)  # no flag: its default's type
    video: bool = option(False, "record")
    name: str = option("a", "a name")

    def __post_init__(self) -> None:
        check_types(self)


def test_check_types_refuses_wrong_types_in_one_line_and_keeps_numpy_out_of_records():
    """Values the Python API and YAML hand over unparsed: a wrong type is one line naming the flag and the value;
    NumPy scalars become Python ones (a manifest is JSON); an int where a float is meant stays as given."""
    import numpy as np

    for kwargs, line in [({"n": "2"}, "--n must be a whole number, got '2' (str); e.g. --n 3"),
                         ({"n": 2.0}, "--n must be a whole number, got 2.0 (float); e.g. --n 3"),
                         ({"n": True}, "--n must be a whole number, got True (bool); e.g. --n 3"),
                         ({"rate": "0.2"}, "--rate must be a number, got '0.2' (str); e.g. --rate 0.5"),
                         ({"limit": 1.5}, "--limit must be a whole number, got 1.5 (float)"),
                         ({"retries": "2"}, "retries must be a whole number, got '2' (str); e.g. retries=2"),
                         ({"video": "yes"}, "--video must be true or false, got 'yes' (str)")]:  # fmt: skip
        with pytest.raises(ConfigError, match=f"^{re.escape(line)}$"):
            Typed(**kwargs)
    t = Typed(n=np.int64(4), rate=np.float32(0.25), video=np.bool_(True), limit=None, name="b")
    assert (t.n, t.rate, t.video) == (4, 0.25, True) and type(t.n) is int and type(t.rate) is float
    assert type(t.video) is bool and type(Typed(rate=1).rate) is int
