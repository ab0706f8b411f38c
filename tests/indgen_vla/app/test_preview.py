"""``indgen preview``: one tile per level, built and reset the way ``evaluate`` does; the object moves with the level,
the same level renders the same pixels twice, and bad input is one line with exit 2."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from indgen_vla.app.cli import main
from indgen_vla.app.preview import PreviewRequest, level_caption, render_level, write_preview
from indgen_vla.core.errors import ConfigError
from scenes.family import get_scene
from scenes.planning import resolve_scene_plan
from tests.scenes.conftest import mini  # noqa: F401 (the LIBERO miniature asset fixture)


def test_tiles_follow_the_level_and_repeat_exactly(tmp_path):
    req = PreviewRequest(get_scene("pick_place"), ("pick_y",), tmp_path / "sheet.png", levels="-1,1", size=64)
    path, tiles = write_preview(req)
    assert [(t.axis, t.level) for t in tiles] == [("pick_y", -1), ("pick_y", 1)]
    assert all(t.image.shape == (64, 64, 3) and t.image.dtype == np.uint8 for t in tiles)
    assert tiles[0].caption == "k = -1\npick_y = -0.155 m"  # pick_place's T0 y is -0.13 m, 2.5 cm a step
    moved = np.abs(tiles[0].image.astype(int) - tiles[1].image.astype(int)).max(axis=2) > 30
    assert 10 < moved.sum() < 0.1 * moved.size  # the milk carton moved 5 cm; the rest of the scene did not
    plan = resolve_scene_plan(get_scene("pick_place"), None, ["pick_y"], "1")
    again = render_level(plan, "milk", "pick_y", 1, req, "agentview")
    assert np.array_equal(again, tiles[1].image)  # the same episode seed: the same initial state and pixels
    with Image.open(path) as im:
        assert im.format == "PNG" and im.size[0] > im.size[1] > 64


def test_captions_of_compositions_name_every_component():
    plan = resolve_scene_plan(get_scene("pick_place"), None, ["pick_y+distractor", "scale"], "-2:2")
    assert level_caption(plan, "milk", "pick_y+distractor", -2) == (
        "k = -2\npick_y = -0.180 m\ndistractor = 2 objects")  # fmt: skip
    assert level_caption(plan, "milk", "scale", 0) == "k = 0\nscale = ×1.000"


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--axis", "pick_q"], "unknown axis 'pick_q'; did you mean"),
        (["--axis", "pick_y", "--levels", "5:6"], "level 5 is outside axis pick_y's range -3..3"),
        (["--axis", "stack"], "unknown axis of scene pick_place 'stack'"),
        (["--axis", "pick_y", "--camera", "top"], "unknown camera(s) ['top']"),
        (["--axis", "pick_y", "--task", "all"], "--task all: a preview shows one task"),
        (["--axis", "pick_y", "--task", "mlik"], "did you mean 'milk'"),
        (["--axis", "pick_y", "--size", "4"], "--size 4 must lie in 8..2048"),
        (
            ["--axis", "pick_y", "--out", "sheet.gif"],
            "or .jpg; end the name with one of them, e.g. --out sheet.png",
        ),
        (["--axis", "pick_y", "--out", "/proc/no/sheet.png"], "cannot write --out /proc/no/sheet.png"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(argv, says, tmp_path, capsys):
    out = [] if "--out" in argv else ["--out", str(tmp_path / "sheet.png")]
    assert main(["preview", "--scene", "pick_place", *argv, *out]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and says in err and err.count("\n") == 1 and "Traceback" not in err
    assert not list(tmp_path.iterdir())  # nothing written


def test_request_is_checked_on_construction():
    with pytest.raises(ConfigError, match="--episode -1"):
        PreviewRequest(get_scene("pick_place"), ("pick_y",), Path("x.png"), episode=-1)
    with pytest.raises(ConfigError, match="--axis is empty"):
        PreviewRequest(get_scene("pick_place"), (), Path("x.png"))


@pytest.mark.slow
def test_libero_miniature_levels_and_cli(mini, tmp_path, capsys):  # noqa: F811
    """LIBERO on the miniature assets: the fixed initial state of the episode, the pick object moved per level."""
    out = tmp_path / "libero.png"
    assert main(["preview", "--scene", "libero_object", "--axis", "pick_y", "--levels", "-1,1", "--size", "64",
                 "--out", str(out)]) == 0  # fmt: skip
    assert "2 level(s) of libero_object" in capsys.readouterr().out and out.stat().st_size > 1000
    req = PreviewRequest(get_scene("libero_object"), ("pick_y",), out, levels="-1,1", size=64)
    _, tiles = write_preview(req)
    assert not np.array_equal(tiles[0].image, tiles[1].image)
    plan = resolve_scene_plan(get_scene("libero_object"), None, ["pick_y"], "1")
    assert np.array_equal(render_level(plan, plan.tasks[0], "pick_y", 1, req, "agentview"), tiles[1].image)
