"""Benchmark (a): adaptive (sequential) vs fixed 50-episode evaluation on synthetic success curves.

Usage: .venv/bin/python scripts/bench_adaptive.py [--replicates 2000] [--alpha 0.025 --beta 0.025 --delta 0.1
       --round-size 5 --thresholds exact|wald] [--seed 0] [--json out.json]

Each replicate draws a success curve over levels -3..3 (per direction S(k) = top·σ(s(c − |k|))/σ(s·c), so
S(0) = top in both directions; top ~ U(0.85, 0.98), s ~ U(1.5, 4), c ~ U(0, 4) per direction), then 50
Bernoulli outcomes per level (no simulator). The fixed design uses all 50 per level; the adaptive designs
(indgen_vla.core.stats.sprt.plan_next, modes kstar and curve) use prefixes of the same outcomes, so the comparison
is paired. True k* = first level outward whose TRUE rate is below γ. "easy" curves have no true rate inside
the indifference zone [γ − δ, γ + δ] at levels 0..k* of either direction; "hard" curves are unrestricted.
Per-level error rates of the rule are checked by Monte Carlo at S = γ ± δ against the exact OC.

``--protocol P`` also simulates P whole protocols of the paper's LIBERO-Object shape (10 tasks × 3 signed axes, 30
ladders of levels -3..3, 10,500 episodes fixed) run the way ``evaluate --adaptive kstar --task all`` runs them: every
round holds every open ladder's next episodes. It reports the episodes used against the fixed design, k* accuracy
per ladder for both, the rounds, and the wall time in episode durations for 1/2/8 workers (equal episode durations
assumed; rounds are barriers), beside running the ladders one after another.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from indgen_vla.core.stats.metrics import break_levels, wilson_ci  # noqa: E402
from indgen_vla.core.stats.sprt import SequentialRule, level_order, operating_characteristic, plan_next  # noqa: E402

LEVELS = list(range(-3, 4))
FIXED_N = 50


def _sig(z):
    return 1 / (1 + math.exp(-z))


def draw_curve(rng: np.random.Generator) -> dict[int, float]:
    """One synthetic success curve over LEVELS (monotone in |k| per direction, S(0) shared)."""
    top, s = rng.uniform(0.85, 0.98), rng.uniform(1.5, 4.0)
    c = {"pos": rng.uniform(0.0, 4.0), "neg": rng.uniform(0.0, 4.0)}
    out = {}
    for k in LEVELS:
        cd = c["pos"] if k >= 0 else c["neg"]
        out[k] = top * _sig(s * (cd - abs(k))) / _sig(s * cd)
    return out


def true_kstar(curve: dict[int, float], gamma: float) -> dict[str, int | None]:
    """First level outward whose true rate is below γ, per direction (None = no break in range)."""
    return break_levels(curve, gamma, signed=True)


def is_easy(curve: dict[int, float], rule: SequentialRule) -> bool:
    """No true rate inside the indifference zone at levels 0..k* (inclusive) of either direction."""
    ks = true_kstar(curve, rule.gamma)
    for direction, order in level_order(LEVELS, True).items():
        for k in order:
            if rule.p_broken <= curve[k] <= rule.p_intact:
                return False
            if k == ks[direction]:
                break
    return True


def run_adaptive(rule, outcomes, mode):
    """Drive plan_next round by round on pre-drawn outcomes; returns (k* per direction, episodes, decisions)."""
    seen: dict[int, dict[int, bool]] = {}
    plan = plan_next(rule, LEVELS, seen, mode, signed=True)
    while not plan.done:
        for k, eps in plan.to_run.items():
            d = seen.setdefault(k, {})
            for i in eps:
                d[i] = bool(outcomes[k][i])
        plan = plan_next(rule, LEVELS, seen, mode, signed=True)
    used = sum(len(v) for v in seen.values())
    return {d: plan.kstar[d]["k"] for d in plan.kstar}, used, plan.decisions, plan.kstar


def _rate(hits: int, n: int) -> dict:
    lo, hi = wilson_ci(hits, n)
    return {"rate": hits / n if n else float("nan"), "n": n, "ci": [round(lo, 4), round(hi, 4)]}


def simulate(rule: SequentialRule, family: str, replicates: int, seed: int) -> dict:
    """Paired comparison of fixed / adaptive-kstar / adaptive-curve on one curve family."""
    rng = np.random.default_rng(seed)
    hits = {"fixed": 0, "kstar": 0, "curve": 0}
    agree = {"kstar": 0, "curve": 0}
    discordant = {
        "kstar": [0, 0],
        "curve": [0, 0],
    }  # [adaptive right & fixed wrong, adaptive wrong & fixed right]
    eps_fixed_stop = 0
    eps = {"fixed": 0, "kstar": 0, "curve": 0}
    determined = 0
    err = {"broken_when_intact": [0, 0], "intact_when_broken": [0, 0], "undetermined": [0, 0]}
    in_zone = 0
    done = 0
    while done < replicates:
        curve = draw_curve(rng)
        easy = is_easy(curve, rule)
        if family == "easy" and not easy:
            continue
        in_zone += not easy
        done += 1
        outcomes = {k: rng.random(FIXED_N) < curve[k] for k in LEVELS}
        truth = true_kstar(curve, rule.gamma)
        fixed = break_levels({k: float(outcomes[k].mean()) for k in LEVELS}, rule.gamma, signed=True)
        hits["fixed"] += fixed == truth
        eps["fixed"] += FIXED_N * len(LEVELS)
        visited = set()  # a fixed-50 design that also stops each direction at its own k*
        for direction, order in level_order(LEVELS, True).items():
            for k in order:
                visited.add(k)
                if k == fixed[direction]:
                    break
        eps_fixed_stop += FIXED_N * len(visited)
        for mode in ("kstar", "curve"):
            ks, used, decisions, status = run_adaptive(rule, outcomes, mode)
            hits[mode] += ks == truth
            discordant[mode][0] += ks == truth and fixed != truth
            discordant[mode][1] += ks != truth and fixed == truth
            agree[mode] += ks == fixed
            eps[mode] += used
            if mode == "kstar":
                determined += all(s["determined"] for s in status.values())
            else:
                for k, d in decisions.items():
                    p = curve[k]
                    if p >= rule.p_intact:
                        err["broken_when_intact"][0] += d.verdict == "broken"
                        err["broken_when_intact"][1] += 1
                    if p <= rule.p_broken:
                        err["intact_when_broken"][0] += d.verdict == "intact"
                        err["intact_when_broken"][1] += 1
                    err["undetermined"][0] += d.verdict == "undetermined"
                    err["undetermined"][1] += 1
    n = replicates
    return {
        "family": family,
        "replicates": n,
        "curves_with_a_relevant_level_in_zone": in_zone,
        "kstar_recovered (both directions exact)": {m: _rate(h, n) for m, h in hits.items()},
        "agrees_with_fixed_kstar (paired, same outcomes)": {m: _rate(a, n) for m, a in agree.items()},
        "mean_episodes_per_curve": {m: e / n for m, e in eps.items()},
        "episode_saving_vs_fixed": {m: 1 - eps[m] / eps["fixed"] for m in ("kstar", "curve")},
        "mean_episodes_fixed_stopping_at_its_kstar": eps_fixed_stop / n,
        "kstar_saving_vs_fixed_stopping_at_its_kstar": 1 - eps["kstar"] / eps_fixed_stop,
        "discordant_pairs [adaptive right & fixed wrong, adaptive wrong & fixed right]": discordant,
        "kstar_determined (kstar mode, both directions)": _rate(determined, n),
        "curve_mode_level_errors (pooled over levels)": {k: _rate(*v) for k, v in err.items()},
    }


PROTOCOL_LADDERS = 10 * 3  # LIBERO-Object: 10 tasks x (pick_y, goal_y, scale)


def simulate_protocol(rule: SequentialRule, protocols: int, seed: int, workers=(1, 2, 8)) -> dict:
    """Whole protocols, interleaved as the engine runs them (a round = every open ladder's next episodes)."""
    rng = np.random.default_rng(seed)
    eps_fixed = eps_adapt = right_fixed = right_adapt = ladders = rounds_total = 0
    wall = {w: [0, 0, 0] for w in workers}  # fixed, interleaved adaptive, one ladder after another
    for _ in range(protocols):
        curves = [draw_curve(rng) for _ in range(PROTOCOL_LADDERS)]
        outcomes = [{k: rng.random(FIXED_N) < c[k] for k in LEVELS} for c in curves]
        seen: list[dict[int, dict[int, bool]]] = [{} for _ in curves]
        per_ladder_rounds: list[list[int]] = [[] for _ in curves]
        round_sizes = []
        while True:
            plans = [plan_next(rule, LEVELS, s, "kstar", signed=True) for s in seen]
            todo = [(i, k, e) for i, p in enumerate(plans) for k, eps in p.to_run.items() for e in eps]
            if not todo:
                break
            round_sizes.append(len(todo))
            for i, p in enumerate(plans):
                if p.to_run:
                    per_ladder_rounds[i].append(sum(len(v) for v in p.to_run.values()))
            for i, k, e in todo:
                seen[i].setdefault(k, {})[e] = bool(outcomes[i][k][e])
        for i, c in enumerate(curves):
            truth = true_kstar(c, rule.gamma)
            fixed = break_levels({k: float(outcomes[i][k].mean()) for k in LEVELS}, rule.gamma, signed=True)
            right_fixed += fixed == truth
            right_adapt += {d: plans[i].kstar[d]["k"] for d in plans[i].kstar} == truth
        ladders += len(curves)
        eps_fixed += len(curves) * len(LEVELS) * FIXED_N
        eps_adapt += sum(sum(len(v) for v in s.values()) for s in seen)
        rounds_total += len(round_sizes)
        for w in workers:
            wall[w][0] += math.ceil(len(curves) * len(LEVELS) * FIXED_N / w)
            wall[w][1] += sum(math.ceil(n / w) for n in round_sizes)
            wall[w][2] += sum(math.ceil(n / w) for r in per_ladder_rounds for n in r)
    return {
        "protocols": protocols,
        "ladders": ladders,
        "episodes_fixed_per_protocol": eps_fixed / protocols,
        "episodes_adaptive_per_protocol": eps_adapt / protocols,
        "adaptive_share_of_fixed": eps_adapt / eps_fixed,
        "kstar_recovered_per_ladder": {
            "fixed": _rate(right_fixed, ladders),
            "kstar": _rate(right_adapt, ladders),
        },
        "rounds_per_protocol": rounds_total / protocols,
        "wall_episode_durations_per_protocol": {
            str(w): {
                "fixed": v[0] / protocols,
                "adaptive_interleaved": v[1] / protocols,
                "adaptive_one_ladder_at_a_time": v[2] / protocols,
            }
            for w, v in wall.items()
        },  # fmt: skip
        "adaptive_speedup_2_vs_1_worker": wall[1][1] / wall[2][1] if 2 in wall else None,
    }


def error_check(rule: SequentialRule, sequences: int, seed: int) -> dict:
    """Per-level verdict frequencies at S = γ + δ and γ − δ (Monte Carlo) beside the exact OC."""
    rng = np.random.default_rng(seed)
    out = {}
    for p in (rule.p_broken, rule.gamma, rule.p_intact):
        counts = {"broken": 0, "intact": 0, "undetermined": 0}
        used = 0
        for _ in range(sequences):
            d = rule.decide(list(rng.random(rule.max_episodes) < p))
            counts[d.verdict] += 1
            used += d.episodes
        oc = operating_characteristic(rule, p)
        out[f"S={p:.3f}"] = {
            "monte_carlo": {v: _rate(c, sequences) for v, c in counts.items()},
            "mean_episodes_mc": used / sequences,
            "exact": {
                "broken": oc.p_broken,
                "intact": oc.p_intact,
                "undetermined": oc.p_undetermined,
                "expected_episodes": oc.expected_episodes,
            },
        }
    return out


def _fmt(r: dict) -> str:
    return f"{100 * r['rate']:.1f} % [{100 * r['ci'][0]:.1f}, {100 * r['ci'][1]:.1f}] (n={r['n']})"


def _paired_diff(b: int, c: int, n: int) -> str:
    """Paired difference of two proportions from the discordant counts, with a 95 % Wald interval."""
    d = (b - c) / n
    se = math.sqrt(max(b + c - (b - c) ** 2 / n, 0.0)) / n
    return f"{100 * d:+.2f} pp [{100 * (d - 1.96 * se):+.2f}, {100 * (d + 1.96 * se):+.2f}] (paired, n={n})"


def summary(res: dict) -> list[str]:
    """Human-readable lines: recovery, agreement, episodes, error rates (each rate with n and Wilson CI)."""
    r = res["rule"]
    lines = [
        f"rule: SPRT gamma={r['gamma']} delta={r['delta']} alpha={r['alpha']} beta={r['beta']} "
        f"round={r['round_size']} max={r['max_episodes']} thresholds={r['thresholds']} "
        f"(A={r['log_threshold_broken']:.3f}, B={r['log_threshold_intact']:.3f}); wall {res['wall_s']} s"
    ]
    for fam in ("easy", "hard"):
        f = res[fam]
        rec, agr = (
            f["kstar_recovered (both directions exact)"],
            f["agrees_with_fixed_kstar (paired, same outcomes)"],
        )
        lines.append(
            f"[{fam}] {f['replicates']} curves ({f['curves_with_a_relevant_level_in_zone']} with a "
            "level on the path to k* inside the zone); paired: same outcomes for every design"
        )
        for m in ("fixed", "kstar", "curve"):
            extra = (
                ""
                if m == "fixed"
                else (
                    f"; agrees with fixed {_fmt(agr[m])}; saving "
                    f"{100 * f['episode_saving_vs_fixed'][m]:.1f} %"
                )
            )
            lines.append(
                f"  {m:6s} true k* recovered {_fmt(rec[m])}; episodes/curve "
                f"{f['mean_episodes_per_curve'][m]:.1f}{extra}"
            )
        lines.append(
            f"  fixed-50 design that also stops each direction at its k*: "
            f"{f['mean_episodes_fixed_stopping_at_its_kstar']:.1f} episodes/curve; adaptive kstar saves "
            f"{100 * f['kstar_saving_vs_fixed_stopping_at_its_kstar']:.1f} % of those"
        )
        disc = f["discordant_pairs [adaptive right & fixed wrong, adaptive wrong & fixed right]"]
        lines.append(
            f"  paired discordant curves (adaptive right/fixed wrong, adaptive wrong/fixed right): "
            f"kstar {disc['kstar']}, curve {disc['curve']}; recovery difference adaptive kstar - fixed "
            f"{_paired_diff(*disc['kstar'], f['replicates'])}"
        )
        lines.append(
            f"  kstar mode: k* determined in both directions {_fmt(f['kstar_determined (kstar mode, both directions)'])}"
        )
        for k, v in f["curve_mode_level_errors (pooled over levels)"].items():
            lines.append(f"  curve mode, per level: {k} {_fmt(v)}")
    for s, v in res["error_check"].items():
        mc, ex = v["monte_carlo"], v["exact"]
        lines.append(
            f"  {s}: P(broken) MC {_fmt(mc['broken'])} exact {ex['broken']:.4f}; P(intact) MC "
            f"{_fmt(mc['intact'])} exact {ex['intact']:.4f}; undetermined exact {ex['undetermined']:.4f}; "
            f"E[episodes] {ex['expected_episodes']:.1f}"
        )
    return lines


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--replicates", type=int, default=2000)
    p.add_argument(
        "--sequences", type=int, default=20000, help="Monte Carlo sequences per S for the error check"
    )
    p.add_argument("--gamma", type=float, default=0.2)
    p.add_argument("--delta", type=float, default=0.1)
    p.add_argument("--alpha", type=float, default=0.025)
    p.add_argument("--beta", type=float, default=0.025)
    p.add_argument("--round-size", type=int, default=5)
    p.add_argument("--thresholds", choices=("wald", "exact"), default="exact")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None, help="also write the results here")
    p.add_argument(
        "--protocol", type=int, default=0, help="also simulate this many whole LIBERO-Object protocols"
    )
    a = p.parse_args()
    rule = SequentialRule(a.gamma, a.delta, a.alpha, a.beta, a.round_size, FIXED_N, a.thresholds)
    t0 = time.perf_counter()
    res = {"rule": rule.as_dict(), "levels": LEVELS, "fixed_episodes_per_level": FIXED_N}
    res["error_check"] = error_check(rule, a.sequences, a.seed)
    for i, fam in enumerate(("easy", "hard")):
        res[fam] = simulate(rule, fam, a.replicates, a.seed + 1 + i)
    if a.protocol:
        res["protocol"] = simulate_protocol(rule, a.protocol, a.seed + 7)
    res["wall_s"] = round(time.perf_counter() - t0, 1)
    text = json.dumps(res, indent=1)
    if a.json:
        with open(a.json, "w") as f:
            f.write(text + "\n")
    for line in summary(res):
        print(line)
    if "protocol" in res:
        print("protocol:", json.dumps(res["protocol"]))


if __name__ == "__main__":
    main()
