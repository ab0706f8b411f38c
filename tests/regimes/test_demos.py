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


def _run(code: str) -> str:
    """stdout + stderr of ``code`` in a fresh interpreter (robosuite not imported yet: its warning would show)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout + out.stderr


def test_demos_and_mimicgen_build_their_scenes_without_robosuites_macro_warning():
    """Both commands build scenes in their own process through scenes.make_env, whose layouts import robosuite by
    scenes.objects, not scenes.sim: its three-line macro-file warning must not reach the terminal there either
    (the fork server's preload: tests/scenes/test_planning.py::test_the_fork_servers_preload_is_quiet)."""
    code = ("import indgen_vla.regimes.demos, indgen_vla.regimes.mimicgen, scenes\n"
            "env = scenes.make_env('pick_place', cameras=())\nenv.reset(seed=0)\nenv.close()")  # fmt: skip
    assert "macro" not in _run(code)


@pytest.mark.slow  # ~25 s: both commands end to end, one state-only episode each
def test_the_demos_and_mimicgen_commands_print_no_macro_warning(tmp_path):
    src, dst = tmp_path / "demos", tmp_path / "mg"
    out = _run(f"from indgen_vla.cli import main\nassert main(['demos', '--scene', 'pick_place', '--n', '1', "
               f"'--cameras', '', '--out', {str(src)!r}]) == 0\n"
               f"assert main(['mimicgen', '--source', {str(src)!r}, '--n', '1', '--out', {str(dst)!r}]) == 0")  # fmt: skip
    assert "recorded 1 episodes" in out and "macro" not in out
