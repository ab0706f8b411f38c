"""A regression gate between two runs of one protocol (``indgen gate``): per level, is the candidate shown no worse
than the baseline within a margin M, shown worse, or neither yet, and how many more episodes would settle it.

Paired runs (same seeds and plan): a level is **non-inferior** when the exact unconditional test on Tango's score
statistic (``stats.noninferiority``) rejects Δ = candidate − baseline ≤ −M at one-sided α; its size holds at the
margin for every n (docs/statistics.md measures it; Newcombe's interval, used before, erred 11 % at n = 50). Unpaired
runs: an exact unconditional test ordered by the lower end of the (1 − 2α) MOVER interval of Wilson intervals (the
interval alone erred 7.2 % at 25 episodes a run). "Non-inferior everywhere" is an
intersection–union test, so it needs no multiplicity correction. A level is **worse** when the Holm-corrected test of
``indgen compare`` (exact McNemar, Boschloo unpaired) shows a difference and the candidate is the lower one. Anything
else is **undecided**, and an undecided gate fails (exit 5). A level below the data floor in either run is undecided
untested.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from indgen_vla.core.comparison.two_runs import compare_summaries, tasks_text
from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.fingerprint import check_comparable
from indgen_vla.core.reporting.caveats import blind_caveat, rate_text
from indgen_vla.core.reporting.report import run_label
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir
from indgen_vla.core.stats import noninferiority as ni
from indgen_vla.core.stats.contrasts import check_margin, paired_difference_ci, pp
from indgen_vla.core.stats.metrics import MIN_N, difference_ci, holm, usable_levels, wilson_ci
from indgen_vla.core.stats.sample_size import first_extra

# exit codes of `indgen gate` (2: bad input, as everywhere)
EXIT_PASS, EXIT_WORSE, EXIT_UNDERPOWERED = 0, 1, 5
DEFAULT_MARGIN = 0.10
MAX_MORE = 5000  # projections beyond this many extra episodes per level are reported as "not decidable"
NON_INFERIOR, WORSE, UNDECIDED = "non-inferior", "worse", "undecided"
POWER = 0.8  # the chance with which a projected number of episodes decides a level, and the plan's power


@dataclass(frozen=True)
class GateConfig:
    """What ``indgen gate`` compares and at which margin and error rate."""

    baseline: str
    candidate: str
    margin: float = DEFAULT_MARGIN
    alpha: float = 0.05
    gamma: float = 0.2
    test: str = "auto"
    allow_protocol_mismatch: bool = False
    labels: tuple[str, str] | None = field(default=None)

    def __post_init__(self) -> None:
        if self.margin is None:
            raise ConfigError("--margin is required: the largest drop in success you accept, e.g. 0.1")
        check_margin(self.margin)
        if not 0 < self.alpha < 0.5:
            raise ConfigError(f"--alpha must be in (0, 0.5), got {self.alpha}")
        if not 0 < self.gamma <= 1:
            raise ConfigError(f"--gamma must be in (0, 1], got {self.gamma}")


def _plan_levels(run: RunDir, summary: dict) -> dict[str, list[int]]:
    """Each axis's planned levels (the manifest's plan, else what the summary holds)."""
    levels = (run.manifest.get("plan") or {}).get("levels")
    if isinstance(levels, dict):
        return {a: sorted(int(k) for k in v) for a, v in levels.items()}
    return {a: sorted(r["level"] for r in ax["levels"]) for a, ax in summary["axes"].items()}


def _check_same_protocol(ra: RunDir, rb: RunDir, la: dict, lb: dict) -> None:
    """Refuse, in one line, runs whose axes or levels differ: a gate compares one protocol run twice."""
    if set(la) != set(lb):
        raise RunDirError(f"{ra.path} runs axes {sorted(la)} but {rb.path} runs {sorted(lb)}; gate two runs of "
                          "the same evaluate command (same --axis, --levels, --task)")  # fmt: skip
    for axis in sorted(la):
        if la[axis] != lb[axis]:
            raise RunDirError(f"axis {axis}: {ra.path} planned levels {la[axis]} but {rb.path} planned {lb[axis]}; "
                              "gate two runs of the same evaluate command")  # fmt: skip
    ta, tb = ((r.manifest.get("plan") or {}).get("tasks") for r in (ra, rb))
    if ta and tb and sorted(ta) != sorted(tb):
        raise RunDirError(f"{ra.path} pools tasks {sorted(ta)} but {rb.path} pools {sorted(tb)}; gate two runs of "
                          "the same evaluate command (same --task)")  # fmt: skip


def _cells(r: dict) -> tuple[int, int, int, int]:
    """(both, baseline only, candidate only, neither) of a paired row (``metrics.compare_paired_levels``)."""
    both = r["successes_a"] - r["a_only"]
    return both, r["a_only"], r["b_only"], r["pairs"] - both - r["a_only"] - r["b_only"]


def _unpaired_ci(sa: int, na: int, sb: int, nb: int, conf: float) -> tuple[float, float]:
    """Interval of Δ = B − A for independent runs: the MOVER combination of the Wilson intervals."""
    if not (na and nb):
        return math.nan, math.nan
    (la, ua), (lb, ub) = wilson_ci(sa, na, conf), wilson_ci(sb, nb, conf)
    return difference_ci((sb / nb, lb, ub), (sa / na, la, ua))


def _shown(paired: bool, r: dict, margin: float, alpha: float) -> tuple[float, list[float], bool, float]:
    """Δ, its (1 − 2α) interval (Newcombe paired, MOVER unpaired), whether non-inferiority within ``margin`` is shown
    and its p-value (paired: the exact test's; unpaired: NaN, the exact test ordered by the MOVER bound decides)."""
    conf = 1 - 2 * alpha
    if paired:
        both, a_only, b_only, neither = _cells(r)
        n = r["pairs"]
        ci = paired_difference_ci(both, a_only, b_only, neither, conf) if n else (math.nan, math.nan)
        delta = (b_only - a_only) / n if n else math.nan
        if not n:
            return delta, list(ci), False, math.nan
        p = ni.p_value(a_only, b_only, n, margin)
        return delta, list(ci), ni.non_inferior(a_only, b_only, n, margin, alpha), p
    ci = _unpaired_ci(r["successes_a"], r["n_a"], r["successes_b"], r["n_b"], conf)
    delta = r["rate_b"] - r["rate_a"] if r["n_a"] and r["n_b"] else math.nan
    if math.isnan(ci[0]):
        return delta, list(ci), False, math.nan
    shown = ni.unpaired_non_inferior(r["successes_a"], r["n_a"], r["successes_b"], r["n_b"], margin, alpha)
    return delta, list(ci), shown, math.nan


def _project_paired(r: dict, margin: float, alpha: float, family: int) -> tuple[int, str] | None:
    """Fewest extra episode pairs after which the level is decided with chance ≥ ``POWER`` if the observed pair
    frequencies are the true ones: (extra, verdict), by exact enumeration of the extra pairs given those observed
    (non-inferior: the exact test; worse: exact McNemar at α / family, Holm's first step); None when nothing
    decides it within ``MAX_MORE`` (or no pair was observed)."""
    n = r["pairs"]
    if not n:
        return None
    _, x, y, _ = _cells(r)
    got = ni.project_pairs(x, y, n, margin, alpha, alpha / family, POWER, MAX_MORE, MIN_N)
    return None if got is None else (got[0], NON_INFERIOR if got[1] else WORSE)


def _project_unpaired(r: dict, margin: float, alpha: float, family: int) -> tuple[int, str] | None:
    """As ``_project_paired`` for unpaired runs, the same number of extra episodes in each, each run's drawn at its
    observed rate; worse is projected with the interval at 1 − α / family (the exact Boschloo test is too slow to
    search with; an approximation of the test that decides)."""
    na, nb = r["n_a"], r["n_b"]
    if not (na and nb):
        return None
    chances = {}

    def decides(extra: int) -> bool:
        if min(na, nb) + extra < MIN_N:
            return False
        chances[extra] = ni.unpaired_conditional_power(r["successes_a"], na, r["successes_b"], nb, extra, margin,
                                                       alpha, alpha / family)  # fmt: skip
        return max(chances[extra]) >= POWER

    extra = first_extra(decides, MAX_MORE)
    if extra is None:
        return None
    p_ni, p_worse = chances[extra]
    return extra, NON_INFERIOR if p_ni >= p_worse else WORSE


def _level_row(axis: str, r: dict, paired: bool, tested: bool, cfg: GateConfig) -> dict[str, Any]:
    delta, ci, shown, p_ni = _shown(paired, r, cfg.margin, cfg.alpha)
    row = {
        "axis": axis, "level": r["level"], "tested": tested, "n_baseline": r["n_a"], "n_candidate": r["n_b"],
        "successes_baseline": r["successes_a"], "successes_candidate": r["successes_b"], "delta": delta,
        "delta_ci": ci, "non_inferior": tested and shown, "p_non_inferior": p_ni,
        "p": r["p_value"] if tested else math.nan,
        "p_holm": math.nan,
    }  # fmt: skip
    if paired:
        row.update(pairs=r["pairs"], discordant=[r["a_only"], r["b_only"]])
    return row


def _visible(row: dict, alpha: float, family: int) -> float | None:
    """The smallest drop from the baseline's rate that this level's pairs would call worse with chance ≥ ``POWER``
    (exact McNemar at α / family, independent outcomes); None: not even a drop to 0."""
    n = row.get("pairs") or min(row["n_baseline"], row["n_candidate"])
    if not n or not row["n_baseline"]:
        return None
    return ni.smallest_visible_drop(n, row["successes_baseline"] / row["n_baseline"], alpha / family, POWER)


def _decide(row: dict, alpha: float) -> str:
    if row["non_inferior"]:
        return NON_INFERIOR
    if row["tested"] and row["p_holm"] < alpha and row["delta"] < 0:
        return WORSE
    return UNDECIDED


def gate(cfg: GateConfig) -> dict[str, Any]:
    """The gate's result (``gate.json``): one row per (axis, level) with its verdict, the overall ``verdict`` and
    ``exit_code`` (0 pass, 1 worse somewhere, 5 underpowered) and ``lines`` to print; bad input raises."""
    ra, rb = RunDir.open(cfg.baseline), RunDir.open(cfg.candidate)
    ea, eb = ra.episodes(), rb.episodes()
    sa, sb = summarize(ea, ra.manifest, cfg.gamma), summarize(eb, rb.manifest, cfg.gamma)
    _check_same_protocol(ra, rb, _plan_levels(ra, sa), _plan_levels(rb, sb))
    la, lb = cfg.labels or (run_label(ra), run_label(rb))
    if la == lb:
        la, lb = f"{la} ({ra.path.name})", f"{lb} ({rb.path.name})"
    protocol = check_comparable([(la, ra.manifest.get("fingerprint")), (lb, rb.manifest.get("fingerprint"))],
                                cfg.allow_protocol_mismatch, "gated against each other")  # fmt: skip
    result = compare_summaries(sa, sb, cfg.test, cfg.gamma, episodes=(ea, eb))
    paired = result["paired"]
    rows: list[dict] = []
    for axis, ax in result["axes"].items():
        usable = usable_levels(sa["axes"][axis]["levels"]) & usable_levels(sb["axes"][axis]["levels"])
        tasks = tasks_text(*(s["axes"][axis].get("pooled_tasks") or [] for s in (sa, sb)))
        for r in ax["levels"]:
            rows.append({**_level_row(axis, r, paired, r["level"] in usable, cfg), "tasks": tasks})
    if not rows:
        raise RunDirError(
            f"{ra.path} and {rb.path} share no level to gate; run the same evaluate command twice"
        )
    tested = [r for r in rows if r["tested"]]
    for r, p in zip(tested, holm([r["p"] for r in tested]), strict=True):
        r["p_holm"] = p
    project = _project_paired if paired else _project_unpaired
    for r in rows:
        r["verdict"] = _decide(r, cfg.alpha)
        r["smallest_visible_drop"] = _visible(r, cfg.alpha, len(rows))
        if r["verdict"] == UNDECIDED:
            src = next(x for x in result["axes"][r["axis"]]["levels"] if x["level"] == r["level"])
            got = project(src, cfg.margin, cfg.alpha, len(rows))
            r["more_episodes"], r["projected"] = got if got else (None, None)
    worse = [r for r in rows if r["verdict"] == WORSE]
    undecided = [r for r in rows if r["verdict"] == UNDECIDED]
    code = EXIT_WORSE if worse else EXIT_UNDERPOWERED if undecided else EXIT_PASS
    out = {
        "baseline": str(ra.path), "candidate": str(rb.path), "label_baseline": la, "label_candidate": lb,
        "margin": cfg.margin, "alpha": cfg.alpha, "paired": paired, "test": result["test"],
        "unpaired_reason": result.get("unpaired_reason"), "holm_over": len(tested), "protocol": protocol,
        "levels": rows, "exit_code": code,
        "verdict": {EXIT_PASS: "pass", EXIT_WORSE: "worse", EXIT_UNDERPOWERED: "underpowered"}[code],
    }  # fmt: skip
    reads = result.get("reads_observations") or {}
    out["caveats"] = [blind_caveat(f"{label} ({side})", True)
                      for key, label, side in (("a", la, "baseline"), ("b", lb, "candidate")) if reads.get(key) is False]  # fmt: skip
    more = [r["more_episodes"] for r in undecided]
    out["more_episodes"] = None if not undecided or None in more else max(more)
    out["lines"] = [
        *out["caveats"],
        *(f"protocol: {x}" for x in protocol),
        *(level_line(r, out) for r in rows),
        summary_line(out),
    ]
    return out


def _k(level: int) -> str:
    return f"L{level:+d}".replace("-", "−") if level else "L0"


def basis_text(res: dict) -> str:
    """Which tests decided the levels, paired or not, and the Holm family."""
    if res["paired"]:
        kind = "non-inferiority: exact unconditional test on Tango's score"
        if any((r.get("pairs") or 0) > ni.N_EXACT for r in res.get("levels", [])):  # not exact there: say so
            kind += (f" (past {ni.N_EXACT} pairs its asymptotic score test, whose size is about α: 5.15 % at 1,500 "
                     "pairs for α = 5 %, docs/statistics.md)")  # fmt: skip
        kind += "; worse: paired exact McNemar"
    else:
        kind = f"non-inferiority: exact test on the MOVER bound; worse: unpaired {res['test'].capitalize()}"
        kind += f" ({res['unpaired_reason']})" if res.get("unpaired_reason") else ""
    return f"{kind}, Holm over {res['holm_over']} level(s) tested"


def _drop_text(r: dict) -> str:
    d = r.get("smallest_visible_drop")
    return ("no drop this run could call a regression" if d is None else
            f"smallest drop this run could call a regression: {100 * d:.0f} pp")  # fmt: skip


def level_line(r: dict, res: dict) -> str:
    """One verdict: "pick_y L+1: non-inferior — baseline 20/20 = 100% [84, 100] vs candidate ...; Δ ... (paired)"."""
    conf = round(100 * (1 - 2 * res["alpha"]))
    sides = (f"baseline {rate_text(r['successes_baseline'], r['n_baseline'])} vs candidate "
             f"{rate_text(r['successes_candidate'], r['n_candidate'])} ({r['tasks']})")  # fmt: skip
    lo, hi = r["delta_ci"]
    pair = (
        f"paired n={r['pairs']}, discordant {r['discordant'][0]}/{r['discordant'][1]}"
        if "pairs" in r
        else "unpaired"
    )
    how = "Newcombe" if "pairs" in r else "MOVER"
    stats = f"Δ {pp(r['delta'])} pp, {how} {conf}% CI [{pp(lo)}, {pp(hi)}] ({pair}"
    if r["tested"] and not math.isnan(r.get("p_non_inferior", math.nan)):
        stats += f", non-inferiority p={r['p_non_inferior']:.2g}"
    stats += f", p={r['p']:.2g}, Holm p={r['p_holm']:.2g})" if r["tested"] else ")"
    stats += _interval_note(r, res["margin"], how)
    head = f"{r['axis']} {_k(r['level'])}: {r['verdict']}"
    if r["verdict"] == NON_INFERIOR:
        return f"{head} within {100 * res['margin']:.0f} pp — {sides}; {stats}; {_drop_text(r)}"
    if r["verdict"] == WORSE:
        return f"{head} — {sides}; {stats}"
    why = "below the data floor in a run" if not r["tested"] else "neither shown"
    more = (f"about {r['more_episodes']} more episode(s) in each run would show it {r['projected']} with "
            f"{POWER:.0%} chance if the observed rates are the true ones (exact enumeration)"
            if r.get("more_episodes") is not None else
            f"not decidable with {POWER:.0%} chance within {MAX_MORE} more episodes at the observed rates")  # fmt: skip
    return f"{head} ({why}; {more}) — {sides}; {stats}; {_drop_text(r)}"


def _interval_note(r: dict, margin: float, how: str) -> str:
    """Where the printed interval and the verdict disagree on −M (the interval alone errs above α at the margin, so
    the exact test decides), say so: else a CI above −M beside "neither shown" reads as a contradiction."""
    lo = r["delta_ci"][0]
    if not r["tested"] or math.isnan(lo) or (lo > -margin) == r["non_inferior"]:
        return ""
    side = "above" if lo > -margin else "at or below"
    return (
        f"; the {how} interval's lower end ({100 * lo:+.1f} pp) is {side} −{100 * margin:g} pp, but that interval "
        "alone errs above α at the margin (docs/statistics.md §1): the exact test decides"
    )


def summary_line(res: dict) -> str:
    """The gate's last line: its verdict, its exit code and what it rests on."""
    rows, m = res["levels"], f"{100 * res['margin']:.0f} pp"
    head = f"gate {res['label_candidate']} (candidate) vs {res['label_baseline']} (baseline), margin {m}"
    basis = f"{basis_text(res)}; non-inferiority: one-sided α = {res['alpha']:g} per level"
    if res["exit_code"] == EXIT_PASS:
        return f"PASS (exit 0): {head}: non-inferior at all {len(rows)} level(s) ({basis})"
    if res["exit_code"] == EXIT_WORSE:
        bad = ", ".join(f"{r['axis']} {_k(r['level'])}" for r in rows if r["verdict"] == WORSE)
        return f"WORSE (exit 1): {head}: significantly worse at {bad} ({basis})"
    n = sum(r["verdict"] == UNDECIDED for r in rows)
    more = (f"about {res['more_episodes']} more episodes per level in each run would decide every one with "
            f"{POWER:.0%} chance each at the observed rates" if res["more_episodes"] is not None else
            f"at least one is not decidable within {MAX_MORE} more episodes per level at the observed rates")  # fmt: skip
    return (f"UNDERPOWERED, FAIL (exit 5): {head}: {n} of {len(rows)} level(s) undecided, so non-inferiority is not "
            f"shown; {more} ({basis})")  # fmt: skip
