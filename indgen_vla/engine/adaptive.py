"""``indgen evaluate --adaptive kstar|curve``: run episodes in rounds and stop each level once it is decided.

Between rounds the sequential rule (``indgen_vla.sequential``, docs/adaptive.md) reads the finished episodes
of every level in episode-index order and says which episodes to run next; the engine runs exactly those
(any workers, any backend) and asks again. Decisions depend only on finished outcomes at round boundaries,
so 1 or N workers, and a run killed and resumed, give the same episodes and the same decisions.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from indgen_vla.errors import ConfigError
from indgen_vla.plan import EvalPlan
from indgen_vla.sequential import MODES, RULE_FIELDS, Plan, SequentialRule, level_outcomes, plan_next


def adaptive_plan_entry(mode: str, rule: SequentialRule) -> dict:
    """What the manifest's plan records: the mode and every parameter of the rule (resume must match)."""
    if mode not in MODES:
        raise ConfigError(f"--adaptive must be one of {', '.join(MODES)}, got {mode!r}")
    return {"mode": mode, **{k: getattr(rule, k) for k in RULE_FIELDS}}


def outcomes_of(episodes, task: str, axis: str) -> dict[int, dict[int, bool | None]]:
    """{level: {episode index: success, or None for an error row}} of one task and axis."""
    return level_outcomes(episodes[(episodes["task"] == task) & (episodes["axis"] == axis)])


def plans(
    episodes, task: str, axes: Sequence[str], levels: dict[str, list[int]], rule, mode
) -> dict[str, Plan]:
    """The sequential plan of every axis given the episodes finished so far."""
    return {a: plan_next(rule, levels[a], outcomes_of(episodes, task, a), mode) for a in axes}


def next_round(plan: EvalPlan, episodes, cfg) -> list:
    """The planned episodes the sequential rule wants next, given the episodes finished so far ([] = settled)."""
    by_key = {j.key: j for j in plan.jobs}
    task = plan.tasks[0]  # --adaptive decides one task (EvalConfig refuses --task all)
    levels = {a: sorted(plan.levels[a]) for a in plan.axes}
    current = plans(episodes, task, list(plan.axes), levels, cfg.sequential_rule(), cfg.adaptive)
    return [
        by_key[(task, a, k, i)]
        for a, p in current.items()
        for k, eps in sorted(p.to_run.items())
        for i in eps
    ]


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
