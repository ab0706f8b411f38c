"""``indgen setup robocasa --placeholders DST`` says what the tree holds, on a fresh tree and on a re-run alike
(it used to count only the files it wrote, so a re-run reported zeros). Needs the RoboCasa venv."""

import re

import pytest

from indgen_vla.app.cli import main
from tests.scenes.robocasa.test_robocasa import needs_venv

LINE = re.compile(
    r"(\d+) files: (\d+) placeholders written, (\d+) already there \((.*)\), (\d+) from RoboCasa"
)


def _summary(dst, capsys) -> tuple[int, int, int, str, int]:
    assert main(["setup", "robocasa", "--placeholders", str(dst)]) == 0
    out = capsys.readouterr().out
    m = LINE.search(out)
    assert m, out
    total, written, present, kinds, package = m.groups()
    return int(total), int(written), int(present), kinds, int(package)


@needs_venv
def test_a_rerun_on_an_existing_tree_says_what_is_already_there(placeholders, capsys):
    # the tree the RoboCasa tests share, written once by their fixture
    total, written, present, kinds, package = _summary(placeholders, capsys)
    assert total == sum(1 for p in placeholders.rglob("*") if p.is_file())
    assert written == 0 and present > 1000 and total == present + package + 1  # + the marker file
    assert "fixtures" in kinds and "objects" in kinds and "textures" in kinds


@needs_venv
@pytest.mark.slow  # writes a second tree (~5 s)
def test_a_fresh_tree_then_a_rerun_count_the_same_files(tmp_path, capsys):
    first = _summary(tmp_path / "tree", capsys)
    again = _summary(tmp_path / "tree", capsys)
    assert first[1] == again[2] > 0 and first[2] == again[1] == 0  # written once, then already there
    assert (first[0], first[3], first[4]) == (again[0], again[3], again[4])


def test_a_graspable_box_is_never_wider_than_the_hand_opens():
    """Tree 9: a graspable category's box at RoboCasa's scale is at most GRASPABLE_WIDTH across (the Panda's
    fingers open 7.7 cm); its shape is kept, other categories and narrow ones keep their size."""
    from scenes.robocasa.placeholder_tree.files import (
        ACCESSORY_HALF,
        GRASPABLE_WIDTH,
        OBJECT_HALF,
        object_half,
    )

    wine = {"graspable": True, "objaverse": {"scale": 1.6}}
    half = object_half(wine, "objaverse")
    assert 2 * half[0] * 1.6 == pytest.approx(GRASPABLE_WIDTH, abs=1e-4)
    assert half[2] / half[0] == pytest.approx(OBJECT_HALF[2] / OBJECT_HALF[0], rel=1e-3)
    fish = {"graspable": True, "aigen": {"scale": [1.35, 1.35, 2.0]}}  # per-axis: the wider side counts
    assert 2 * object_half(fish, "aigen")[0] * 1.35 == pytest.approx(GRASPABLE_WIDTH, abs=1e-4)
    assert object_half({"graspable": True, "objaverse": {"scale": 1.1}}, "objaverse") == OBJECT_HALF
    assert object_half({"graspable": False, "objaverse": {"scale": 2.0}}, "objaverse") == OBJECT_HALF
    cup = {"graspable": True, "lightwheel": {"scale": 1.0}}  # the registry's 8 cm models shrink too
    assert object_half(cup, "lightwheel", ACCESSORY_HALF)[0] == pytest.approx(GRASPABLE_WIDTH / 2)
    assert object_half(None, "lightwheel", ACCESSORY_HALF) == ACCESSORY_HALF
