"""``indgen evaluate --adaptive``: run episodes in rounds until the rule (kstar, curve, until-failure) settles each level.

Every (task, axis) is a ladder with its own decisions; a round holds the next episodes of every ladder still open,
so a whole protocol (``--task all --axis pick_y,goal_y,scale``) runs as one interleaved schedule. Between rounds the
sequential rule (``indgen_vla.core.stats.sprt``, docs/adaptive.md) reads the finished episodes
of every level in episode-index order and says which episodes to run next; the engine runs exactly those
(any workers, any backend) and asks again. Decisions depend only on finished outcomes at round boundaries,
so 1 or N workers, and a run killed and resumed, give the same episodes and the same decisions.
"""

from __future__ import annotations

from collections.abc import Callable

from indgen_vla.app.engine.share import round_rollouts
from indgen_vla.core.protocol.plan import EvalPlan
from indgen_vla.core.stats.sprt import Plan, level_outcomes, plan_next


def outcomes_of(episodes, task: str, axis: str) -> dict[int, dict[int, bool | None]]:
    """{level: {episode index: success, or None for an error row}} of one task and axis."""
    return level_outcomes(episodes[(episodes["task"] == task) & (episodes["axis"] == axis)])


def ladder_outcomes(episodes) -> dict[tuple[str, str], dict[int, dict[int, bool | None]]]:
    """``outcomes_of`` every (task, axis) with episodes, from one pass over the rows (a filter per ladder is
    O(ladders × rows) per round on a protocol of many tasks)."""
    return {(t, a): level_outcomes(g) for (t, a), g in episodes.groupby(["task", "axis"], sort=False)}


def ladder_plans(plan: EvalPlan, episodes, cfg) -> dict[tuple[str, str], Plan]:
    """The sequential plan of every (task, axis) ladder (both directions of a signed axis), from the episodes
    finished so far; each ladder is decided on its own episodes only."""
    rule = cfg.sequential_rule()
    outcomes = ladder_outcomes(episodes)
    return {
        (t, a): plan_next(rule, sorted(plan.levels[a]), outcomes.get((t, a), {}), cfg.adaptive.mode)
        for a in plan.axes
        for t in plan.tasks
    }


def next_round(plan: EvalPlan, episodes, cfg) -> list:
    """The rollouts of the planned episodes every ladder's rule wants next, in one round ([] = all settled): the
    ladders of all tasks and axes run side by side, so a protocol-sized round keeps every worker busy; a shared
    level-0 episode runs once, for its owner axis (``share.round_rollouts``)."""
    return round_rollouts(plan, (
        plan.job((t, a, k, i))
        for (t, a), p in ladder_plans(plan, episodes, cfg).items()
        for k, eps in sorted(p.to_run.items())
        for i in eps
    ))  # fmt: skip


def run_adaptive(plan: EvalPlan, read_episodes: Callable, run_jobs: Callable[[list], None], cfg) -> None:
    """Round after round: ask the rule which planned episodes to run, run them, until every level is settled.

    Args:
        plan: the resolved plan; a subset of its episodes runs.
        read_episodes: () -> the run directory's episodes so far (a DataFrame).
        run_jobs: runs a list of jobs and records them (the local or Ray backend under the progress display).
        cfg: the ``EvalConfig`` (mode, rule and axes).
    """
    last: list = []
    while todo := next_round(plan, read_episodes(), cfg):
        assert todo != last, "the backend ran a round without recording its episodes"
        run_jobs(todo)
        last = todo
