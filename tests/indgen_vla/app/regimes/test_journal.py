"""A JournaledDataset killed mid-episode resumes into the very files of an uninterrupted one (tiny synthetic episodes
through lerobot's real writer; the process dies by os._exit, which like SIGKILL runs no finalizer)."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("lerobot")

from indgen_vla.app.regimes.journal import EPISODES_SIDECAR, JOURNAL, JournaledDataset, read_episode_sidecar  # noqa: E402
from tests.fixtures.datasets import dataset_digest  # noqa: E402

FEATURES = {
    "observation.images.cam": {
        "dtype": "image",
        "shape": (4, 4, 3),
        "names": ["height", "width", "channels"],
    },
    "observation.state": {"dtype": "float32", "shape": (2,), "names": None},
    "action": {"dtype": "float32", "shape": (1,), "names": None},
}
LEROBOT = {
    "repo_id": "local/journal",
    "fps": 20,
    "features": FEATURES,
    "use_videos": False,
    "video_backend": "pyav",
}
DIE = "INDGEN_TEST_JOURNAL_DIE"  # "EPISODE:WHERE": the writer's process exits there (WHERE: mid_frames, after_save)


def write(ds, payload: dict) -> dict:
    """Episode ``i``: 3 frames whose values derive from ``i``, tasks alternating (a new task after a checkpoint)."""
    i = payload["i"]
    die_at, _, where = os.environ.get(DIE, ":").partition(":")
    for f in range(3):
        if die_at == str(i) and where == "mid_frames" and f == 2:
            os._exit(0)
        ds.add_frame({"observation.images.cam": np.full((4, 4, 3), 10 * i + f, np.uint8),
                      "observation.state": np.array([i, f], np.float32), "action": np.array([i], np.float32),
                      "task": f"task {i % 3}"})  # fmt: skip
    ds.save_episode()
    if die_at == str(i) and where == "after_save":
        os._exit(0)
    return {"episode_index": ds.num_episodes - 1, "i": i}


KW = {"repo_id": "local/journal", "record": "meta/args.json", "write": write, "every": 2}


def record(out: Path, episodes: range) -> JournaledDataset:
    """Create (or reopen) ``out`` and add ``episodes``."""
    if out.exists():
        dataset = JournaledDataset.reopen(out, **KW)
    else:
        dataset = JournaledDataset.create(out, {"args": 1}, LEROBOT, **KW)
    for i in episodes:
        dataset.add({"i": i})
    return dataset


@pytest.fixture(scope="module")
def whole(tmp_path_factory) -> Path:
    """Episodes 0-4 recorded without interruption."""
    out = tmp_path_factory.mktemp("journal") / "whole"
    record(out, range(5)).complete({"done": True})
    return out


# each a subprocess that imports lerobot and records (~15 s): both under slow, for the default suite's budget
@pytest.mark.slow
@pytest.mark.parametrize("where", ["mid_frames", "after_save"])
def test_a_dataset_killed_mid_episode_resumes_into_the_uninterrupted_files(whole, tmp_path, where):
    import pyarrow.parquet as pq
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    killed = tmp_path / "killed"
    code = f"from tests.indgen_vla.app.regimes.test_journal import record\nrecord(__import__('pathlib').Path({str(killed)!r}), range(5))"
    env = {**os.environ, DIE: f"3:{where}"}
    subprocess.run(
        [sys.executable, "-c", code], env=env, check=True, timeout=120, cwd=Path(__file__).parents[4]
    )
    # what the kill left: episodes 0-1 checkpointed, 2 saved, 3 staged (and half saved); lerobot's open Parquet
    # file of episodes 2-3 has no footer, yet info.json counts them
    assert [p.name for p in sorted((killed / JOURNAL).iterdir())] == [
        "checkpoint-000002", "ep-000002.pkl", "ep-000003.pkl"]  # fmt: skip
    assert len(read_episode_sidecar(killed)) == 3
    with pytest.raises(Exception, match="footer|magic|size"):
        pq.read_metadata(killed / "data/chunk-000/file-001.parquet")
    if where == "after_save":
        assert json.loads((killed / "meta/info.json").read_text())["total_episodes"] == 4
    else:
        assert any((killed / "images").rglob("*.png"))  # lerobot's staged frames of the unsaved episode
    (killed / JOURNAL / ".ep-000004.pkl.k1ll3d").write_bytes(b"half")  # a staging cut short: ignored

    resumed = record(killed, range(4, 5))
    assert resumed.episodes == 5
    resumed.complete({"done": True})
    assert dataset_digest(killed) == dataset_digest(whole)
    assert [r["i"] for r in read_episode_sidecar(killed)] == list(range(5))
    ds = LeRobotDataset("local/journal", root=killed)
    assert ds.num_episodes == 5 and len(ds) == 15 and float(ds[14]["observation.state"][0]) == 4.0


def test_rollback_refuses_a_dataset_changed_since_its_checkpoint(tmp_path):
    from indgen_vla.core.errors import ConfigError

    out = tmp_path / "ds"
    record(out, range(3))  # checkpointed at 2, episode 2 in an open segment
    (out / "data/chunk-000/file-000.parquet").write_bytes(b"edited by hand")
    with pytest.raises(ConfigError, match="file-000.parquet changed since the last checkpoint"):
        JournaledDataset.reopen(out, **KW)
    assert (out / EPISODES_SIDECAR).is_file()
