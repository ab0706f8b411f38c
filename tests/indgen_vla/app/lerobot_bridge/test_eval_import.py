"""``indgen import lerobot-eval``: a real lerobot-eval output as a run directory that report, compare and gate read;
two imported runs gate paired by seed, unpaired ones and bad files are refused in one line (exit 2)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.cli import main
from tests.fixtures.lerobot_runs import AXIS, EPISODES, LEVEL, needs_plugin, successes

pytestmark = needs_plugin


def _import(capsys, *args: str) -> tuple[int, str, str]:
    code = main(["import", "lerobot-eval", *args])
    got = capsys.readouterr()
    return code, got.out, got.err


def _copy(src: Path, dst: Path, edit=None) -> Path:
    """A copy of a real eval_info.json, optionally edited (``edit(data)`` changes it in place)."""
    dst.mkdir(parents=True)
    data = json.loads((src / "eval_info.json").read_text())
    if edit is not None:
        edit(data)
    (dst / "eval_info.json").write_text(json.dumps(data))
    return dst


def test_import_pairs_with_indgen_evaluate(lerobot_eval_out, indgen_run, tmp_path, capsys):
    """The imported rows are indgen evaluate's rows (episode, seed, level parameter, outcome); gate pairs them."""
    code, out, _ = _import(capsys, str(lerobot_eval_out), "--out", str(tmp_path / "imp"), "--policy", "act")
    assert code == 0 and "not in eval_info.json: steps" in out
    imp = pd.read_parquet(tmp_path / "imp" / "episodes.parquet").sort_values("episode")
    ref = pd.read_parquet(indgen_run / "episodes.parquet").sort_values("episode")
    cols = ["scene", "task", "axis", "level", "episode", "seed", "param", "success"]
    pd.testing.assert_frame_equal(imp[cols].reset_index(drop=True), ref[cols].reset_index(drop=True))
    manifest = json.loads((tmp_path / "imp" / "manifest.json").read_text())
    (src,) = manifest["imported"]["sources"]
    assert (
        src["task_group"].startswith("indgen@pick_place@milk@pick_y@-1@p-0.155@seed0@first1000")
        and "1000 + episode_ix" in src["reset_seeds"]
    )
    assert "Imported episodes" in (tmp_path / "imp" / "report.md").read_text()
    summary = json.loads((tmp_path / "imp" / "summary.json").read_text())
    (row,) = summary["axes"][AXIS]["levels"]
    assert (row["level"], row["n"], row["successes"]) == (LEVEL, EPISODES, sum(successes(lerobot_eval_out)))
    assert main(["gate", str(indgen_run), str(tmp_path / "imp"), "--json"]) in (0, 5)
    gate = json.loads(capsys.readouterr().out)
    assert (
        gate["paired"]
        and gate["levels"][0]["pairs"] == EPISODES
        and gate["levels"][0]["discordant"] == [0, 0]
    )
    assert main(["compare", str(indgen_run), str(tmp_path / "imp"), "--out", str(tmp_path / "cmp")]) == 0
    cmp = json.loads((tmp_path / "cmp" / "compare.json").read_text())
    assert cmp["paired"] and cmp["test"] == "mcnemar_exact"
    capsys.readouterr()
    code, _, err = _import(capsys, str(lerobot_eval_out), "--out", str(indgen_run))  # never over a real run
    assert code == 2 and "was not imported" in err


def test_gate_of_two_imports_pairs_by_seed_and_refuses_unpaired(lerobot_eval_out, tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert _import(capsys, str(lerobot_eval_out), "--out", str(a))[0] == 0
    assert _import(capsys, str(lerobot_eval_out), "--out", str(b))[0] == 0
    assert main(["gate", str(a), str(b)]) in (0, 5)
    assert "paired exact McNemar" in capsys.readouterr().out

    def drop_last(data):  # a run of one episode fewer: its last seed has no partner
        m = data["per_task"][0]["metrics"]
        for k in ("successes", "sum_rewards", "max_rewards"):
            m[k] = m[k][:-1]
        data["overall"]["n_episodes"] -= 1

    short = _copy(lerobot_eval_out, tmp_path / "short_src", drop_last)
    assert _import(capsys, str(short), "--out", str(tmp_path / "short"))[0] == 0
    assert main(["gate", str(a), str(tmp_path / "short")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "pair episodes by seed" in err and "no partner" in err
    assert main(["compare", str(a), str(tmp_path / "short"), "--out", str(tmp_path / "c")]) == 2  # as compare
    assert "no partner" in capsys.readouterr().err and not (tmp_path / "c").exists()
    # another --seed: the same episode indices, other initial states
    assert _import(capsys, str(lerobot_eval_out), "--out", str(tmp_path / "other"), "--seed", "2000")[0] == 0
    assert main(["gate", str(a), str(tmp_path / "other")]) == 2
    assert "no partner" in capsys.readouterr().err
    # reset seed 2000 + i is indgen's episode 1000 + i (first_seed 1000), started from indgen's seed for it
    from indgen_vla.core.protocol.seeding import evaluation_seed

    rows = pd.read_parquet(tmp_path / "other" / "episodes.parquet").sort_values("episode")
    assert list(rows["episode"]) == [1000 + i for i in range(EPISODES)]
    assert list(rows["seed"]) == [evaluation_seed(0, "pick_place", "milk", 1000 + i) for i in range(EPISODES)]


def _truncate(src: Path, dst: Path) -> Path:
    dst.mkdir(parents=True)
    raw = (src / "eval_info.json").read_bytes()
    (dst / "eval_info.json").write_bytes(raw[: len(raw) // 2])
    return dst


def _edit(fn):
    return lambda src, dst: _copy(src, dst, fn)


def _short_rewards(d):
    d["per_task"][0]["metrics"]["sum_rewards"].pop()


def _overall(d):
    d["overall"]["n_episodes"] += 3


def _not_bool(d):
    d["per_task"][0]["metrics"]["successes"][1] = "yes"


def _neither(d):
    d.pop("per_task")


@pytest.mark.parametrize(
    "make, says",
    [
        (_truncate, "is not valid JSON"),
        (_edit(_short_rewards), "sum_rewards holds"),
        (_edit(_overall), f"overall.n_episodes is {EPISODES + 3} but per_task holds {EPISODES}"),
        (_edit(_not_bool), "successes[1] is 'yes', not true/false"),
        (_edit(_neither), "has neither per_task nor per_episode"),
        (lambda src, dst: dst, "holds no eval_info.json"),
    ],
)
def test_corrupt_or_partial_eval_info_is_one_line(lerobot_eval_out, tmp_path, capsys, make, says):
    bad = make(lerobot_eval_out, tmp_path / "bad")
    code, _, err = _import(capsys, str(bad), "--out", str(tmp_path / "run"))
    assert code == 2 and len(err.strip().splitlines()) == 1 and says in err, err
    assert not (tmp_path / "run" / "episodes.parquet").exists()


def test_older_per_episode_format_and_other_envs(lerobot_eval_out, tmp_path, capsys):
    """lerobot-eval's older per_episode file (seeds recorded) imports to the same rows; another env's task group
    needs --axis/--level and keeps lerobot's reset seeds."""
    ok = successes(lerobot_eval_out)
    group = json.loads((lerobot_eval_out / "eval_info.json").read_text())["per_task"][0]["task_group"]
    legacy = {"per_episode": [{"episode_ix": i, "sum_reward": float(s), "max_reward": float(s), "success": s,
                               "seed": 1000 + i} for i, s in enumerate(ok)],
              "aggregated": {"pc_success": 100 * sum(ok) / len(ok)}}  # fmt: skip
    (tmp_path / "legacy").mkdir()
    (tmp_path / "legacy" / "eval_info.json").write_text(json.dumps(legacy))
    code, _, err = _import(capsys, str(tmp_path / "legacy"), "--out", str(tmp_path / "l"))
    assert code == 2 and "not an indgen level; pass --axis A --level K" in err

    def rename(d):
        d["per_task"][0]["task_group"] = "libero_object"
        d["per_group"] = {"libero_object": d["per_group"].pop(group)}

    other = _copy(lerobot_eval_out, tmp_path / "other_src", rename)
    assert (
        _import(capsys, str(other), "--out", str(tmp_path / "o"), "--axis", "scale", "--level", "1")[0] == 0
    )
    rows = pd.read_parquet(tmp_path / "o" / "episodes.parquet").sort_values("episode")
    assert set(rows["scene"]) == {"lerobot-eval:libero_object"} and set(rows["level"]) == {1}
    assert list(rows["seed"]) == [1000 + i for i in range(len(ok))] and list(rows["success"]) == ok
    assert _import(capsys, str(tmp_path / "legacy"), "--out", str(tmp_path / "l2"), "--axis", "scale",
                   "--level", "1")[0] == 0  # fmt: skip
    legacy_rows = pd.read_parquet(tmp_path / "l2" / "episodes.parquet").sort_values("episode")
    assert list(legacy_rows["seed"]) == list(rows["seed"]) and list(legacy_rows["success"]) == ok
    shutil.rmtree(tmp_path / "o")


def test_series_reads_imported_runs(lerobot_eval_out, tmp_path, capsys):
    """An imported run at S/runs/<step> counts as that checkpoint's evaluation: series skips it and reports it."""
    from tests.fixtures.lerobot_runs import CHECKPOINT

    ckpt = tmp_path / "train" / "checkpoints" / "000002"
    ckpt.mkdir(parents=True)
    (ckpt / "pretrained_model").symlink_to(CHECKPOINT)
    series = tmp_path / "S"
    assert _import(capsys, str(lerobot_eval_out), "--out", str(series / "runs" / "000000002"))[0] == 0
    argv = ["series", str(tmp_path / "train"), "--out", str(series), "--scene", "pick_place", "--axis", AXIS,
            "--levels", f"{LEVEL}:{LEVEL}", "--episodes", str(EPISODES)]  # fmt: skip
    assert main(argv) == 0
    assert "already evaluated" in capsys.readouterr().out
    got = json.loads((series / "series.json").read_text())
    assert got["steps"] == [2] and (series / "series.md").is_file()
    (row,) = got["axes"][AXIS]["levels"][str(LEVEL)]
    assert (row["n"], row["successes"]) == (EPISODES, sum(successes(lerobot_eval_out)))
