"""``indgen series``: one run per checkpoint of a LeRobot training output, the series report, resume, refusals."""

import json
import shutil
from pathlib import Path

import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.studies.series import find_checkpoints
from indgen_vla.core.comparison.series_report import write_series
from tests.indgen_vla.core.reporting.test_report import make_run

pytestmark = pytest.mark.filterwarnings("ignore")
SHIPPED = Path(__file__).resolve().parents[4] / "checkpoints" / "act_pick_place_human"


def lerobot_output(root: Path, steps) -> Path:
    """LeRobot's training layout: ROOT/checkpoints/<step, zero-padded>/pretrained_model, and the 'last' link."""
    for s in steps:
        shutil.copytree(SHIPPED, root / "checkpoints" / f"{s:06d}" / "pretrained_model")
    (root / "checkpoints" / "last").symlink_to(f"{steps[-1]:06d}")
    return root


@pytest.mark.slow  # two evaluate runs and a re-run: minutes on a loaded 2-core machine
def test_series_of_two_shipped_checkpoints_writes_its_report_and_resumes(tmp_path, capsys):
    pytest.importorskip("lerobot")
    root = lerobot_output(tmp_path / "train", [100, 200])
    argv = ["series", str(root), "--scene", "pick_place", "--axis", "pick_y", "--levels", "0", "--episodes", "5",
            "--max-steps", "20", "--workers", "1", "--out", str(tmp_path / "s")]  # fmt: skip
    assert main(argv) == 0
    s = tmp_path / "s"
    series = json.loads((s / "series.json").read_text())
    assert series["steps"] == [100, 200]
    lv = series["axes"]["pick_y"]["levels"]
    assert [p["n"] for p in lv["0"]] == [5, 5] and [p["step"] for p in lv["0"]] == [100, 200]
    assert all(0 <= p["ci"][0] <= p["rate"] <= p["ci"][1] <= 1 for p in lv["0"])
    assert series["pairs"][0]["paired"] and series["pairs"][0]["test"] == "mcnemar_exact"
    md = (s / "series.md").read_text()
    assert "| 100 |" in md and "step 100 → 200 (paired), `pick_y`" in md and "task milk" in md
    for name in ("pick_y_success.png", "pick_y_kstar.png"):
        assert (s / "plots" / name).stat().st_size > 5000
    manifest = json.loads((s / "runs" / "000000100" / "manifest.json").read_text())
    assert manifest["policy"] == f"lerobot:{root / 'checkpoints' / '000100' / 'pretrained_model'}"
    mtimes = {p: p.stat().st_mtime_ns for p in s.glob("runs/*/episodes.parquet")}
    capsys.readouterr()
    assert main(argv) == 0  # resumes: both finished, nothing re-run
    assert "2 checkpoint(s) already evaluated" in capsys.readouterr().out
    assert {p: p.stat().st_mtime_ns for p in s.glob("runs/*/episodes.parquet")} == mtimes
    argv[argv.index("--episodes") + 1] = "6"
    assert main(argv) == 2  # another protocol into the same series: refused
    assert "episodes=5, now 6" in capsys.readouterr().err


def test_series_report_trend_and_kstar_from_runs(tmp_path):
    """Three checkpoints whose level 1 rises 1/10 → 6/10 → 10/10: Cochran–Armitage over the steps shows the rise, Holm
    over the table's 4 one-sided tests too; the pooled OOD success gets no test (one training run); k* moves from +1
    to none in range (Kendall τ > 0)."""
    runs = [(s, make_run(tmp_path / str(s), {0: (10, 10), 1: (k, 10)}, regime=str(s)).path)
            for s, k in ((1000, 1), (2000, 6), (3000, 10))]  # fmt: skip
    series = write_series(runs, tmp_path / "out")
    ax = series["axes"]["pick_y"]
    t = ax["trend"]["1"]
    assert t["p_rising"] < 0.001 and t["holm_over"] == 4  # a rise and a fall at levels 0 and 1
    assert t["p_rising_holm"] == pytest.approx(min(1, 4 * t["p_rising"])) and ax["trend"]["ood"] is None
    assert [x["k"] for x in ax["kstar"]["pos"]] == [1, None, None]
    assert ax["trend"]["kstar_pos"]["tau"] > 0
    md = (tmp_path / "out" / "series.md").read_text()
    assert "| 1000 | 10/10 = 100% [72, 100] | 1/10 = 10% [2, 40] |" in md
    assert "k* (+ side) by step: 1000: +1, 2000: none in range, 3000: none in range" in md
    assert "Holm over the 4 one-sided tests above" in md and "| OOD success | no trend test" in md
    assert "step 1000 → 2000 (paired), `pick_y`: no level differs" in md


def test_checkpoint_discovery(tmp_path):
    root = tmp_path / "out"
    being_written = root / "checkpoints" / "000500" / "pretrained_model"  # no config.json yet
    being_written.mkdir(parents=True)
    with pytest.raises(Exception, match="no <step>/pretrained_model with a config.json yet"):
        find_checkpoints([root])
    assert find_checkpoints([root], must_exist=False) == []
    shutil.rmtree(being_written.parent)
    lerobot_output(root, [100])  # complete: 'last' points at it
    shutil.copytree(
        SHIPPED, root / "checkpoints" / "000200" / "pretrained_model"
    )  # written, 'last' not moved yet
    assert [c.step for c in find_checkpoints([root])] == [100]
    (root / "checkpoints" / "last").unlink()
    (root / "checkpoints" / "last").symlink_to("000200")
    assert [c.step for c in find_checkpoints([root])] == [100, 200]
    a, b = tmp_path / "step_20", tmp_path / "step_3"
    for d in (a, b):
        d.mkdir()
        (d / "config.json").write_text("{}")
    assert [(c.step, c.path) for c in find_checkpoints([a, b])] == [(3, b), (20, a)]
    with pytest.raises(Exception, match="no such directory"):
        find_checkpoints([tmp_path / "nope"])


@pytest.mark.slow  # one real evaluate
def test_follow_waits_for_checkpoints_a_training_writes(tmp_path):
    """--follow on a training output without a checkpoint yet: the one written while it polls is evaluated, then it
    stops after --idle-stop seconds without another."""
    import threading

    from indgen_vla.app.engine.config import EvalConfig
    from indgen_vla.app.studies.config import SeriesConfig
    from indgen_vla.app.studies.series import run_series
    from tests.fixtures.resolved import family

    pytest.importorskip("lerobot")
    root = tmp_path / "train"
    (root / "checkpoints").mkdir(parents=True)
    timer = threading.Timer(0.5, lambda: lerobot_output(root, [300]))
    timer.start()
    base = EvalConfig.from_flat(policy="series", scene="pick_place", axes=("pick_y",), levels="0", episodes=1, max_steps=5,
                      workers=1, out="_")  # fmt: skip
    said = []
    cfg = SeriesConfig(protocol=base, roots=(root,), out=tmp_path / "s", follow=True, poll=0.2, idle_stop=1.0)
    entries = run_series(cfg, family(base), say=said.append)
    timer.join()
    assert [s for s, _ in entries] == [300] and said[-1].startswith("series: step 300: evaluating")
    assert (tmp_path / "s" / "runs" / "000000300" / "summary.json").exists()


def test_a_failed_first_command_does_not_lock_the_series_protocol(tmp_path, capsys):
    """A first series whose ROOT was wrong ran nothing: the corrected command with other flags goes on (it was
    refused as 'a series run with episodes=50, now 5'); once a checkpoint's run exists, other flags are refused."""
    from indgen_vla.app.studies.series import check_protocol, run_dir

    s = tmp_path / "s"
    argv = [
        "series",
        str(tmp_path),
        "--scene",
        "pick_place",
        "--axis",
        "pick_y",
        "--levels",
        "0",
        "--out",
        str(s),
    ]
    assert main(argv) == 2
    assert "holds no config.json" in capsys.readouterr().err and (s / "series_protocol.json").is_file()
    check_protocol(s, {"episodes": 5})  # the corrected command's protocol: recorded, not refused
    assert json.loads((s / "series_protocol.json").read_text()) == {"episodes": 5}
    make_run(run_dir(s, find_checkpoints([lerobot_output(tmp_path / "train", [100])])[0]), {0: (5, 5)})
    with pytest.raises(Exception, match="series run with episodes=5, now 6"):
        check_protocol(s, {"episodes": 6})
