"""The pure helpers of scripts/bench_vs_lerobot.py: profile categories, paired ratios (its placeholder assets are
scenes.libero.overlay, tested in tests/scenes/test_libero_overlay.py)."""

import importlib.util
from pathlib import Path

import pytest

_spec = importlib.util.spec_from_file_location(
    "bench_vs_lerobot", Path(__file__).resolve().parents[2] / "scripts" / "bench_vs_lerobot.py"
)
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


def test_parse_sizes_accepts_lists_and_refuses_bad_input():
    assert bench.parse_sizes("128,256") == [128, 256]
    for bad in ("", "128,x", "0", "-5"):
        with pytest.raises(SystemExit, match="--sizes"):
            bench.parse_sizes(bad)


def test_categorize_takes_the_first_matching_rule_over_the_whole_stack(tmp_path):
    raw = tmp_path / "p.txt"
    raw.write_text(
        "rollout (lerobot_eval.py:1);step (robosuite/environments/base.py:2);render (robosuite/utils/binding_utils.py:3) 6\n"
        "step (robosuite/environments/base.py:2);run_controller (robosuite/robots/single_arm.py:9) 3\n"
        "render_frame (lerobot_eval.py:4);render (lerobot/envs/libero.py:281);render (robosuite/utils/binding_utils.py:3) 1\n"
        "not a sample line\n"
    )
    shares = bench.categorize(raw)
    assert shares == {"render": 60.0, "physics (OSC control + mj_step)": 30.0,
                      "video (lerobot's extra frames + mp4)": 10.0}  # fmt: skip


def test_paired_ratio_is_the_geometric_mean_with_a_t_interval():
    r = bench.paired_ratio([2.0, 4.0], [1.0, 2.0])
    assert r["ratio"] == 2.0 and r["ci95"] == [2.0, 2.0] and r["n"] == 2 and r["paired"]
    r = bench.paired_ratio([3.0, 1.0], [1.0, 1.0])
    assert r["ratio"] == pytest.approx(3**0.5, abs=1e-3) and r["ci95"][0] < 1.0 < 3.0 < r["ci95"][1]
    assert bench.paired_ratio([1.5], [1.0])["ci95"] is None
