"""``--log trackio`` / ``--log wandb``: a run's numbers reach a local tracker, offline, with no connection leaving the
machine (each run in a subprocess whose sockets refuse any address but loopback and local sockets)."""

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from indgen_vla.core.runs.video import write_mp4
from tests.indgen_vla.core.reporting.test_report import make_run

ROOT = Path(__file__).resolve().parents[4]
GUARD = textwrap.dedent("""
    import socket, sys
    tried = []
    real = socket.socket.connect
    def connect(self, address):
        host = address[0] if isinstance(address, tuple) else None
        if host is not None and host not in ("127.0.0.1", "::1", "localhost"):
            tried.append(address)
            raise OSError("network refused by the test")
        return real(self, address)
    socket.socket.connect = connect
    import atexit
    atexit.register(lambda: print("NETWORK_TRIED", tried))
""")


def run_logged(tmp_path, kind: str, code: str) -> str:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "TRACKIO_DIR": str(tmp_path / "trackio"), "WANDB_MODE": "offline",
           "WANDB_DIR": str(tmp_path / "wandb"), "WANDB_SILENT": "true", "HF_HUB_OFFLINE": "1",
           "GRADIO_ANALYTICS_ENABLED": "False", "WANDB_DISABLE_GIT": "true"}  # fmt: skip
    r = subprocess.run([sys.executable, "-c", GUARD + code], env=env, capture_output=True, text=True, timeout=240,
                       cwd=tmp_path)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert "NETWORK_TRIED []" in r.stdout, r.stdout[-2000:]
    return r.stdout


def a_run(tmp_path):
    run = make_run(tmp_path / "run", {0: (9, 10), 1: (1, 10)}, regime="h-only")
    frames = [np.full((32, 32, 3), i * 20, np.uint8) for i in range(8)]
    write_mp4(frames, run.path / "videos" / "pick_y_L0" / "ep0_success.mp4")
    return run.path


def test_trackio_writes_a_local_project(tmp_path):
    pytest.importorskip("trackio")
    run = a_run(tmp_path)
    code = f"""
from indgen_vla.app.engine.trackers import log_runs
print("LOGGED", log_runs("trackio", [(1000, {str(run)!r})], project="indgen-test", name="series"))
"""
    out = run_logged(tmp_path, "trackio", code)
    assert "LOGGED [1000]" in out
    db = list((tmp_path / "trackio").glob("*.db"))
    assert [p.stem for p in db] == ["indgen-test"]
    import sqlite3

    con = sqlite3.connect(db[0])
    rows = con.execute("SELECT step, metrics FROM metrics").fetchall()
    ((step, metrics),) = rows
    metrics = json.loads(metrics)
    assert step == 1000 and metrics["pick_y/L0/success"] == 0.9 and metrics["pick_y/L0/n"] == 10
    assert metrics["pick_y/L1/ci_high"] == pytest.approx(0.4042, abs=1e-3)  # Wilson 1/10
    assert metrics["pick_y/kstar_pos"] == 1
    assert (
        "pick_y/verdict" in metrics and "levels" in metrics and any(k.startswith("video/") for k in metrics)
    )
    config = json.loads(con.execute("SELECT config FROM configs").fetchone()[0])
    assert config["policy"] == "standin:noop"


@pytest.mark.slow  # ~9 s: wandb's offline run; trackio's stays in the default suite
def test_wandb_offline_writes_a_local_run(tmp_path):
    pytest.importorskip("wandb")
    run = a_run(tmp_path)
    code = f"""
from indgen_vla.app.engine.trackers import log_runs
print("LOGGED", log_runs("wandb", [(None, {str(run)!r})], project="indgen-test", name="one",
                         directory={str(tmp_path / "wandb")!r}))
"""
    out = run_logged(tmp_path, "wandb", code)
    assert "LOGGED [0]" in out
    (log,) = (tmp_path / "wandb").rglob(
        "offline-run-*/run-*.wandb"
    )  # the offline run, for `wandb sync` later
    raw = log.read_bytes()
    for key in (
        b"pick_y/L0/success",
        b"pick_y/L1/ci_high",
        b"pick_y/kstar_pos",
        b"pick_y/verdict",
        b"fingerprint",
    ):
        assert key in raw
    (table,) = log.parent.rglob("levels_*.table.json")
    t = json.loads(table.read_text())
    assert t["columns"][:5] == ["axis", "level", "n", "successes", "rate"]
    assert t["data"][1][:5] == ["pick_y", 1, 10, 1, 0.1] and t["data"][1][6] == pytest.approx(
        0.4042, abs=1e-3
    )
    assert list(log.parent.rglob("*.mp4"))


def test_a_missing_tracker_is_one_line(tmp_path, monkeypatch):
    from indgen_vla.app.engine import trackers
    from indgen_vla.core.errors import ConfigError

    monkeypatch.setitem(sys.modules, "trackio", None)  # as if not installed
    with pytest.raises(ConfigError, match=r"--log trackio needs the trackio package; pip install"):
        trackers.log_runs("trackio", [(None, a_run(tmp_path))])


@pytest.mark.slow  # a real evaluate in a subprocess
def test_evaluate_log_trackio_end_to_end(tmp_path):
    pytest.importorskip("trackio")
    out = tmp_path / "run"
    code = f"""
from indgen_vla.app.cli import main
rc = main(["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0",
           "--episodes", "5", "--max-steps", "5", "--workers", "1", "--out", {str(out)!r}, "--log", "trackio",
           "--log-project", "e2e"])
print("RC", rc)
"""
    assert "RC 0" in run_logged(tmp_path, "trackio", code)
    import sqlite3

    con = sqlite3.connect(tmp_path / "trackio" / "e2e.db")
    ((metrics,),) = con.execute("SELECT metrics FROM metrics").fetchall()
    m = json.loads(metrics)
    assert m["pick_y/L0/n"] == 5 and m["pick_y/L0/success"] == 0.0
    config = json.loads(con.execute("SELECT config FROM configs").fetchone()[0])
    assert config["fingerprint"]["scene"] == "pick_place" and len(config["fingerprint_digest"]) == 12


def test_api_log_is_the_log_flag_and_a_missing_tracker_runs_nothing(tmp_path, monkeypatch, capsys):
    """``indgen_vla.evaluate(log=...)`` is ``--log``: a tracker that is unknown or not installed is one line before any
    episode runs (no run directory), as the command now refuses it too."""
    import indgen_vla
    from indgen_vla.core.errors import ConfigError

    args = dict(policy="standin:random", scene="pick_place", axis="pick_y", levels="0", episodes=1, workers=1)
    with pytest.raises(ConfigError, match=r"^--log must be one of trackio, wandb, got 'mlflow'$"):
        indgen_vla.evaluate(**args, out=tmp_path / "a", log="mlflow")
    monkeypatch.setitem(sys.modules, "trackio", None)  # as if not installed
    with pytest.raises(ConfigError, match=r"^--log trackio needs the trackio package; pip install"):
        indgen_vla.evaluate(**args, out=tmp_path / "b", log="trackio")
    from indgen_vla.app.cli import main

    cli = [
        "evaluate",
        *[f"--{k}={v}" for k, v in args.items()],
        f"--out={tmp_path / 'c'}",
        "--log",
        "trackio",
    ]
    assert main(cli) == 2
    assert capsys.readouterr().err.startswith("error: --log trackio needs the trackio package")
    assert not any((tmp_path / d).exists() for d in "abc")


def test_api_evaluate_logs_to_trackio_offline(tmp_path):
    """The Python API's ``log="trackio"``, ``log_project=``: the run's rates reach a local project, nothing leaves."""
    pytest.importorskip("trackio")
    code = f"""
import indgen_vla
run = indgen_vla.evaluate(policy="standin:random", scene="pick_place", axis="pick_y", levels="0", episodes=5,
                          max_steps=5, workers=1, out={str(tmp_path / "run")!r}, quiet=True, log="trackio",
                          log_project="api")
print("RUN", run.path.name)
"""
    assert "RUN run" in run_logged(tmp_path, "trackio", code)
    import sqlite3

    con = sqlite3.connect(tmp_path / "trackio" / "api.db")
    ((step, metrics),) = con.execute("SELECT step, metrics FROM metrics").fetchall()
    assert step == 0 and json.loads(metrics)["pick_y/L0/n"] == 5


def test_api_series_refuses_a_missing_tracker_before_any_checkpoint(tmp_path, monkeypatch):
    import indgen_vla
    from indgen_vla.core.errors import ConfigError

    proto = indgen_vla.EvalConfig.from_flat(policy="series", scene="pick_place", axes=("pick_y",), out="x")
    cfg = indgen_vla.SeriesConfig(protocol=proto, roots=(str(tmp_path / "nope"),), out=str(tmp_path / "s"))
    monkeypatch.setitem(sys.modules, "wandb", None)  # as if not installed
    with pytest.raises(ConfigError, match=r"^--log wandb needs the wandb package"):
        indgen_vla.series(cfg, log="wandb")  # before the missing checkpoint directory is even looked at
    assert not (tmp_path / "s").exists()


@pytest.mark.slow  # two real evaluations of the shipped checkpoint
def test_series_logs_each_checkpoint_at_its_step(tmp_path):
    """``indgen series ... --log trackio`` (through ``indgen_vla.series(log=...)``): one tracker run named after --out,
    each checkpoint's rates at its training step."""
    pytest.importorskip("trackio")
    pytest.importorskip("lerobot")
    for step in (100, 200):
        (tmp_path / f"step_{step}").symlink_to(ROOT / "checkpoints" / "act_pick_place_human")
    code = f"""
from indgen_vla.app.cli import main
rc = main(["series", {str(tmp_path / "step_100")!r}, {str(tmp_path / "step_200")!r}, "--scene", "pick_place",
           "--axis", "pick_y", "--levels", "0", "--episodes", "1", "--max-steps", "5", "--workers", "1",
           "--out", {str(tmp_path / "s")!r}, "--log", "trackio", "--log-project", "ser"])
print("RC", rc)
"""
    assert "RC 0" in run_logged(tmp_path, "trackio", code)
    import sqlite3

    con = sqlite3.connect(tmp_path / "trackio" / "ser.db")
    rows = con.execute("SELECT run_name, step, metrics FROM metrics ORDER BY step").fetchall()
    assert [(r[0], r[1]) for r in rows] == [("s", 100), ("s", 200)]
    assert all(json.loads(r[2])["pick_y/L0/n"] == 1 for r in rows)
