"""``PolicySpec`` declared by hand (docs/extending.md): a value of the wrong type is one line naming the field, not a
TypeError mid-run or a camera per letter of a name; an integer image size is the square it names."""

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.interface import PolicySpec


def spec(**kw) -> PolicySpec:
    return PolicySpec(family="mine", name="mine:p", **kw)


def test_a_camera_name_given_as_text_and_wrong_types_are_one_line():
    for kw, line in [
        (
            {"cameras": "agentview"},
            "cameras must be a tuple of camera names, e.g. ('agentview',) or () for none",
        ),
        ({"chunk_size": "2"}, "chunk_size must be an integer, got '2'"),
        ({"replan_steps": 1.0}, "replan_steps must be an integer, got 1.0"),
        ({"batched": "yes"}, "batched must be true or false, got 'yes'"),
        ({"image_size": -1}, "image_size must be (H, W) in pixels or None, got (-1, -1)"),
        ({"image_size": (64,)}, "image_size must be (H, W) in pixels or None, got (64,)"),
    ]:
        with pytest.raises(ConfigError) as e:
            spec(**kw)
        assert str(e.value).startswith(f"policy mine:p: {line}") and "\n" not in str(e.value)


def test_sizes_and_counts_are_normalised_to_python_values():
    s = spec(cameras=["agentview"], image_size=64, chunk_size=np.int64(4), replan_steps=2)
    assert s.cameras == ("agentview",) and s.image_size == (64, 64) and type(s.chunk_size) is int
    assert spec(image_size=(np.int64(48), 64)).image_size == (
        48,
        64,
    )  # a checkpoint's own (H, W) stays as declared
    assert spec(cameras=(), image_size=None).image_size is None
