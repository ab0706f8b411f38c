"""Noisy-oracle T0 demonstrations round-trip through lerobot's own LeRobotDataset."""

import numpy as np
import pytest

from indgen_vla.errors import ConfigError
from indgen_vla.regimes.demos import HumanNoise, record_demos


@pytest.mark.slow  # ~30 s (32-px rendering + dataset write); test_train covers the state-only round trip by default
def test_demos_round_trip_through_lerobot(one_demo):
    from lerobot.datasets.lerobot_dataset import LeRobotDataset

    out, stats = one_demo
    assert stats["episodes"] == 1 and stats["frames"] > 50
    ds = LeRobotDataset("local/indgen_demos", root=out)
    assert ds.num_episodes == 1 and len(ds) == stats["frames"]
    item = ds[0]
    assert tuple(item["observation.images.agentview"].shape) == (3, 32, 32)
    assert tuple(item["observation.state"].shape) == (8,) and tuple(item["action"].shape) == (7,)
    assert item["task"].startswith("pick up the") and item["task"].endswith("in the basket")
    actions = np.stack([ds[i]["action"].numpy() for i in range(len(ds))])
    assert np.all(np.abs(actions) <= 1.0) and set(np.unique(np.sign(actions[:, -1]))) <= {-1.0, 1.0}
    assert actions[:, -1].max() == 1.0  # the gripper closed at some point: a grasp happened
    with pytest.raises(ConfigError, match="already exists"):
        record_demos("pick_place", out, n=1)


def test_noise_validation():
    with pytest.raises(ConfigError):
        HumanNoise(sigma=-1)
    with pytest.raises(ConfigError):
        HumanNoise(pause_steps=(3, 1))
