"""scripts/bench_engine.py's GPU-box parts run on this CPU with small configs, so a GPU call finds them working:
the policy alone by batch size, engine scaling by worker count against that ceiling (pipelined too), and the
coordinator profile. Numbers are not asserted (they are benchmarks), only that every row is there and consistent."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.fixtures.tiny_policies import build_tiny_checkpoint

pytest.importorskip("lerobot")
pytestmark = pytest.mark.timeout(600)
ROOT = Path(__file__).resolve().parents[2]


def _bench(*args: str) -> tuple[dict, list[str]]:
    """Run the script as a user does; its last line is the result, earlier JSON lines are per-row progress."""
    proc = subprocess.run([sys.executable, "scripts/bench_engine.py", *args], cwd=ROOT, capture_output=True,
                          text=True, timeout=540)  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
    return json.loads(lines[-1]), lines[:-1]


@pytest.fixture(scope="module")
def act2cam(tmp_path_factory) -> str:
    return build_tiny_checkpoint(
        "act", tmp_path_factory.mktemp("act"), cameras=("agentview", "wrist"), size=32
    )


@pytest.mark.slow  # ~20 s: a lerobot import for the checkpoint and one for the script (benchmarks run on demand)
def test_model_part_times_each_batch_size(act2cam):
    out, _ = _bench(
        "--only", "model", "--policy", f"lerobot:{act2cam}", "--batches", "1,3", "--seconds", "0.05"
    )
    assert out["device"] == "cpu" and out["precision"] == "fp32" and out["compile"] == "off"
    for b in (1, 3):
        row = out[f"b{b}"]
        assert row["calls"] >= 3 and row["ms_per_act"] > 0 and row["gpu_busy_pct"] is None
        assert row["obs_per_s"] == pytest.approx(b * 1000 / row["ms_per_act"], rel=0.05)


@pytest.mark.slow  # ~25 s
def test_scaling_part_in_process_worker_reports_its_ceiling(act2cam):
    """One worker steps in the main process (no fork): the cheapest run that goes through every column."""
    out, progress = _bench("--only", "scaling", "--policy", f"lerobot:{act2cam}", "--workers", "1",
                           "--episodes", "2", "--max-steps", "4", "--seconds", "0.05")  # fmt: skip
    assert (
        out["scaling_cameras"] == ["agentview", "wrist"] and out["replan"] == 10 and out["pipeline"] is False
    )
    row = out["w1"]
    assert json.loads(progress[-1]) == {"w1": row}  # printed as it finished, for a run cut by a timeout
    assert row["control_steps"] == 2 * 4
    assert row["ceiling_steps_per_s"] == pytest.approx(
        1 * 10 * 1000 / row["model_alone_ms_per_act"], rel=0.01
    )
    if row["steps_per_s_net_of_start"] is not None:
        assert row["share_of_model_alone"] == pytest.approx(
            row["steps_per_s_net_of_start"] / row["ceiling_steps_per_s"], rel=0.01
        )


@pytest.mark.slow  # ~1-2 min on 2 cores: worker processes, two lanes each, and a reduced pi0.5 build
def test_scaling_part_pipelined_with_reduced_pi05(tmp_path):
    """The issue-28 GPU row (pi0.5 in the engine, lanes on) on the reduced model: workers fork, each runs two
    environments, the ceiling is the model alone at batch W."""
    sys.path.insert(0, str(ROOT / "scripts"))
    import build_real_size

    spec = build_real_size.build_pi05(tmp_path / "pi05", reduced=True) + "&replan=5"
    out, _ = _bench("--only", "scaling", "--policy", spec, "--workers", "2", "--episodes", "4", "--max-steps",
                    "10", "--pipeline", "--precision", "bf16", "--seconds", "0.2")  # fmt: skip
    assert out["pipeline"] is True and out["replan"] == 5
    assert out["fork_server_cpu_s"] > 0  # its preload, warmed with the first task, is reported apart
    row = out["w2"]
    assert row["control_steps"] == 4 * 10 and row["workers_cpu_s"] > 0  # stepped in worker processes
    assert row["ceiling_steps_per_s"] == pytest.approx(2 * 5 * 1000 / row["model_alone_ms_per_act"], rel=0.01)


@pytest.mark.slow  # ~1 min: two runs of 2 workers, one under cProfile
def test_profile_coordinator_splits_the_main_process(act2cam):
    out, _ = _bench("--profile-coordinator", "--policy", f"lerobot:{act2cam}", "--episodes", "2",
                    "--max-steps", "20")  # fmt: skip
    assert out["control_steps"] == 2 * 20 and out["forward_calls"] >= 2 * 20 // 10
    assert out["coordinator_ms_per_step"] > 0
    parts = out["profile_ms_per_step"]
    assert parts["records + Parquet"] > 0 and parts["receive (read + unpickle observations)"] > 0
