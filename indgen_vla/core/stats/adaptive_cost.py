"""What an ``--adaptive`` protocol will cost, before it runs: the project's own sequential rule
(``sequential.plan_next``, the function the engine asks between rounds) played against simulated outcomes of an
assumed success curve, ladder by ladder and round by round, T0 run once for the axes that share it (as
``engine/share.py`` does). Pure and seeded; ``indgen budget`` prints its episodes and rounds (docs/budget.md)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.sprt import SequentialRule, UntilFailure, plan_next

CurveDraw = Mapping[str, Mapping[int, float]]  # axis -> level -> success rate


@dataclass(frozen=True)
class Curve:
    """The success rates assumed per axis and level: a point (``--assume``) or a pilot run's counts, whose
    uncertainty is propagated by drawing each replicate's rates from their Beta(s + ½, n − s + ½) posterior."""

    rates: Mapping[str, Mapping[int, float]] | None = None
    counts: Mapping[str, Mapping[int, tuple[int, int]]] | None = None  # axis -> level -> (successes, n)

    def __post_init__(self):
        if (self.rates is None) == (self.counts is None):
            raise ConfigError("a success curve is either assumed rates or a pilot run's counts, not both")
        for axis, by_level in (self.rates or {}).items():
            for k, p in by_level.items():
                if not 0 <= p <= 1:
                    raise ConfigError(f"assumed success rate of {axis} level {k} must be in [0, 1], got {p}")
        for axis, by_level in (self.counts or {}).items():
            for k, (s, n) in by_level.items():
                if n < 1 or not 0 <= s <= n:
                    raise ConfigError(
                        f"pilot counts of {axis} level {k} must be 0 <= s <= n, n >= 1; got {s}/{n}"
                    )

    @property
    def uncertain(self) -> bool:
        """True for a pilot's counts (each replicate draws its own rates)."""
        return self.counts is not None

    def draw(self, rng: np.random.Generator) -> CurveDraw:
        """One replicate's rates (the point itself for assumed rates)."""
        if self.rates is not None:
            return self.rates
        return {a: {k: float(rng.beta(s + 0.5, n - s + 0.5)) for k, (s, n) in by.items()}
                for a, by in self.counts.items()}  # fmt: skip


def assumed_curve(values: Sequence[float], axes: Sequence[str], levels: Mapping[str, Sequence[int]]) -> Curve:
    """``--assume 0.95,0.9,0.5,0.1``: the rate at |level| 0, 1, 2, ... of every axis and task (both directions)."""
    out = {}
    for a in axes:
        need = max(abs(k) for k in levels[a])
        if len(values) <= need:
            raise ConfigError(
                f"--assume gives {len(values)} rate(s) (|level| 0..{len(values) - 1}) but axis {a} runs level "
                f"{need}: give one rate per |level| 0..{need}, e.g. --assume {','.join(['0.9'] * (need + 1))}"
            )
        out[a] = {k: float(values[abs(k)]) for k in levels[a]}
    return Curve(rates=out)


@dataclass(frozen=True)
class TaskCost:
    """One task's ladders run to the end: rollouts per protocol round (shared T0 counted once)."""

    per_round: tuple[int, ...]

    @property
    def episodes(self) -> int:
        return sum(self.per_round)


def simulate_task(rule: SequentialRule | UntilFailure, mode: str, levels: Mapping[str, Sequence[int]],
                  rates: CurveDraw, owners: Mapping[str, str], rng: np.random.Generator) -> TaskCost:  # fmt: skip
    """Run one task's ladders (one per axis) against Bernoulli outcomes drawn from ``rates``, asking
    ``plan_next`` what to run each round as the engine does; ``owners``: axis -> the axis whose level-0 episodes
    it shares (itself when not shared). Episode i of a level has one outcome, so sharers see their owner's T0."""
    cap = rule.max_episodes
    draws = {a: {k: rng.random(cap) < rates[a][k] for k in levels[a] if not (k == 0 and owners.get(a, a) != a)}
             for a in levels}  # fmt: skip
    for a in levels:
        if 0 in levels[a] and owners.get(a, a) != a:
            draws[a][0] = draws[owners[a]][0]
    outcomes: dict[str, dict[int, dict[int, bool]]] = {a: {} for a in levels}
    open_axes, per_round = set(levels), []
    while open_axes:
        ran: set[tuple[str, int, int]] = set()  # (axis that rolls it out, level, episode)
        for a in sorted(open_axes):
            p = plan_next(rule, list(levels[a]), outcomes[a], mode)
            if p.done:
                open_axes.discard(a)
                continue
            for k, eps in p.to_run.items():
                by = outcomes[a].setdefault(k, {})
                for i in eps:
                    by[i] = bool(draws[a][k][i])
                    ran.add((owners.get(a, a) if k == 0 else a, k, i))
        if ran:
            per_round.append(len(ran))
    return TaskCost(tuple(per_round))


@dataclass(frozen=True)
class AdaptiveCost:
    """Simulated rollouts of a whole protocol: per replicate its total and its rounds' sizes."""

    totals: tuple[int, ...]
    rounds: tuple[tuple[int, ...], ...]
    fixed: int  # the same protocol's rollouts under the fixed design (the cap on every level)

    def summary(self) -> dict:
        """``episodes_adaptive`` of ``indgen budget --json``."""
        t = np.asarray(self.totals)
        return {"expected": float(t.mean()), "p5": float(np.percentile(t, 5)), "p95": float(np.percentile(t, 95)),
                "rounds_expected": float(np.mean([len(r) for r in self.rounds])), "replicates": len(t),
                "share_of_fixed": float(t.mean() / self.fixed) if self.fixed else None}  # fmt: skip


def simulate_protocol(rule: SequentialRule | UntilFailure, mode: str, tasks: int,
                      levels: Mapping[str, Sequence[int]], curve: Curve, owners: Mapping[str, str], fixed: int,
                      replicates: int = 200, seed: int = 0) -> AdaptiveCost:  # fmt: skip
    """``replicates`` protocols of ``tasks`` tasks with i.i.d. outcomes. Tasks are exchangeable under one curve, so
    ``replicates`` tasks are simulated and each protocol sums ``tasks`` of them drawn with replacement; a pilot's
    curve is drawn once per protocol (its uncertainty is common to all tasks), from a pool of simulated tasks per
    draw. Rounds of a protocol add up its tasks' rounds (all ladders run side by side, docs/adaptive.md §8)."""
    if tasks < 1 or replicates < 1:
        raise ConfigError(f"tasks and replicates must be >= 1, got {tasks}, {replicates}")
    rng = np.random.default_rng(seed)
    draws = max(1, replicates // 5) if curve.uncertain else 1
    per_draw = max(1, replicates // draws)
    pools = []
    for _ in range(draws):
        rates = curve.draw(rng)
        pools.append([simulate_task(rule, mode, levels, rates, owners, rng) for _ in range(per_draw)])
    totals, rounds = [], []
    for r in range(max(replicates, 2000)):
        pool = pools[r % draws]
        picked = [pool[i] for i in rng.integers(0, len(pool), size=tasks)]
        width = max(len(c.per_round) for c in picked)
        sizes = tuple(int(sum(c.per_round[j] for c in picked if j < len(c.per_round))) for j in range(width))
        totals.append(sum(sizes))
        rounds.append(sizes)
    return AdaptiveCost(tuple(totals), tuple(rounds), fixed)
