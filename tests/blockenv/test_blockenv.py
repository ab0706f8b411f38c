"""BlockEnv: environment invariants, the oracle, the CLI, the learners and a tiny reproduce run."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from indgen_vla.blockenv.env import (
    DISTRACTOR,
    GOAL,
    BlockEnv,
    BlockEnvConfig,
    chain_offsets,
    legal_grasps,
    oracle_actions,
    sample_grids,
)
from indgen_vla.errors import ConfigError

CFG = BlockEnvConfig(grid_size=12)


def _grids(k: int, n: int = 20, seed: int = 0) -> np.ndarray:
    return sample_grids(np.full(n, k), CFG, np.random.default_rng(seed))


def test_chains_match_the_definition():
    fwd, flip = chain_offsets(4)
    assert fwd.tolist() == [[0, -1], [1, -1], [1, -2], [2, -2]]  # left, down, left, down
    assert flip.tolist() == [[-1, 0], [-1, 1], [-2, 1], [-2, 2]]  # up, right, up, right


@pytest.mark.parametrize("k", [0, 1, 2, 5, 10])
def test_reset_invariants(k):
    grids = _grids(k)
    assert ((grids == DISTRACTOR).sum((1, 2)) == 2 * k).all()
    assert ((grids == GOAL).sum((1, 2)) == 1).all()
    legal = legal_grasps(grids)
    for g, lg in zip(grids, legal, strict=True):
        goal = tuple(np.argwhere(g == GOAL)[0])
        assert lg[goal].any() == (k == 0)  # the goal is blocked for k >= 1
        cells = {tuple(c) for c in np.argwhere(lg.any(-1))}
        tips = {tuple(np.array(goal) + ch[-1]) for ch in chain_offsets(k)} if k else {goal}
        assert cells == tips  # only chain tips are graspable


def test_level_k_plus_1_leaves_the_hull_of_level_k():
    for k in range(0, 8):
        inner = np.vstack([np.zeros((1, 2)), *chain_offsets(k)])
        outer = [ch[-1] for ch in chain_offsets(k + 1)]
        lo, hi = inner.min(0), inner.max(0)
        for tip in outer:
            assert ((tip < lo) | (tip > hi)).any()


@pytest.mark.parametrize("k", [0, 1, 3, 10])
def test_oracle_solves_every_level_in_k_plus_1_grasps(k):
    env = BlockEnv(CFG)
    env.reset(np.full(50, k), np.random.default_rng(1))
    arms = np.random.default_rng(2).integers(0, 2, 50)
    while not env.done.all():
        env.step(oracle_actions(env.grids, arms))
    assert env.success.all() and (env.steps == k + 1).all()


def test_wasted_steps_exhaust_the_budget_and_strict_fails_at_once():
    for strict, steps in ((False, 4), (True, 1)):
        env = BlockEnv(BlockEnvConfig(grid_size=12, strict=strict))
        env.reset(np.array([1]), np.random.default_rng(0))
        goal = np.argwhere(env.grids[0] == GOAL)[0]
        while not env.done.all():
            env.step(np.array([[goal[0], goal[1], 0]]))  # the goal is blocked at level 1
        assert not env.success[0] and env.steps[0] == steps


def test_level_that_does_not_fit_is_refused():
    with pytest.raises(ConfigError, match="grid"):
        BlockEnvConfig(grid_size=6).check_level(8)


def _run(rest):
    from indgen_vla.blockenv.cli import blockenv_main

    return blockenv_main(argparse.Namespace(rest=rest))


def test_sample_cli_prints_json_grids(capsys):
    assert _run(["sample", "--level", "3", "--n", "2", "--seed", "7", "--json"]) == 0
    grids = np.array(json.loads(capsys.readouterr().out))
    assert grids.shape == (2, 12, 12) and ((grids == 1).sum((1, 2)) == 6).all()
    again = _run(["sample", "--level", "3", "--n", "2", "--seed", "7", "--json"])
    assert again == 0 and np.array(json.loads(capsys.readouterr().out)).tolist() == grids.tolist()


@pytest.mark.parametrize("method", ["rnn", "transformer_goal_act", "trm", "maml", "ind", "local_equivariant"])
def test_training_reduces_the_loss(method):
    from indgen_vla.blockenv.train import TrainConfig, train

    losses = []
    train(
        TrainConfig(method, steps=25, demos_per_level=20, hidden=32), progress=lambda i, v: losses.append(v)
    )
    assert np.mean(losses[-5:]) < np.mean(losses[:5])


def test_reproduce_writes_table1(tmp_path):
    """Every method runs through the pipeline (tiny models, 2 updates); per-seed counts, per-seed break levels
    and the t-interval over seeds land beside the pooled Wilson CI."""
    from scipy.stats import t as student_t

    from indgen_vla.blockenv.reproduce import BASELINES, ReproduceConfig, reproduce
    from indgen_vla.metrics import break_level, wilson_ci

    cfg = ReproduceConfig(seeds=(0, 1), eval_levels=(0, 1, 3), episodes=4, steps=2, demos_per_level=4,
                          method_steps=(), hidden=16)  # fmt: skip
    reproduce(cfg, tmp_path, log=lambda m: None)
    table = json.loads((tmp_path / "table1.json").read_text())
    assert set(table) == {*BASELINES, "local_equivariant", "oracle"}
    oracle3 = table["oracle"]["levels"]["3"]
    assert oracle3["rate"] == 1.0 and table["oracle"]["break_level"] is None
    assert oracle3["per_seed"] == [{"seed": 0, "successes": 4, "n": 4}, {"seed": 1, "successes": 4, "n": 4}]
    assert (oracle3["seed_ci_low"], oracle3["seed_ci_high"]) == (1.0, 1.0)  # no spread over seeds
    for m, e in table.items():
        for v in e["levels"].values():
            (s0, n0), (s1, n1) = [(p["successes"], p["n"]) for p in v["per_seed"]]
            assert v["n"] == n0 + n1 == 8 and v["rate"] == (s0 + s1) / 8
            assert (v["ci_low"], v["ci_high"]) == pytest.approx(wilson_ci(s0 + s1, 8))
            r = np.array([s0 / n0, s1 / n1])
            half = student_t.ppf(0.975, 1) * r.std(ddof=1) / np.sqrt(2)
            assert v["seed_ci_low"] == pytest.approx(max(0.0, r.mean() - half))
            assert v["seed_ci_high"] == pytest.approx(min(1.0, r.mean() + half))
        for i, seed in enumerate(cfg.seeds):
            rates = {
                int(k): v["per_seed"][i]["successes"] / v["per_seed"][i]["n"] for k, v in e["levels"].items()
            }
            assert e["break_level_per_seed"][str(seed)] == break_level(rates, cfg.gamma), m
    md = (tmp_path / "table1.md").read_text()
    assert (tmp_path / "table1.png").stat().st_size > 0 and "| ind |" in md
    assert (
        "| per seed |" in md
        and "Student-t over the per-seed rates" in md
        and "| oracle | 68–100 / 100–100 |" in md  # Wilson 8/8: 8 / (8 + 1.96²)
    )


def _workers_config(methods, steps):
    from indgen_vla.blockenv.reproduce import ReproduceConfig

    return ReproduceConfig(seeds=(0, 1), eval_levels=(0, 1, 2), episodes=6, steps=steps, demos_per_level=10,
                           methods=methods, method_steps=(), hidden=32)  # fmt: skip


def test_reproduce_results_do_not_depend_on_workers(tmp_path):
    from indgen_vla.blockenv.reproduce import reproduce

    cfg = _workers_config(("rnn", "local_equivariant"), steps=5)
    one = reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1)["methods"]
    two = reproduce(cfg, tmp_path / "w2", log=lambda m: None, workers=2)["methods"]
    assert one == two


@pytest.mark.slow
def test_reproduce_results_do_not_depend_on_workers_trm(tmp_path):
    """The same with TRM's deep-supervision training loop (minutes on CPU)."""
    from indgen_vla.blockenv.reproduce import ReproduceConfig, reproduce

    cfg = ReproduceConfig(seeds=(0, 1), eval_levels=(0, 1, 2), episodes=6, steps=20, demos_per_level=10,
                          methods=("rnn", "trm"), method_steps=())  # fmt: skip
    one = reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1)["methods"]
    two = reproduce(cfg, tmp_path / "w2", log=lambda m: None, workers=2)["methods"]
    assert one == two


def test_trm_reads_its_answer_off_the_whole_grid():
    """Patch tokens must still address every cell, including those of a partial last patch (G = 11)."""
    import torch

    from indgen_vla.blockenv.models.recursive import TRMPolicy

    torch.manual_seed(0)
    model = TRMPolicy(grid=11, d=32, patch=3)
    with torch.no_grad():
        model.out.bias.zero_()
        model.out.weight.zero_()
        model.out.bias[-1] = 5.0  # the last cell of every patch, θ = 1
    obs = torch.zeros(1, 1, 11, 11, dtype=torch.long)
    joint = model(obs, torch.zeros(1, dtype=torch.long))["joint"]
    assert joint.shape == (1, 1, 11, 11, 2)
    hot = torch.nonzero(joint[0, 0] > 1).tolist()
    assert sorted(hot) == [[r, c, 1] for r in (2, 5, 8) for c in (2, 5, 8)]
