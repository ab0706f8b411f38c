"""``indgen train --eval-every``: the weights in memory are evaluated every N updates into a series, and the training
is not changed by it (the checkpoint equals one trained without evaluations, byte for byte)."""

from __future__ import annotations

import json

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.cli.train import eval_config
from indgen_vla.app.regimes.train import TrainConfig, train_policy
from indgen_vla.app.regimes.train_eval import make_hook
from indgen_vla.core.runs.records import RunDir
from tests.fixtures.resolved import family
from tests.indgen_vla.app.regimes.test_train import TINY, _same_checkpoint

pytest.importorskip("lerobot")
pytestmark = [pytest.mark.timeout(900), pytest.mark.filterwarnings("ignore")]


@pytest.mark.slow  # a training twice and two evaluations: minutes on a loaded 2-core machine
def test_eval_every_runs_in_memory_and_leaves_the_checkpoint_unchanged(demos, tmp_path):
    plain = train_policy(TrainConfig(datasets=[demos], out=tmp_path / "plain", recipe=TINY))
    evals, said = tmp_path / "act_evals", []
    base = eval_config(
        "--scene pick_place --axis pick_y --levels 0 --episodes 1 --max-steps 10 --workers 1", evals
    )
    hook = make_hook(base, family(base), evals, every=8, last=TINY.steps, say=said.append)
    out = train_policy(TrainConfig(datasets=[demos], out=tmp_path / "act", recipe=TINY), after_step=hook)
    _same_checkpoint(plain, out)  # evaluating in the middle changed no weight, optimiser step or loss
    assert said == [
        f"train: evaluating step {s} in memory into {evals / 'runs' / f'{s:09d}'}" for s in (8, 12)
    ]
    series = json.loads((evals / "series.json").read_text())
    assert series["steps"] == [8, 12] and series["pairs"][0]["paired"]
    assert RunDir.open(evals / "runs" / "000000012").manifest["policy"] == "object:indgen-train@step12"
    assert (evals / "plots" / "pick_y_success.png").exists()


def test_eval_flags_are_checked_before_training(tmp_path, capsys):
    out, demos = str(tmp_path / "act"), tmp_path / "demos"  # refused before the datasets are read
    assert main(["train", str(demos), "--out", out, "--steps", "2", "--eval-every", "1"]) == 2
    assert "--eval-every N and --eval 'FLAGS' go together" in capsys.readouterr().err
    assert (
        main(["train", str(demos), "--out", out, "--eval-every", "1", "--eval=--scene pick_place --policy x"])
        == 2
    )
    assert (
        "--eval --policy: the trained policy and the run directories are set per step"
        in capsys.readouterr().err
    )
    assert (
        main(["train", str(demos), "--out", out, "--eval-every", "1", "--eval=--scene pick_place --levels"])
        == 2
    )
    assert "not valid evaluate flags" in capsys.readouterr().err
    assert not (tmp_path / "act").exists()
