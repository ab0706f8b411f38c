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
