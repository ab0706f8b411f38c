"""A policy object in memory (a training loop's weights) runs the same episodes as the same weights from disk."""

from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.fingerprint import differences
from indgen_vla.core.runs.records import RunDir
from tests.fixtures.resolved import evaluate
from tests.fixtures.tiny_policies import build_tiny_checkpoint

pytestmark = pytest.mark.filterwarnings("ignore")
SHIPPED = Path(__file__).resolve().parents[4] / "checkpoints" / "act_pick_place_human"
COLUMNS = ["task", "axis", "level", "episode", "seed", "success", "steps", "status", "failure", "progress"]


def cfg(out, policy, **kw):
    base = dict(policy=policy, scene="pick_place", axes=("pick_y",), levels="0:1", episodes=2, workers=1,
                max_steps=40, out=str(out))  # fmt: skip
    return EvalConfig.from_flat(**{**base, **kw})


def from_disk(path):
    """The weights and processors as a training script holds them, from lerobot's own loaders (imported without
    lerobot's other policies, as the engine does: an import of them all takes a minute on a loaded 2-core machine)."""
    from policy_wrappers.lerobot_import import one_package_scan, policy_package

    with one_package_scan():
        policy_package("act")
        from lerobot.configs.policies import PreTrainedConfig
        from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    config = PreTrainedConfig.from_pretrained(str(path))
    policy = get_policy_class(config.type).from_pretrained(str(path), config=config)
    pre, post = make_pre_post_processors(config, pretrained_path=str(path))
    return policy, pre, post


def episodes(out) -> pd.DataFrame:
    df = RunDir.open(out).episodes()
    return df[COLUMNS].sort_values(["level", "episode"]).reset_index(drop=True)


def same_run(a, b) -> None:
    pd.testing.assert_frame_equal(episodes(a), episodes(b))
    fa, fb = (RunDir.open(x).manifest["fingerprint"] for x in (a, b))
    assert not [d for d in differences(fa, fb) if d[3]]  # pairable: compare and gate accept the two runs


@pytest.mark.slow  # ~8-20 s a kind: test_a_policy_protocol_object_runs_like_its_spec_and_stays_open stays by default
@pytest.mark.parametrize("kind", ["shipped", "tiny_images"])
def test_lerobot_object_runs_the_episodes_of_its_checkpoint(tmp_path, kind):
    """The shipped state-only ACT (the episodes run long enough for the policy to act), and a tiny image ACT
    (LIBERO camera names: flipped renders of both cameras)."""
    import torch

    pytest.importorskip("lerobot")
    path = SHIPPED if kind == "shipped" else build_tiny_checkpoint("act", tmp_path / "ckpt")
    kw = (
        dict(levels="0", episodes=2, max_steps=25)
        if kind == "shipped"
        else dict(levels="0", episodes=1, max_steps=12)
    )
    disk = evaluate(cfg(tmp_path / "disk", f"lerobot:{path}", **kw), quiet=True)
    objs = from_disk(path)
    objs[0].train()  # as in a training loop: the run evaluates in eval mode and hands it back in train mode
    rng = torch.get_rng_state()
    mem = evaluate(cfg(tmp_path / "mem", "object:ACTPolicy", **kw), quiet=True, policy=objs)
    assert objs[0].training and torch.equal(rng, torch.get_rng_state())  # the loop's state is left as it was
    same_run(disk, mem)
    assert RunDir.open(mem).manifest["policy"] == "object:ACTPolicy"
    if kind == "shipped":
        assert episodes(mem)["steps"].min() > 10  # the policy acted over several chunks


def test_a_policy_protocol_object_runs_like_its_spec_and_stays_open(tmp_path):
    from policy_wrappers.standin import RandomPolicy

    closed = []

    class Mine(RandomPolicy):
        def close(self):
            closed.append(True)

    disk = evaluate(cfg(tmp_path / "spec", "standin:random", max_steps=12), quiet=True)
    mem = evaluate(cfg(tmp_path / "obj", "object:Mine", max_steps=12), quiet=True, policy=Mine())
    same_run(disk, mem)
    assert not closed  # the caller owns it


def test_object_refusals_are_one_line(tmp_path):
    pytest.importorskip("lerobot")
    policy, pre, post = from_disk(SHIPPED)
    with pytest.raises(ConfigError, match="local backend only"):
        evaluate(
            cfg(tmp_path / "r", "object:ACTPolicy", backend="ray"), quiet=True, policy=(policy, pre, post)
        )
    with pytest.raises(ConfigError, match=r"needs its processors .*\(policy, preprocessor, postprocessor\)"):
        evaluate(cfg(tmp_path / "p", "object:ACTPolicy"), quiet=True, policy=policy)
    with pytest.raises(ConfigError, match="neither a LeRobot PreTrainedPolicy"):
        evaluate(cfg(tmp_path / "x", "object:dict"), quiet=True, policy={"weights": 1})
    with pytest.raises(ConfigError, match="runs uncompiled"):
        evaluate(
            cfg(tmp_path / "c", "object:ACTPolicy", compile="default"), quiet=True, policy=(policy, pre, post)
        )
    assert not (tmp_path / "p" / "episodes.parquet").exists()
