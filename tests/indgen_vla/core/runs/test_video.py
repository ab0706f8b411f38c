import numpy as np
import pytest

from indgen_vla.core.runs.video import write_mp4
from tests.fixtures.kill import writes_cut_short_after


def _frames(n=12, size=32):
    rng = np.random.default_rng(0)
    return [rng.integers(0, 255, (size, size, 3), dtype=np.uint8) for _ in range(n)]


def test_a_video_is_written_whole_under_its_name(tmp_path):
    path = write_mp4(_frames(), tmp_path / "videos" / "pick_y_L0_ep0_success.mp4")
    assert path.stat().st_size > 0
    assert [p.name for p in path.parent.iterdir()] == [path.name]


def test_an_encode_cut_short_leaves_no_video_under_its_final_name(tmp_path):
    """A kill or a full disk mid-encode used to leave a truncated mp4 with the episode's name."""
    path = tmp_path / "pick_y_L0_ep0_fail.mp4"
    with pytest.raises(OSError, match="disk full"), writes_cut_short_after(2048):
        write_mp4(_frames(60, 96), path)
    assert list(tmp_path.iterdir()) == []
