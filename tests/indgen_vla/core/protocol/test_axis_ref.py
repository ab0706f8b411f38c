"""An axis name is parsed once into an ``AxisRef``: components, held axis and level; a malformed one is one line."""

import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.axis_ref import AxisRef


def test_single_axes_compositions_and_held_axes_parse_into_their_parts():
    single = AxisRef.parse("pick_y")
    assert (single.components, single.held, single.held_level) == (("pick_y",), None, 0)
    assert single.ladder is single and single.axes() == ("pick_y",)
    comp = AxisRef.parse("pick_y+distractor")
    assert comp.components == ("pick_y", "distractor") and comp.held is None
    held = AxisRef.parse("pick_y+scale@goal_y=-3")
    assert (held.components, held.held, held.held_level) == (("pick_y", "scale"), "goal_y", -3)
    assert held.ladder == AxisRef.parse("pick_y+scale")
    assert held.axes() == ("pick_y", "scale", "goal_y")


def test_the_name_stays_the_key():
    """``str(ref)`` is the text as written: the key of plans, records, manifests and summaries."""
    for name in ("pick_y", "base_y", "pick_y+distractor", "pick_y@distractor=2", "scale@pick_y=-2"):
        ref = AxisRef.parse(name)
        assert str(ref) == name == ref.name and f"{ref}" == name
    assert AxisRef.parse(AxisRef.parse("pick_y")) == AxisRef.parse("pick_y")  # an entrance takes either
    assert hash(AxisRef.parse("pick_y@distractor=2")) == hash(AxisRef.parse("pick_y@distractor=2"))


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("", "name an axis or a composition, e.g. pick_y"),
        ("pick_y+", "write compositions as 'pick_y\\+distractor'"),
        ("+pick_y", "write compositions as 'pick_y\\+distractor'"),
        ("pick_y+pick_y", "repeats a component"),
        ("pick_y@distractor", "write a held axis as A@B=j"),
        ("@goal_y=1", "write a held axis as A@B=j"),
        ("pick_y@distractor=x", "held level 'x' is not an integer"),
        ("pick_y@distractor=0:3", "range form A@B=i:j is for --axis.*e.g. pick_y@distractor=0"),
        ("pick_y@goal_y+scale=1", "the held axis must be a single axis, e.g. pick_y@goal_y=1"),
        ("pick_y@goal_y=1@scale=2", "hold one axis at a time"),
    ],
)
def test_malformed_names_are_one_line_naming_the_fix(name, match):
    with pytest.raises(ConfigError, match=match) as e:
        AxisRef.parse(name)
    assert "\n" not in str(e.value)
