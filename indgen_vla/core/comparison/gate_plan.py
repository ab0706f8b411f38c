"""``indgen gate --plan BASELINE``: the episodes a level a CI smoke needs so that the gate passes two equal policies
with chance ≥ 80 % and fails a drop of 2M at one level with chance ≥ 80 %, from the baseline's per-level rates.

Pass means non-inferiority shown at every level (the exact test of ``stats.noninferiority``); levels are independent
samples, so the chance of passing is the product of the per-level powers, summed exactly over each level's tables.
The pairing of a candidate's outcomes with the baseline's is assumed (``independent`` by default, or the
``most-discordant`` coupling, the least power); two runs of a deterministic policy and simulator agree pair by pair and
pass with fewer episodes than planned here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.stats.metrics import MIN_N
from indgen_vla.core.stats.noninferiority import pass_chance
from indgen_vla.core.stats.sample_size import first_extra

MAX_PLAN = 5000


def plan_episodes(rates: Sequence[float], margin: float, alpha: float = 0.05, power: float = 0.8,
                  model: str = "independent") -> dict[str, Any]:  # fmt: skip
    """The fewest episodes a level (found by doubling, then bisection) at which equal policies pass with chance
    ≥ ``power``, with the chances it gives: passing equal policies, and passing a drop of 2·margin at the level
    where that is likeliest among those whose rate allows it (a 0 % level cannot drop; None when none can)."""
    if not rates:
        raise ConfigError("the baseline has no level above the data floor to plan from")
    if not 0 < power < 1:
        raise ConfigError(f"--power must be in (0, 1), got {power}")

    def ok(n: int) -> bool:
        return n >= MIN_N and pass_chance(rates, n, margin, alpha, model) >= power

    n = first_extra(ok, MAX_PLAN)
    if n is None:
        return {"episodes": None, "rates": list(rates), "model": model, "power": power}
    can_drop = [i for i, p in enumerate(rates) if p >= 2 * margin - 1e-12]
    worst = max(
        can_drop, key=lambda i: pass_chance(rates, n, margin, alpha, model, 2 * margin, i), default=None
    )
    return {
        "episodes": n, "rates": list(rates), "model": model, "power": power, "margin": margin, "alpha": alpha,
        "pass_equal": pass_chance(rates, n, margin, alpha, model), "drop_level_index": worst,
        "pass_drop_2m": None if worst is None else pass_chance(rates, n, margin, alpha, model, 2 * margin, worst),
    }  # fmt: skip


def baseline_rates(path: str, gamma: float = 0.2) -> list[tuple[str, int, float]]:
    """(axis, level, rate) of every level of the baseline run above the data floor."""
    run = RunDir.open(path)
    s = summarize(run.episodes(), run.manifest, gamma)
    return [(axis, r["level"], r["rate"]) for axis, ax in s["axes"].items() for r in ax["levels"]
            if not r["insufficient"] and not math.isnan(r["rate"])]  # fmt: skip


def plan_lines(path: str, plan: dict, levels: list[tuple[str, int, float]]) -> list[str]:
    """The terminal text of ``gate --plan``."""
    rates = ", ".join(f"{a} L{k:+d} {100 * p:.0f}%".replace("+0", "0") for a, k, p in levels)
    if plan["episodes"] is None:
        return [f"no smoke of up to {MAX_PLAN} episodes a level passes equal policies with {plan['power']:.0%} "
                f"chance at these rates ({rates}); widen --margin"]  # fmt: skip
    m = plan["margin"]
    if plan["drop_level_index"] is None:
        drop = f"no level's rate is {200 * m:.0f}% or more, so no drop of {200 * m:.0f} pp can be tried"
    else:
        a, k, _ = levels[plan["drop_level_index"]]
        drop = (f"a drop of {200 * m:.0f} pp at one level ({a} L{k:+d}, the likeliest to pass) passes with chance "
                f"{plan['pass_drop_2m']:.2%}")  # fmt: skip
    return [
        f"baseline {path}: {len(levels)} level(s) above the data floor ({rates})",
        f"run the smoke and the baseline with --episodes {plan['episodes']} (same --seed): then two equal policies "
        f"pass with chance {plan['pass_equal']:.1%}, and {drop} (margin {100 * m:.0f} pp, exact "
        f"non-inferiority test at one-sided α = {plan['alpha']:g} per level; outcomes paired {plan['model']}, exact "
        "sums over each level's tables)",
    ]
