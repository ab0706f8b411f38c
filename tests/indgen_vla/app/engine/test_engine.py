"""The rollout engine on the real pick_place scene with CPU stand-ins (short episodes)."""

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from indgen_vla.app.engine.config import EvalConfig, config_from_args, plan_episodes
from indgen_vla.app.engine.local import LocalOptions, run_local
from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
from indgen_vla.core.errors import ConfigError, PolicyError, RunDirError, UnknownNameError
from indgen_vla.core.protocol.interface import ACTION_DIM, PolicySpec
from indgen_vla.core.runs.records import RunDir
from scenes.family import get_scene
from scenes.planning import scene_levels
from tests.fixtures.kill import kill_midway
from tests.fixtures.resolved import evaluate

pytestmark = pytest.mark.filterwarnings("ignore")


def cfg(tmp_path, **kw):
    base = dict(policy="standin:random", scene="pick_place", axes=("pick_y",), levels="0:1", episodes=2,
                workers=1, max_steps=12, out=str(tmp_path / "run"))  # fmt: skip
    base.update(kw)
    return EvalConfig.from_flat(**base)


def outcomes(run_dir):
    df = pd.read_parquet(Path(run_dir) / "episodes.parquet")
    return {
        (r.task, r.axis, r.level, r.episode): (r.seed, r.success, r.steps, r.status) for r in df.itertuples()
    }


def test_two_level_run_writes_run_dir(tmp_path):
    out = evaluate(cfg(tmp_path), quiet=True)
    df = pd.read_parquet(out / "episodes.parquet")
    assert len(df) == 4 and set(df["level"]) == {0, 1}
    assert (df["status"] == "ok").all() and (df["steps"] == 12).all()
    assert set(df["failure"]) <= {"no_contact", "no_grasp"}  # a random arm for 12 steps lifts nothing
    # episode i has the same seed at every level (paired design), different seeds across episodes
    assert df.groupby("episode")["seed"].nunique().eq(1).all() and df["seed"].nunique() == 2
    summary = json.loads((out / "summary.json").read_text())
    assert [lv["n"] for lv in summary["axes"]["pick_y"]["levels"]] == [2, 2]
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["plan"]["episodes"] == 2 and manifest["versions"]["robosuite"] == "1.4.0"
    # standin:random declares it reads no observation: recorded, and the report says first what it cannot answer
    assert manifest["reads_observations"] is False and summary["reads_observations"] is False
    report = (out / "report.md").read_text().splitlines()
    assert report[2].startswith(
        "**Cannot answer** (standin:random): the policy declares it reads no observation"
    )
    assert any(line.startswith("| 0 |") for line in report) and (out / "plots" / "pick_y.svg").exists()


def test_video_episodes_land_whole_and_named_by_outcome(tmp_path):
    out = evaluate(
        cfg(tmp_path, levels="0", episodes=2, max_steps=2, video=True, video_per_level=1), quiet=True
    )
    df = pd.read_parquet(out / "episodes.parquet").sort_values("episode")
    outcome = "success" if df["success"].iloc[0] else "fail"
    assert df["video"].tolist() == [f"videos/pick_y_L0_{df['task'].iloc[0]}_ep0_{outcome}.mp4", ""]
    assert sorted(p.name for p in (out / "videos").iterdir()) == [
        Path(df["video"].iloc[0]).name
    ]  # no partials
    import imageio_ffmpeg

    assert imageio_ffmpeg.count_frames_and_secs(str(out / df["video"].iloc[0]))[0] >= 2


@pytest.mark.slow  # 8 s; 1 vs 2 workers stay covered by default (pipeline, Ray and adaptive-protocol tests)
def test_oracle_workers_1_vs_2_identical(tmp_path):
    kw = dict(policy="standin:oracle", levels="-1:1", episodes=1, max_steps=None)
    a = evaluate(cfg(tmp_path / "w1", workers=1, **kw), quiet=True)
    b = evaluate(cfg(tmp_path / "w2", workers=2, **kw), quiet=True)
    oa, ob = outcomes(a), outcomes(b)
    assert oa == ob and len(oa) == 3
    assert all(v[1] for v in oa.values()), oa  # the oracle solves these levels
    assert set(pd.read_parquet(Path(a) / "episodes.parquet")["failure"]) == {"none"}


def test_resume_after_sigkill(tmp_path, capsys):
    """The run SIGKILLed is a real process; the reference and the resume run in this one (the same CLI path, two
    interpreter start-ups fewer): the resume reads only what the killed process left on disk."""
    from indgen_vla.app.cli import main

    args = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y",
            "--levels", "0:1", "--episodes", "4", "--workers", "1", "--max-steps", "8"]  # fmt: skip
    ref = tmp_path / "ref"
    assert main([*args, "--out", str(ref)]) == 0
    killed = tmp_path / "killed"
    kept = kill_midway(args, killed, total=8)
    assert 0 < kept < 8
    capsys.readouterr()
    assert main([*args, "--out", str(killed)]) == 0
    assert outcomes(killed) == outcomes(ref) and len(outcomes(ref)) == 8
    said = " ".join(capsys.readouterr().err.split())  # rich wraps at $COLUMNS
    assert f"{kept} of 8 planned episodes already recorded; running the other {8 - kept}" in said


def test_manifest_mismatch_refused(tmp_path):
    evaluate(cfg(tmp_path, levels="0", episodes=1), quiet=True)
    with pytest.raises(RunDirError, match="different plan"):
        evaluate(cfg(tmp_path, levels="0", episodes=3), quiet=True)


def test_a_run_whose_manifest_is_gone_is_not_resumed_by_another_plan(tmp_path):
    """Without manifest.json nothing says which plan made the rows: evaluate with another policy used to adopt
    them ("all 2 planned episodes are already in ...") and report them as its own."""
    out = evaluate(cfg(tmp_path, levels="0", episodes=2), quiet=True)
    (out / "manifest.json").unlink()
    before = (out / "episodes.parquet").read_bytes()
    with pytest.raises(RunDirError, match="holds episodes but no manifest.json"):
        evaluate(cfg(tmp_path, levels="0", episodes=2, policy="standin:noop"), quiet=True)
    assert (out / "episodes.parquet").read_bytes() == before and not (out / "manifest.json").exists()


def test_resuming_a_batched_policy_under_another_worker_count_says_so(tmp_path, capsys):
    """ACT pads its batch to the worker count, and --workers 1 vs 2 gave one episode 107 vs 112 steps here: a
    resume under another count mixed the two without a word. It still goes on (a cluster resume may need to)."""
    from indgen_vla.app.cli import main
    from indgen_vla.core.runs.records import EpisodeRecord

    out = tmp_path / "run"
    args = ["evaluate", "--policy", "lerobot:checkpoints/act_pick_place_human", "--scene", "pick_place", "--axis",
            "pick_y", "--levels", "0", "--episodes", "2", "--max-steps", "5", "--out", str(out)]  # fmt: skip
    assert main([*args, "--workers", "1"]) == 0
    run = RunDir(out)  # episode 1 lost, as a kill before its row leaves the run
    run.rewrite([EpisodeRecord(**r) for r in run.rows() if r["episode"] == 0])
    capsys.readouterr()
    assert main([*args, "--workers", "2"]) == 0
    said = " ".join(capsys.readouterr().err.split())  # rich wraps at $COLUMNS
    assert "warning: resumed with --workers 2, the run began with --workers 1: the policy's batches" in said
    assert len(RunDir.open(out).episodes()) == 2


def test_bad_inputs_are_clear(tmp_path):
    with pytest.raises(UnknownNameError, match="did you mean 'pick_place'"):
        evaluate(cfg(tmp_path, scene="pick_plase"), quiet=True)
    with pytest.raises(ConfigError, match="outside axis pick_y's range"):
        evaluate(cfg(tmp_path, levels="0:9"), quiet=True)
    with pytest.raises(ConfigError, match="--episodes"):
        cfg(tmp_path, episodes=0)


class FlakyPolicy:
    """Raises on the first act of every episode whose seed is even: exercises retry and error rows."""

    def __init__(self, always_fail_seeds=()):
        self.spec = PolicySpec("standin", "test:flaky", chunk_size=4, replan_steps=4, cameras=())
        self.calls: dict[int, int] = {}
        self.always = set(always_fail_seeds)

    def reset(self, instruction, seed=None):
        self.seed = seed
        self.calls[seed] = self.calls.get(seed, 0) + 1

    def act(self, observations):
        if self.seed in self.always or (self.seed % 2 == 0 and self.calls[self.seed] == 1):
            raise PolicyError(f"policy test:flaky failed for seed {self.seed}")
        return np.zeros((len(observations), 4, ACTION_DIM), np.float32)

    def close(self):
        pass


def test_retry_then_error_rows(tmp_path):
    c = cfg(tmp_path, levels="0", episodes=3)
    jobs = plan_episodes(c, _first_task(), {"pick_y": [0]}, {(t, "pick_y", 0): 0.0 for t in _first_task()})
    stubborn = jobs[1].seed
    policy = FlakyPolicy(always_fail_seeds={stubborn})
    records = []
    rc = RunnerConfig(
        levels=scene_levels(get_scene("pick_place"), ["pick_y"]),
        cameras=(),
        image_size=(64, 64),
        max_steps=6,
        privileged=False,
    )
    run_local(
        jobs,
        rc,
        lambda: policy,
        RunMeta("r", "test:flaky", "", "pick_place"),
        records.append,
        LocalOptions(workers=1, replan_steps=4, max_retries=2),
    )
    by_ep = {r.episode: r for r in records}
    assert len(records) == 3
    assert by_ep[1].status == "error" and "attempt 3" in by_ep[1].error and "test:flaky" in by_ep[1].error
    assert (
        by_ep[1].failure == "error" and by_ep[0].failure == by_ep[2].failure == "no_contact"
    )  # zeros: no move
    assert policy.calls[stubborn] == 3  # first try + 2 retries
    assert all(by_ep[e].status == "ok" for e in (0, 2))


def _first_task():
    import scenes

    return list(scenes.get_scene("pick_place").tasks)[:1]


def test_config_from_yaml_and_flags(tmp_path):
    import argparse

    preset = tmp_path / "p.yaml"
    preset.write_text("scene: pick_place\naxis: [pick_y, scale]\nepisodes: 50\nlevels: '-3:3'\n")
    ns = argparse.Namespace(config=str(preset), policy="standin:noop", episodes=5, out="x", axis=None)
    c = config_from_args(ns)
    assert c.plan.axes == ("pick_y", "scale") and c.plan.episodes == 5 and c.plan.levels == "-3:3"
    preset.write_text("episods: 3\n")
    with pytest.raises(ConfigError, match="did you mean episodes"):
        config_from_args(argparse.Namespace(config=str(preset)))


def test_one_unpipelined_env_runs_in_process_without_a_forkserver():
    """Start-up: a single env steps in this process, so nothing starts (or waits for) a forkserver; a pipelined
    worker with more jobs than workers needs its second lane, so it is a process."""
    from indgen_vla.app.engine.local import worker_processes

    assert worker_processes(1, 8, False) == 0 and worker_processes(5, 1, False) == 0
    assert worker_processes(1, 1, True) == 0  # one job: no second lane to pipeline
    assert (
        worker_processes(3, 1, True) == 1
        and worker_processes(3, 2, False) == 2
        and worker_processes(9, 4, True) == 4
    )


class _Unavailable:
    """A real pick_place level whose reset raises EpisodeUnavailableError for the seeds in ``ruled_out`` (as
    RoboCasa's worker does for a kitchen too narrow for pick_x) and otherwise reports its own ``episode_param``."""

    def __init__(self, env, ruled_out: set[int], resets: list[int]):
        self._env, self._out, self._resets = env, ruled_out, resets
        self.episode_param = None

    def __getattr__(self, name):
        return getattr(self._env, name)

    def reset(self, *, seed=None, options=None):
        from indgen_vla.core.errors import EpisodeUnavailableError

        self._resets.append(seed)
        if seed in self._out:
            raise EpisodeUnavailableError(f"seed {seed}: a 0.180 m range (not retried)")
        self.episode_param = 0.5 + seed % 7 / 100  # the episode's own parameter, as the backend measured it
        return self._env.reset(seed=seed, options=options)


class _Zeros(FlakyPolicy):
    def act(self, observations):
        return np.zeros((len(observations), 4, ACTION_DIM), np.float32)


@dataclasses.dataclass(frozen=True)
class _UnavailableLevels:
    inner: object
    ruled_out: frozenset
    resets: list

    scene = "pick_place"
    preload = ()

    def make_env(self, task, axis, level, **kw):
        return _Unavailable(self.inner.make_env(task, axis, level, **kw), set(self.ruled_out), self.resets)

    def describe(self):
        return self.inner.describe()


def test_an_unavailable_episode_is_one_unavailable_row_and_a_backends_own_param_is_recorded(tmp_path):
    """An EpisodeUnavailableError at reset is recorded once as ``unavailable`` (no retry: its seed decides it), with
    its line, and a resume does not run it again; an
    episode whose env reports ``episode_param`` records that, not the plan's parameter. Both loops: the local
    scheduler and the reference ``run_episode`` (Ray)."""
    from indgen_vla.app.engine.rollout import EnvRunner, run_episode

    c = cfg(tmp_path, levels="0", episodes=3)
    jobs = plan_episodes(c, _first_task(), {"pick_y": [0]}, {(t, "pick_y", 0): 0.0 for t in _first_task()})
    out = jobs[1].seed
    resets: list[int] = []
    levels = _UnavailableLevels(scene_levels(get_scene("pick_place"), ["pick_y"]), frozenset({out}), resets)
    rc = RunnerConfig(levels=levels, cameras=(), image_size=(64, 64), max_steps=4, privileged=False)
    records = []
    run_local(
        jobs,
        rc,
        _Zeros,
        RunMeta("r", "test:zeros", "", "pick_place"),
        records.append,
        LocalOptions(workers=1, replan_steps=4, max_retries=2),
    )
    by_ep = {r.episode: r for r in records}
    assert by_ep[1].status == "unavailable" and by_ep[1].error.startswith(
        "attempt 1: EpisodeUnavailableError: seed"
    )
    assert by_ep[1].failure == "unavailable" and by_ep[1].progress is None and not by_ep[1].success
    run = RunDir.create_or_resume(tmp_path / "run", {"run_id": "r", "plan": {}})
    run.append(records)
    assert RunDir.open(tmp_path / "run").done_keys() == {
        r.key for r in records
    }  # a resume re-runs none of them
    assert resets.count(out) == 1 and by_ep[1].param == 0.0  # not retried; no parameter of its own
    assert len(resets) == 3  # the others ran once each
    for e in (0, 2):
        assert by_ep[e].status == "ok" and by_ep[e].param == 0.5 + jobs[e].seed % 7 / 100
    resets.clear()
    rec = run_episode(EnvRunner(rc), _Zeros(), jobs[1], RunMeta("r", "test:zeros", "", "pick_place"), 4, 2)
    assert rec.status == "unavailable" and resets == [out] and "attempt 1:" in rec.error


def test_warmup_steps_render_only_the_last_and_change_no_image(monkeypatch):
    """``--warmup-steps``: nobody reads the images of the warm-up's earlier steps, so only its last step renders; the
    first observation is the one a fully rendered warm-up gives."""
    from indgen_vla.app.engine.rollout import EnvRunner
    from tests.fixtures.renders import count_renders

    renders = count_renders(monkeypatch)
    c = EvalConfig.from_flat(policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=1)
    task = "milk"
    (job,) = plan_episodes(c, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})
    firsts = []
    for lazy in (True, False):
        rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=("agentview",), image_size=(32, 32),
                          max_steps=10, privileged=False, warmup_steps=4, lazy_render=lazy)  # fmt: skip
        runner = EnvRunner(rc)
        renders["n"] = 0
        firsts.append((runner.reset(job).obs.images["agentview"], renders["n"]))
        runner.close()
    (lazy_img, lazy_n), (full_img, full_n) = firsts
    np.testing.assert_array_equal(lazy_img, full_img)
    assert full_n - lazy_n == 3, (lazy_n, full_n)  # the first three warm-up steps' renders are skipped
