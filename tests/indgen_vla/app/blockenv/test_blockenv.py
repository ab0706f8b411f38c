"""BlockEnv: environment invariants, the oracle, the CLI, the learners and a tiny reproduce run."""

from __future__ import annotations

import json
import signal

import numpy as np
import pytest

from indgen_vla.app.blockenv.env import (
    DISTRACTOR,
    GOAL,
    BlockEnv,
    BlockEnvConfig,
    chain_offsets,
    legal_grasps,
    oracle_actions,
    sample_grids,
)
from indgen_vla.core.errors import ConfigError

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
    from indgen_vla.app.cli.blockenv import run

    return run(rest)


def test_sample_cli_prints_json_grids(capsys):
    assert _run(["sample", "--level", "3", "--n", "2", "--seed", "7", "--json"]) == 0
    grids = np.array(json.loads(capsys.readouterr().out))
    assert grids.shape == (2, 12, 12) and ((grids == 1).sum((1, 2)) == 6).all()
    again = _run(["sample", "--level", "3", "--n", "2", "--seed", "7", "--json"])
    assert again == 0 and np.array(json.loads(capsys.readouterr().out)).tolist() == grids.tolist()


@pytest.mark.parametrize("method", ["rnn", "transformer_goal_act", "trm", "maml", "ind", "local_equivariant"])
def test_training_reduces_the_loss(method):
    from indgen_vla.app.blockenv.fit import FitConfig, train

    losses = []
    train(FitConfig(method, steps=25, demos_per_level=20, hidden=32), progress=lambda i, v: losses.append(v))
    assert np.mean(losses[-5:]) < np.mean(losses[:5])


def test_reproduce_writes_table1(tmp_path):
    """Every method runs through the pipeline (tiny models, 2 updates); per-seed counts, per-seed break levels
    and the t-interval over seeds land beside the pooled Wilson CI."""
    from scipy.stats import t as student_t

    from indgen_vla.app.blockenv.reproduce import BASELINES, ReproduceConfig, reproduce
    from indgen_vla.core.stats.metrics import break_level, wilson_ci

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
    from indgen_vla.app.blockenv.reproduce import ReproduceConfig

    return ReproduceConfig(seeds=(0, 1), eval_levels=(0, 1, 2), episodes=6, steps=steps, demos_per_level=10,
                           methods=methods, method_steps=(), hidden=32)  # fmt: skip


@pytest.mark.slow  # ~35 s: the reproduction twice, 1 and 2 workers
def test_reproduce_results_do_not_depend_on_workers(tmp_path):
    from indgen_vla.app.blockenv.reproduce import reproduce

    cfg = _workers_config(("rnn", "local_equivariant"), steps=5)
    first = reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1, resume=True)
    one = first["methods"]
    two = reproduce(cfg, tmp_path / "w2", log=lambda m: None, workers=2)["methods"]
    assert one == two
    # --resume: the four finished jobs are kept and read back (same counts, same recorded seconds), not rerun
    assert len(list((tmp_path / "w1" / "jobs").glob("*.json"))) == 4
    again = reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1, resume=True)
    assert again["methods"] == one and again["job_seconds"] == first["job_seconds"]
    # a job file cut short (an older version wrote it in place; a kill mid-write) is run again, not a crash
    job = sorted((tmp_path / "w1" / "jobs").glob("*.json"))[0]
    job.write_text(job.read_text()[:20])
    assert reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1, resume=True)["methods"] == one
    assert json.loads(job.read_text())["counts"]


@pytest.mark.slow
def test_reproduce_results_do_not_depend_on_workers_trm(tmp_path):
    """The same with TRM's deep-supervision training loop (minutes on CPU)."""
    from indgen_vla.app.blockenv.reproduce import ReproduceConfig, reproduce

    cfg = ReproduceConfig(seeds=(0, 1), eval_levels=(0, 1, 2), episodes=6, steps=20, demos_per_level=10,
                          methods=("rnn", "trm"), method_steps=())  # fmt: skip
    one = reproduce(cfg, tmp_path / "w1", log=lambda m: None, workers=1)["methods"]
    two = reproduce(cfg, tmp_path / "w2", log=lambda m: None, workers=2)["methods"]
    assert one == two


def test_trm_reads_its_answer_off_the_whole_grid():
    """Patch tokens must still address every cell, including those of a partial last patch (G = 11)."""
    import torch

    from indgen_vla.app.blockenv.models.recursive import TRMPolicy

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


def test_legality_target_matches_hand_computed_cells():
    """Ind's auxiliary target on a hand-drawn grid: a grasp is legal on an occupied cell whose two neighbours
    along the approach axis (θ 0: up/down, θ 1: left/right) are free; off-grid counts as free."""
    from indgen_vla.app.blockenv.data import legality_targets

    grid = np.array(
        [
            [1, 0, 0, 0, 0],
            [1, 2, 1, 0, 0],
            [0, 0, 0, 0, 1],
            [0, 0, 0, 0, 0],
            [0, 1, 1, 1, 0],
        ]
    )
    target = legality_targets(grid[None])[0]
    assert target.shape == (5, 5, 2) and target.dtype == np.float32
    legal = {(r, c, th) for r, c, th in zip(*np.nonzero(target), strict=True)}
    assert legal == {
        (0, 0, 1),  # top-left corner: off-grid to the left, free to the right; (1, 0) below blocks θ 0
        # (1, 0) has neither: (0, 0) above it, the goal to its right
        (1, 1, 0),  # the goal: free above and below, blocked left and right
        (1, 2, 0),  # right of the goal: free above and below
        (2, 4, 0), (2, 4, 1),  # isolated block at the right edge: both axes free
        (4, 1, 0), (4, 3, 0),  # row ends of the bottom bar: free above and off-grid below
        (4, 2, 0),  # its middle: blocked left/right but free above and below
    }  # fmt: skip


def test_ind_gate_masks_empty_cells_and_adds_scaled_legality():
    """At inference an empty cell can never win, and the gate adds gate_scale · log σ(legal) to the pick logits."""
    import torch
    from torch.nn import functional as F  # noqa: N812

    from indgen_vla.app.blockenv.evaluate import decode
    from indgen_vla.app.blockenv.models import build_model

    obs = torch.zeros(1, 4, 4, dtype=torch.long)
    obs[0, 1, 1], obs[0, 2, 3] = 2, 1
    joint = torch.zeros(1, 4, 4, 2)
    joint[0, 0, 0, 0] = 50.0  # the ungated favourite is an empty cell
    joint[0, 2, 3, 1] = 1.0
    legal = torch.full((1, 4, 4, 2), -8.0)
    legal[0, 1, 1, 0] = 3.0  # the goal, top/bottom, is predicted legal
    out = {"joint": joint[:, None], "legal": legal[:, None]}
    for scale, expected in ((0.0, [2, 3, 1]), (1.0, [1, 1, 0])):
        model = build_model("ind", 4, 16, {"gate_scale": scale})
        gated = model.gate({k: v[:, -1] for k, v in out.items()}, obs)
        assert torch.isinf(gated[0, 0, 0]).all() and (gated[0, 0, 0] < 0).all()
        occupied = gated[0, 2, 3, 1]
        assert occupied == pytest.approx(float(1.0 + scale * F.logsigmoid(torch.tensor(-8.0))))
        assert decode(out, obs, model).tolist() == [expected]
    unmasked = build_model("ind", 4, 16, {"mask": False, "gate_scale": 0.0})
    assert decode(out, obs, unmasked).tolist() == [[0, 0, 0]]


def test_legality_loss_weights_match_a_hand_computed_bce():
    import torch
    from torch.nn import functional as F  # noqa: N812

    from indgen_vla.app.blockenv.fit import bc_loss

    torch.manual_seed(0)
    joint = torch.randn(2, 1, 3, 3, 2)
    legal_logits = torch.randn(2, 1, 3, 3, 2)
    actions = torch.tensor([[[0, 1, 1]], [[2, 2, 0]]])
    target = torch.zeros(2, 1, 3, 3, 2)
    target[0, 0, 0, 1, 1] = target[1, 0, 2, 2, 0] = 1.0
    ce = F.cross_entropy(joint.flatten(2).squeeze(1), torch.tensor([3, 16]))
    p = torch.sigmoid(legal_logits)
    bce = -(3.0 * target * p.log() + (1 - target) * (1 - p).log()).mean()
    got = bc_loss(
        {"joint": joint, "legal": legal_logits}, actions, None, target, legal_weight=5.0, legal_pos_weight=3.0
    )
    assert float(got) == pytest.approx(float(ce + 5.0 * bce), rel=1e-5)


def test_variant_options_are_checked():
    from indgen_vla.app.blockenv.fit import FitConfig

    assert FitConfig("ind", extra={"gate_scale": 4}).extra == {"gate_scale": 4}
    for method, extra, msg in (
        ("ind", {"gate": 1.0}, "no option"),
        ("rnn", {"patch": 2}, "allowed: none"),
        ("ind", {"mask": "yes"}, "must be bool"),
        ("ind", {"legal_weight": -1.0}, ">= 0"),
        ("maml", {"head": "both"}, "'factored' or 'joint'"),
        ("trm", {"patch": 0}, "patch must be >= 1"),
    ):
        with pytest.raises(ConfigError, match=msg):
            FitConfig(method, extra=extra)


def test_maml_joint_head_never_mixes_the_two_right_answers():
    """With two equally right first grasps, factored argmaxes can pair one tip's row with the other's column;
    one softmax over (r, c, θ) picks a whole cell."""
    import torch

    from indgen_vla.app.blockenv.evaluate import decode
    from indgen_vla.app.blockenv.models import build_model

    model = build_model("maml", 5, 8, {"head": "joint"})
    obs = torch.zeros(1, 1, 5, 5, dtype=torch.long)
    out = model(obs, torch.zeros(1, dtype=torch.long))
    assert out["joint"].shape == (1, 1, 5, 5, 2) and set(out) == {"joint"}
    joint = torch.zeros(1, 1, 5, 5, 2)
    joint[0, 0, 1, 3, 0] = joint[0, 0, 3, 1, 0] = 2.0
    assert decode({"joint": joint}, obs[:, 0], model).tolist() in ([[1, 3, 0]], [[3, 1, 0]])
    rows, cols = torch.zeros(1, 1, 5), torch.zeros(1, 1, 5)
    rows[0, 0, [1, 3]] = torch.tensor([2.0, 1.9])
    cols[0, 0, [3, 1]] = torch.tensor([1.9, 2.0])  # tips (1, 3) and (3, 1): the argmaxes pick (1, 1)
    factored = {"rows": rows, "cols": cols, "theta": torch.zeros(1, 1, 2)}
    assert decode(factored, obs[:, 0], build_model("maml", 5, 8)).tolist() == [[1, 1, 0]]


def test_ablate_writes_per_seed_tables_into_the_doc(tmp_path):
    """A tiny ablation run: per-seed counts, both intervals, and the doc section between the markers only."""
    from indgen_vla.app.blockenv.ablate import BEGIN, END, ablate, quick_scale
    from indgen_vla.core.stats.metrics import wilson_ci

    doc = tmp_path / "doc.md"
    doc.write_text(f"# head\n\n{BEGIN}\nold\n{END}\n\ntail\n")
    res = ablate(["maml_head"], quick_scale(), tmp_path / "abl.json", doc, log=lambda m: None)
    rows = res["maml_head"]["variants"]
    assert [r["extra"] for r in rows] == [{}, {"head": "joint"}]
    for r in rows:
        l3 = r["levels"]["2"]
        s = sum(p["successes"] for p in l3["per_seed"])
        assert [p["n"] for p in l3["per_seed"]] == [3, 3] and l3["n"] == 6
        assert (l3["ci_low"], l3["ci_high"]) == pytest.approx(wilson_ci(s, 6))
    text = doc.read_text()
    assert text.startswith("# head\n") and text.endswith("tail\n") and "old" not in text
    assert "| joint (r, c, θ) |" in text and "L2 t over seeds" in text
    assert json.loads((tmp_path / "abl.json").read_text())["maml_head"]["variants"] == rows
    from indgen_vla.app.blockenv.ablate import write_doc

    bare = tmp_path / "bare.md"
    bare.write_text("no markers\n")
    with pytest.raises(ConfigError, match="no ablation markers"):
        write_doc(res, bare)


def test_legality_top1_scores_the_head_on_oracle_states():
    """A hand-wired local legality head that computes the rule scores 1 at an unseen level; its negation 0."""
    import torch

    from indgen_vla.app.blockenv.ablate import legality_top1
    from indgen_vla.app.blockenv.models import build_model

    model = build_model("ind", 12, 16, {"legal_head": "local"})
    first, mid, last = model.local_legal[0], model.local_legal[2], model.local_legal[4]
    with torch.no_grad():
        for m in (first, mid, last):
            m.weight.zero_()
            m.bias.zero_()
        # channel 0: occupied(centre) − occupied(above) − occupied(below); channel 1: the same left/right
        first.weight[0, 0, 1, 1] = first.weight[1, 0, 1, 1] = 1.0
        first.weight[0, 0, 0, 1] = first.weight[0, 0, 2, 1] = -1.0
        first.weight[1, 0, 1, 0] = first.weight[1, 0, 1, 2] = -1.0
        mid.weight[0, 0] = mid.weight[1, 1] = 1.0
        last.weight[0, 0] = last.weight[1, 1] = 10.0
    cfg = BlockEnvConfig(grid_size=12)
    assert legality_top1(model, 5, 4, cfg, seed=0) == 1.0
    with torch.no_grad():
        last.weight.neg_()
    assert legality_top1(model, 5, 4, cfg, seed=0) == 0.0


def test_ablation_table_rows_match_the_header_with_the_legality_column():
    """The committed result's Ind table: header, rule and every row have the same number of cells."""
    from pathlib import Path

    from indgen_vla.app.blockenv.ablate import render

    results = json.loads(
        (Path(__file__).resolve().parents[4] / "docs/results/blockenv_ablations.json").read_text()
    )
    table = [ln for ln in render(results["ind_local_gate"]).splitlines() if ln.startswith("|")]
    assert "| legality top-1 L2 / L3 / L4 |" in table[0]
    assert len({ln.count("|") for ln in table}) == 1


def test_train_cli_passes_variant_options(tmp_path):
    from indgen_vla.app.blockenv.fit import load_checkpoint

    out = tmp_path / "ind"
    rest = ["train", "--method", "ind", "--steps", "1", "--demos-per-level", "2", "--out", str(out)]
    assert _run([*rest, "--option", "legal_head=local", "--option", "gate_scale=2"]) == 0
    model, cfg = load_checkpoint(out)
    assert cfg.extra == {"legal_head": "local", "gate_scale": 2} and model.gate_scale == 2.0
    assert model.legal_head == "local" and "legal" not in model.heads
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        _run([*rest, "--option", "legal_head"])
    with pytest.raises(ConfigError, match="no option"):
        _run([*rest, "--option", "patch=2"])


def test_a_checkpoint_save_cut_short_never_loads_as_another(tmp_path):
    """A save cut short over an older checkpoint leaves no config.json beside other weights, and a model.pt cut
    short (what the old in-place torch.save left on a kill) is one clear error, not a torch traceback."""
    from indgen_vla.app.blockenv.fit import FitConfig, load_checkpoint, save_checkpoint, train
    from tests.fixtures.kill import writes_cut_short_after

    out = tmp_path / "ckpt"
    small, _ = train(FitConfig("rnn", steps=1, demos_per_level=2, hidden=8))
    save_checkpoint(small, FitConfig("rnn", steps=1, demos_per_level=2, hidden=8), out)
    big_cfg = FitConfig("rnn", steps=1, demos_per_level=2, hidden=64)
    big, _ = train(big_cfg)
    with pytest.raises(OSError), writes_cut_short_after((out / "model.pt").stat().st_size + 100):
        save_checkpoint(big, big_cfg, out)
    with pytest.raises(ConfigError, match="no readable config.json"):
        load_checkpoint(out)
    save_checkpoint(big, big_cfg, out)
    weights = (out / "model.pt").read_bytes()
    (out / "model.pt").write_bytes(weights[: len(weights) // 2])
    with pytest.raises(ConfigError, match="model.pt is missing or unreadable"):
        load_checkpoint(out)


def test_ablation_doc_and_results_survive_a_write_cut_short(tmp_path):
    """docs/results/blockenv_ablations.md and the results JSON hold every ablation run so far: a rewrite cut short keeps the old file."""
    from indgen_vla.app.blockenv.ablate import BEGIN, END, replace_section
    from tests.fixtures.kill import writes_cut_short_after

    doc = tmp_path / "doc.md"
    before = f"# head\n\n{BEGIN}\nold\n{END}\n\ntail\n"
    doc.write_text(before)
    with pytest.raises(OSError), writes_cut_short_after(len(before) + 10):
        replace_section(doc, BEGIN, END, "x" * 1000, "ablation")
    assert doc.read_text() == before
    assert [p.name for p in tmp_path.iterdir()] == ["doc.md"]  # and no temporary file is left beside it


def test_table1_opens_with_what_it_cannot_answer():
    from indgen_vla.app.blockenv.reproduce import render_markdown, table_caveats

    def method(s0: int, n: int) -> dict:
        lv = {
            "rate": s0 / n,
            "ci_low": 0.0,
            "ci_high": 1.0,
            "n": n,
            "per_seed": [{"seed": 0, "successes": s0, "n": n}],
        }
        return {"levels": {"0": lv}, "break_level": 0, "break_level_per_seed": {"0": 0}}

    result = {"config": {"seeds": [0], "eval_levels": [0], "episodes": 10, "train_steps": 2, "demos_per_level": 4,
                         "gamma": 0.2}, "wall_s": 1.0, "methods": {"rnn": method(1, 10), "ind": method(10, 10)}}  # fmt: skip
    blind, few, seeds = table_caveats(result)
    assert blind.startswith("**Cannot answer** (rnn 1/10 = 10% [2, 40] at L0")  # Wilson 1/10: [0.018, 0.404]
    assert "0/10 leaves the Wilson 95 % CI above γ = 0.2" in few and "n ≥ 16" in few
    assert seeds.startswith("**Too few seeds**: 1 training seed")
    assert render_markdown(result).splitlines()[2] == blind
    result["config"].update(seeds=[0, 1, 2], episodes=100)
    result["methods"] = {"ind": method(100, 100)}
    assert table_caveats(result) == []


def test_eval_cli_names_task_ci_and_caveats(tmp_path, capsys):
    out = tmp_path / "e.json"
    assert _run(["eval", "--method", "oracle", "--levels", "0:1", "--episodes", "10", "--out", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("Too few episodes (oracle, `k`, task BlockEnv 12×12): at most n = 10 a level")
    assert lines[1] == "oracle on task BlockEnv 12×12, seed 1000: success per level with Wilson 95 % CI"
    res = json.loads(out.read_text())
    assert res["task"] == "BlockEnv 12×12" and res["caveats"][0].startswith("**Too few episodes**")


@pytest.mark.slow  # 30-60 s: two --quick reproductions with 2 worker processes, stopped after their first job
def test_a_stopped_reproduce_leaves_no_worker_running(tmp_path):
    """SIGTERM stops the jobs in progress at once (the old ProcessPoolExecutor waited for every queued job, then
    dropped them unsaved), and the workers of a SIGKILLed reproduce end (the executor's trained on, orphaned)."""
    from tests.fixtures.kill import stop_midway

    def first_job_saved(out):
        return lambda: any((out / "jobs").glob("*.json"))

    for sig in (signal.SIGTERM, signal.SIGKILL):
        out = tmp_path / sig.name
        argv = ["blockenv", "reproduce", "--quick", "--workers", "2", "--resume", "--out", str(out)]
        stopped = stop_midway(argv, sig, first_job_saved(out), linger_s=60)
        assert stopped.survivors == [], sig.name
        assert sig == signal.SIGKILL or (stopped.returncode == 143 and stopped.exit_s < 10), stopped
