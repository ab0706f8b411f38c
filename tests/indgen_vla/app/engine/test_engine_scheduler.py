"""The local engine's job queue: a slot keeps the scene it holds (one build per cell, not one per worker and cell),
and which slot runs an episode changes no outcome."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from indgen_vla.app.engine.config import EvalConfig, plan_episodes
from indgen_vla.app.engine.local import Handoff, LocalOptions, run_local
from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
from indgen_vla.app.engine.scheduler import JobQueue, first_jobs
from indgen_vla.core.protocol.plan import EpisodeJob
from scenes.family import get_scene
from scenes.planning import SceneLevels, scene_levels
from tests.fixtures.feedback import feedback_policy_class

pytestmark = pytest.mark.filterwarnings("ignore")
StateFeedback = feedback_policy_class()


def _jobs(cells: dict[str, int]) -> list[EpisodeJob]:
    """Plan-ordered episodes of one task and axis: ``{level name: episodes}``, levels as given."""
    return [EpisodeJob("t", "ax", int(k), i, seed=i, param=0.0) for k, n in cells.items() for i in range(n)]


def test_a_slot_keeps_its_cell_and_a_free_slot_takes_the_least_run_cell():
    """Cells 0 (3 episodes), 1 (2), 2 (1), two slots: the sequence follows the rule by hand."""
    q = JobQueue(_jobs({"0": 3, "1": 2, "2": 1}))
    took = lambda slot: (lambda j: j and (j.level, j.episode))(q.take(slot))  # noqa: E731
    assert took(0) == (0, 0)  # empty slots: cell 0 (no one runs it) ...
    assert took(1) == (1, 0)  # ... then cell 1: cell 0 is run by slot 0, cell 1 by no one
    assert took(0) == (0, 1)  # a slot stays on its cell
    assert took(1) == (1, 1)
    assert took(1) == (2, 0)  # cell 1 is done: cell 2 (run by no one) before cell 0 (run by slot 0)
    assert took(1) == (0, 2)  # cell 2 is done: the only cell left, although slot 0 runs it
    assert took(0) is None and took(1) is None and not q


def test_more_slots_than_cells_share_the_least_run_cells_in_plan_order():
    q = JobQueue(_jobs({"0": 4, "1": 1}))
    assert [(j.level, j.episode) for j in (q.take(s) for s in range(4))] == [(0, 0), (1, 0), (0, 1), (0, 2)]
    assert q.take(1).episode == 3 and q.take(1) is None  # slot 1's cell is done: it joins cell 0


def test_early_workers_prepare_what_the_slots_start_with():
    jobs = _jobs({"0": 3, "-1": 3, "1": 3})
    assert [(j.level, j.episode) for j in first_jobs(jobs, 2)] == [(0, 0), (-1, 0)]
    assert len(first_jobs(jobs[:1], 4)) == 1


@dataclasses.dataclass(frozen=True)
class CountingLevels(SceneLevels):
    """SceneLevels that appends a line per scene build to ``log`` (worker processes pickle it)."""

    log: str = ""

    def make_env(self, task, axis, level, **kw):
        with open(self.log, "a") as f:
            f.write(f"{task} {axis} {level}\n")
        return super().make_env(task, axis, level, **kw)


def _counted(log: Path, levels: list[int], episodes: int) -> tuple[list, RunnerConfig]:
    """pick_place's first task at ``levels`` (``episodes`` each, 6 steps), built by a builder that logs to ``log``."""
    import scenes

    task = list(scenes.get_scene("pick_place").tasks)[0]
    cfg = EvalConfig.from_flat(
        policy="test", scene="pick_place", axes=("pick_y",), out="-", episodes=episodes
    )
    jobs = plan_episodes(cfg, [task], {"pick_y": levels}, {(task, "pick_y", k): 0.02 * k for k in levels})
    log.touch()
    base = scene_levels(get_scene("pick_place"), ["pick_y"])
    rc = RunnerConfig(levels=CountingLevels(base.family, base.successors, log=str(log)), cameras=(),
                      image_size=(64, 64), max_steps=6, privileged=False)  # fmt: skip
    return jobs, rc


def _run(tmp_path: Path, workers: int, levels=(0, 1, -1), episodes: int = 3) -> tuple[list, list[str]]:
    log = tmp_path / f"builds_{workers}_{len(levels)}x{episodes}.txt"
    jobs, rc = _counted(log, list(levels), episodes)
    records: list = []
    run_local(
        jobs,
        rc,
        StateFeedback,
        RunMeta("r", "test", "", "pick_place"),
        records.append,
        LocalOptions(workers=workers, replan_steps=5),
    )
    rows = sorted((r.task, r.axis, r.level, r.episode, r.seed, r.success, r.steps, r.status) for r in records)
    return rows, log.read_text().splitlines()


def test_two_workers_build_each_cell_about_once_with_the_records_of_one(tmp_path):
    """3 levels x 3 episodes on 2 worker processes: at most cells + workers - 1 = 4 scene builds (plan order
    would give each worker most cells: 5-6), and the records equal one in-process worker's."""
    ref, ref_builds = _run(tmp_path, workers=1)
    got, builds = _run(tmp_path, workers=2)
    assert len(ref) == 9 and all(r[-1] == "ok" for r in ref)
    assert got == ref
    assert len(ref_builds) == 3  # one worker: one build per cell
    assert len(set(builds)) == 3 and len(builds) <= 4, builds


def _rounds(tmp_path: Path, name: str, levels: list[int], episodes: int, workers: int, split: int):
    """The plan's episodes in two run_local calls (episodes < ``split``, then the rest), the workers kept between
    them; the builds each call made, the two calls' pools and the records of both."""
    log = tmp_path / f"{name}.txt"
    jobs, rc = _counted(log, levels, episodes)
    records: list = []
    builds, pools, kept = [], [], []
    try:
        for part in ([j for j in jobs if j.episode < split], [j for j in jobs if j.episode >= split]):
            early, kept = kept, []
            run_local(
                part,
                rc,
                StateFeedback,
                RunMeta("r", "test", "", "pick_place"),
                records.append,
                LocalOptions(workers=workers, replan_steps=5),
                handoff=Handoff(early=early, keep=kept),
            )
            builds.append(len(log.read_text().splitlines()) - sum(builds))
            pools.append(list(kept))
    finally:
        for w in kept:
            w.close()
    rows = sorted((r.task, r.axis, r.level, r.episode, r.seed, r.success, r.steps, r.status) for r in records)
    return builds, pools, rows


def test_workers_kept_between_calls_keep_their_processes_and_scenes(tmp_path):
    """Adaptive rounds hand the workers from one ``run_local`` to the next (``keep`` -> ``early``): no new process
    starts and a scene a worker holds is not built again; the records equal one uninterrupted run's."""
    # two worker processes, one cell: round 2 builds nothing and runs in the same processes
    builds, pools, rows = _rounds(tmp_path, "procs", [0], episodes=6, workers=2, split=3)
    assert builds == [2, 0]
    assert [w.proc.pid for w in pools[1]] == [w.proc.pid for w in pools[0]] and len(pools[0]) == 2
    assert len(rows) == 6 and all(r[-1] == "ok" for r in rows)
    # one in-process worker, two cells: it holds level 1 after round 1 and starts round 2 there (1 build, not 2)
    builds, pools, rows = _rounds(tmp_path, "inproc", [0, 1], episodes=4, workers=1, split=2)
    assert builds == [2, 1] and pools[1][0] is pools[0][0]
    ref, _ = _run(tmp_path, workers=1, levels=[0, 1], episodes=4)
    assert (
        rows == ref
    )  # the records of one uninterrupted run (test_adaptive_engine checks the same end to end)
