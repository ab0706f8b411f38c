"""Certification: the Clopper–Pearson rule against scipy, the sequential early stop, per-task storage and
lookup, resuming, the SUMMARY table, and the up-front strictly-harder checks (compositions included)."""

import json
import math
import os
import re
from pathlib import Path

import pytest
from scipy.stats import beta

import scenes
from indgen_vla.app.certify import certify_levels as certify_run
from indgen_vla.app.certify.suite import default_jobs, write_summary
from indgen_vla.core.errors import ConfigError, EpisodeUnavailableError, UnknownNameError
from indgen_vla.core.protocol.progression import ProgressionError
from indgen_vla.core.runs.records import atomic_write_json
from scenes.certificates import (
    Rule,
    axis_dirname,
    cert_path,
    certification_root,
    episodes_needed,
    find_certification,
    infeasible_levels,
    level_status,
    load_certification,
    lower_bound,
    tree_stamp,
    write_json_atomic,
)
from scenes.family import SceneCertificates, get_scene
from scenes.heldout import SPENDING
from scenes.listing import builtin_scenes
from scenes.planning import resolve_scene_plan
from tests.fixtures.certify import run_certify, run_prepare
from tests.fixtures.levels import level_param
from tests.scenes.conftest import mini  # noqa: F401 (the LIBERO miniature asset fixture)


@pytest.mark.parametrize("x,n", [(59, 59), (58, 58), (20, 20), (57, 59), (10, 30), (1, 1), (0, 5), (95, 100)])
def test_lower_bound_is_scipys_one_sided_beta_quantile(x, n):
    want = 0.0 if x == 0 else beta.ppf(0.05, x, n - x + 1)  # one-sided 95 % Clopper–Pearson lower bound
    assert lower_bound(x, n) == pytest.approx(want, abs=1e-12)


def test_all_successes_need_59_episodes_for_095():
    # with x == n the bound is alpha ** (1 / n): 0.05 ** (1/59) = 0.95051 >= 0.95 > 0.05 ** (1/58) = 0.94970
    assert lower_bound(59, 59) == pytest.approx(0.05 ** (1 / 59)) and lower_bound(59, 59) >= 0.95
    assert lower_bound(58, 58) < 0.95
    assert episodes_needed() == 59 == Rule().n_max
    assert episodes_needed(0.9) == math.ceil(math.log(0.05) / math.log(0.9))  # 29
    assert Rule().status(59, 59) == "certified" and Rule().status(20, 20) == "insufficient"


def test_sequential_rule_stops_once_the_bound_is_out_of_reach():
    r59 = Rule()
    assert r59.stop(0, 1) and r59.status(0, 1) == "failed"  # at n_max 59 any failure is final
    assert r59.stop(40, 41) and not r59.stop(41, 41) and r59.status(41, 41) == "insufficient"
    r = Rule(n_max=100)
    # the most failures out of 100 that still certify, from scipy directly
    allowed = max(f for f in range(101) if beta.ppf(0.05, 100 - f, f + 1) >= 0.95)
    assert allowed == 1
    assert not r.stop(9, 10) and r.status(9, 10) == "insufficient"  # one failure: 99/100 still reachable
    assert r.stop(8, 10) and r.status(8, 10) == "failed"  # two failures: stop at once
    assert r.status(99, 100) == "certified" and r.status(98, 100) == "failed"
    # replaying an outcome sequence: stops right after the failure that makes 0.95 unreachable
    seq, s = [True] * 30 + [False] + [True] * 20 + [False] + [True] * 48, 0
    for n, ok in enumerate(seq, start=1):
        s += ok
        if r.stop(s, n):
            break
    assert n == 52 and r.status(s, n) == "failed"
    with pytest.raises(ConfigError, match="threshold"):
        Rule(threshold=1.0)


def test_failing_level_stops_after_one_episode_and_is_refused(tmp_path):
    # 5 control steps cannot solve stack: the first failure ends the level (59 would be needed)
    out = tmp_path / "c" / "certify.json"
    cert = run_certify("stack", "stack", levels="0", max_steps=5, path=out)
    row = cert["levels"][0]
    assert (row["n"], row["successes"], row["status"], row["certified"], row["feasible"]) == (
        1,
        0,
        "failed",
        False,
        False,
    )
    assert row["stopped_early"] and row["lower_bound"] == 0.0 and infeasible_levels(cert) == [0]
    assert cert["rule"] == {
        "name": "clopper-pearson-sequential-held-out",
        "threshold": 0.95,
        "confidence": 0.9515,  # attempt 1 spends 0.0485 of the 0.05 (scenes.heldout): still 59/59
        "n_max": 59,
        "alpha": 0.05,
        "spending": SPENDING,
    }
    # the first attempt draws block 1 (block 0 is burnt) and records itself, with its outcome and oracle
    (attempt,) = row["attempts"]
    assert row["block"] == attempt["block"] == 1 and attempt["attempt"] == 1 and attempt["held_out"]
    assert (attempt["n"], attempt["successes"], attempt["status"], attempt["alpha"]) == (
        1,
        0,
        "failed",
        0.0485,
    )
    assert attempt["oracle"]["code_hash"] == cert["oracle"]["code_hash"] and "certified_on" not in row
    assert load_certification(out)["levels"] == cert["levels"]


def test_certify_is_per_task_resumable_and_atomic(tmp_path):
    root = tmp_path / "certs"
    a = cert_path(get_scene("stack"), "orange_on_blue", "stack", root=root)
    assert a == root / "stack" / "orange_on_blue" / "stack" / "certify.json"
    cert = run_certify("stack", "stack", task="orange_on_blue", levels="0", episodes=1, max_steps=5, path=a)
    assert cert["levels"][0]["status"] == "failed" and cert["task"] == "orange_on_blue"  # 5 steps: no success
    assert [p.name for p in a.parent.iterdir()] == ["certify.json"]  # no temp files left behind
    assert (
        find_certification(get_scene("stack"), "orange_on_blue", "stack", root=root)["task"]
        == "orange_on_blue"
    )
    assert (
        find_certification(get_scene("stack"), None, "stack", root=root) is not None
    )  # None: the first task
    other = list(scenes.get_scene("stack").tasks)[1]
    assert (
        find_certification(get_scene("stack"), other, "stack", root=root) is None
    )  # never inherits another task's
    assert find_certification(get_scene("stack"), "orange_on_blue", "stack", step=0.5, root=root) is None
    logs = []
    again = run_certify(
        "stack",
        "stack",
        task="orange_on_blue",
        levels="0:1",
        episodes=1,
        max_steps=5,
        path=a,
        log=logs.append,
    )
    assert any("reusing levels [0]" in m for m in logs) and [r["level"] for r in again["levels"]] == [0, 1]
    assert again["levels"][0] == cert["levels"][0]
    logs.clear()
    run_certify(
        "stack",
        "stack",
        task="orange_on_blue",
        levels="0",
        episodes=1,
        seed=1,
        max_steps=6,
        path=a,
        log=logs.append,
    )
    assert any("replacing" in m for m in logs)  # another episode length does not reuse


def test_find_certification_reads_old_and_new_rows(tmp_path, monkeypatch):
    d = tmp_path / "stack" / "orange_on_blue" / "stack"
    rows = [
        {
            "level": 0,
            "param": 0.0,
            "n": 59,
            "successes": 59,
            "rate": 1.0,
            "feasible": True,
            "status": "certified",
        },
        {"level": 1, "param": 0.25, "n": 20, "successes": 20, "rate": 1.0, "feasible": True},  # old 20/20 row
        {"level": 2, "param": 0.5, "n": 20, "successes": 18, "rate": 0.9, "feasible": False},
    ]
    write_json_atomic(d / "certify.json", {"scene": "stack", "task": "orange_on_blue", "axis": "stack",
                                           "step": 0.25, "unit": "in", "levels": rows})  # fmt: skip
    monkeypatch.setenv("INDGEN_CERT_DIR", str(tmp_path))
    cert = find_certification(get_scene("stack"), "orange_on_blue", "stack")
    assert [level_status(r) for r in cert["levels"]] == ["certified", "insufficient", "failed"]
    assert infeasible_levels(cert) == [2]
    summary = write_summary(tmp_path).read_text()
    assert (
        "| stack | orange_on_blue | stack | 0.25 in | 0: 59/59~ 1: 20/20? 2: 18/20! | 0 | 1, 2, 3, 4 | v1 |"
        in summary
    )
    assert f"0 of {len(default_jobs())} default" in summary


def test_default_jobs_put_every_tasks_first_axis_first():
    jobs = default_jobs()
    n_first = sum(len(s.tasks) for s in builtin_scenes())
    assert all(a == list(scenes.get_scene(s).axes)[0] for s, _, a in jobs[:n_first])
    assert ("pick_place", "bread", "pick_y+distractor") in jobs[n_first:]
    assert len(jobs) == len(set(jobs)) == 7 * 7 + 4 * 6 + 5 * 3


def test_strictly_harder_is_checked_up_front_for_axes_and_compositions(tmp_path):
    resolve_scene_plan(get_scene("pick_place"), None, ["pick_y"])
    resolve_scene_plan(get_scene("pick_place"), None, ["pick_y+distractor"])
    with pytest.raises(ProgressionError, match="placement jitter"):
        resolve_scene_plan(get_scene("pick_place"), None, ["pick_y"], step=0.005)
    preset = tmp_path / "small.yaml"
    preset.write_text("axes:\n  pick_y: {step: 0.005}\n")
    with pytest.raises(ProgressionError, match=r"component pick_y at step 0.005"):
        resolve_scene_plan(get_scene("pick_place"), None, ["pick_y+distractor"], preset=str(preset))
    preset.write_text("axes:\n  goal_y: {step: 0.004}\n")
    with pytest.raises(ProgressionError, match="component goal_y"):
        resolve_scene_plan(get_scene("stack"), None, ["goal_y+distractor"], preset=str(preset))
    with pytest.raises(ProgressionError):  # certify refuses before building any env
        run_certify("pick_place", "pick_y", step=0.005, episodes=1, path=tmp_path / "x" / "certify.json")
    assert not (tmp_path / "x").exists()


def _spec(name: str, step: float | None = None, preset: str | None = None):
    """The spec of ``name`` on pick_place under ``step`` / ``preset``, as the plan resolves it."""
    return resolve_scene_plan(get_scene("pick_place"), None, [name], step=step, preset=preset).axes[name]


def test_axes_preset_steps_reach_specs_params_and_folders(tmp_path):
    (tmp_path / "wide.yaml").write_text("axes:\n  pick_y: {step: 0.05, max_level: 2}\n")
    p = str(tmp_path / "wide.yaml")
    spec = _spec("pick_y+distractor", preset=p)
    assert "pick_y (0.05 m)" in spec.description and spec.max_level == 2
    base = level_param("pick_place", None, "pick_y", 1)
    assert level_param("pick_place", None, "pick_y", 1, preset=p) == pytest.approx(base + 0.025)
    assert axis_dirname("pick_y+distractor") == "pick_y+distractor"
    assert axis_dirname("pick_y+distractor", preset=p) == "pick_y+distractor@pick_y=0.05,distractor=1"
    assert axis_dirname("pick_y", preset="paper") == "pick_y"  # the paper preset states the defaults
    with pytest.raises(UnknownNameError, match="did you mean 'paper'"):
        _spec("pick_y", preset="papr")
    (tmp_path / "bad.yaml").write_text("axes: [pick_y\n")
    with pytest.raises(ConfigError, match="invalid YAML"):
        _spec("pick_y", preset=str(tmp_path / "bad.yaml"))
    (tmp_path / "typo.yaml").write_text("axes:\n  pick_z: {step: 0.05}\n")
    with pytest.raises(
        ConfigError, match=r"unknown axis in preset .*typo.yaml: 'pick_z'; did you mean 'pick_y', 'pick_x'"
    ):
        _spec("pick_y", preset=str(tmp_path / "typo.yaml"))
    with pytest.raises(ConfigError, match="--axes-preset NAME"):
        _spec("pick_y+distractor", step=0.05)


def test_json_is_written_atomically(tmp_path):
    p = tmp_path / "a" / "certify.json"
    write_json_atomic(p, {"x": 1})
    write_json_atomic(p, {"x": 2})
    assert json.loads(p.read_text()) == {"x": 2} and [q.name for q in p.parent.iterdir()] == ["certify.json"]


def test_libero_certificates_are_cached_per_asset_tree(mini):  # noqa: F811
    import hashlib

    cache = os.environ["INDGEN_CACHE"]
    tag = hashlib.sha1(str(mini.resolve()).encode()).hexdigest()[:12]
    assert certification_root(get_scene("libero_object")) == Path(cache) / "certification" / tag
    assert certification_root(get_scene("pick_place")).parts[-2:] == (
        "scenes",
        "certification",
    )  # built-ins: committed
    assert (
        cert_path(get_scene("libero_object"), None, "pick_y").parent.parent.parent.parent
        == Path(cache) / "certification" / tag
    )


@pytest.mark.slow
def test_workers_give_the_same_certificate(tmp_path):
    kw = dict(task="orange_on_blue", levels="0:2", episodes=2)
    one = run_certify("stack", "stack", workers=1, path=tmp_path / "a" / "certify.json", **kw)
    two = run_certify("stack", "stack", workers=2, path=tmp_path / "b" / "certify.json", **kw)
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in one["levels"]]
    assert strip == [{k: v for k, v in r.items() if k != "wall_s"} for r in two["levels"]]
    assert [r["level"] for r in load_certification(tmp_path / "b")["levels"]] == [0, 1, 2]


def test_an_asset_file_changed_in_place_voids_the_certificate(tmp_path, monkeypatch):
    """LIBERO's and RoboCasa365's certificates are cached per asset tree path: a tree updated at the same path (here
    one file rewritten, same size) must not keep the old tree's certificate, nor must one made before certificates
    recorded their tree. Played on ``stack`` given an asset tree (5 control steps: one failed episode, cheap)."""
    tree = tmp_path / "assets"
    (tree / "objects").mkdir(parents=True)
    (tree / "objects" / "box.xml").write_text("<mujoco model='a'/>")
    given = type("GivenTree", (SceneCertificates,), {"asset_tree": lambda self: tree})
    monkeypatch.setattr(type(get_scene("stack")), "Certificates", given)
    root = tmp_path / "certs"
    out = cert_path(get_scene("stack"), None, "stack", root=root)
    run_certify("stack", "stack", levels="0", episodes=1, max_steps=5, path=out)
    cert = find_certification(get_scene("stack"), None, "stack", root=root)
    assert cert is not None and cert["assets"]["root"] == str(tree.resolve()) and cert["assets"]["files"] == 1
    (tree / "objects" / "box.xml").write_text("<mujoco model='b'/>")  # same path and size, other content
    tree_stamp.cache_clear()  # the next command sees the tree as it is now
    assert find_certification(get_scene("stack"), None, "stack", root=root) is None
    logs = []
    run_certify("stack", "stack", levels="0", episodes=1, max_steps=5, path=out, log=logs.append)
    assert any("made on other asset files than" in m for m in logs), logs  # made again, not reused
    assert find_certification(get_scene("stack"), None, "stack", root=root) is not None
    old = json.loads(out.read_text())
    del old["assets"]  # as written before certificates recorded their tree
    out.write_text(json.dumps(old))
    assert find_certification(get_scene("stack"), None, "stack", root=root) is None


def test_certify_builds_its_levels_through_the_plan(tmp_path):
    """certify resolves its axis as evaluate does and hands each level job the plan's builder (the one road)."""
    p = run_prepare(
        "pick_place", "pick_y+distractor", task="lemon", levels="0:1", episodes=1, path=tmp_path / "c.json"
    )
    plan = resolve_scene_plan(get_scene("pick_place"), "lemon", ["pick_y+distractor"], "0:1")
    assert [(j.task, j.axis, j.level) for j in p.jobs] == [
        ("lemon", "pick_y+distractor", 0),
        ("lemon", "pick_y+distractor", 1),
    ]
    assert all(j.builder == plan.builder for j in p.jobs)
    assert p.cert["steps"] == {"pick_y": 0.025, "distractor": 1.0} and p.levels == [0, 1]
    with pytest.raises(ConfigError, match="write a held axis as A@B=j") as e:
        run_prepare("pick_place", "pick_y@distractor", episodes=1)
    assert "\n" not in str(e.value)


def test_a_seed_that_cannot_hold_the_level_is_skipped_and_counted(monkeypatch):
    """``EpisodeUnavailableError`` (a RoboCasa kitchen too narrow for pick_x): that seed is no episode of the level;
    certification goes on with the next seed index and the row counts it; a level too few seeds hold is ``failed``,
    with the reason in its row (a batch goes on to its next level)."""

    class Env:
        axis_param, calls, out = 0.0, [], {1}

        def reset(self, seed):
            self.calls.append(seed)
            if len(self.calls) - 1 in self.out:
                raise EpisodeUnavailableError(f"seed {seed}: a 0.165 m range")

        def close(self):
            pass

    class Builder:  # the plan's builder, building the stand-in above
        scene, family = "stack", get_scene("stack")

        def make_env(self, *args, **kwargs):
            return Env()

    monkeypatch.setattr(certify_run, "oracle_for", lambda scene: None)
    monkeypatch.setattr(
        certify_run, "run_oracle_episode", lambda env, policy, seed, i: (env.reset(seed), (True, 9))[1]
    )
    rule = certify_run.Rule(n_max=3)
    row = certify_run.certify_level(certify_run.LevelJob(Builder(), "t", "a", 0, 0, None, rule))
    assert (row["n"], row["unavailable"], len(Env.calls), len(set(Env.calls))) == (3, 1, 4, 4)
    assert "unavailable" not in certify_run.level_row(0, 0.0, [(True, 9)], rule, 1.0)
    Env.calls, Env.out = [], set(range(10))
    # no seed holds it: failed, with why
    row = certify_run.certify_level(certify_run.LevelJob(Builder(), "t", "a", 0, 0, None, rule))
    assert (row["status"], row["feasible"], row["n"], row["unavailable"]) == ("failed", False, 0, 4)
    assert re.fullmatch(
        r"4 of 4 seeds cannot hold this level, e\.g\. seed \d+: a 0\.165 m range", row["infeasible"]
    )
    assert certify_run.level_line("s", "t", "a", row).endswith("; infeasible: " + row["infeasible"])


def test_summary_counts_shipped_triples_outside_the_default_batch_apart(tmp_path):
    """LIBERO-Object's shipped certificates are not in certify's default batch: counted beside it, never as its."""
    row = {"n": 59, "successes": 59, "rate": 1.0, "feasible": True, "status": "certified"}
    for task in ("bbq_sauce", "butter"):
        d = tmp_path / "libero_object" / task / "goal_y"
        d.mkdir(parents=True)
        levels = [{**row, "level": k, "param": 0.0} for k in range(-3, 4) if (task, k) != ("butter", 3)]
        atomic_write_json(d / "certify.json", {"scene": "libero_object", "task": task, "axis": "goal_y",
                                               "step": 0.0367, "unit": "m", "levels": levels})  # fmt: skip
    summary = write_summary(tmp_path).read_text()
    assert f"0 of {len(default_jobs())} default (scene, task, axis) triples" in summary
    assert "Besides them, 1 of the 2 other triples shipped have every default level certified." in summary
