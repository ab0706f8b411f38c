"""Adaptive allocation of episodes: a truncated, group-sequential Wald SPRT per level (docs/adaptive.md).

Per level the rule tests H_intact: S = γ + δ against H_broken: S = γ − δ (δ = half-width of the indifference
zone) with Wald's thresholds A = log((1 − β)/α) and B = log(β/(1 − α)) on the log-likelihood ratio
Λ_n = log L(γ − δ)/L(γ + δ). It looks only at round boundaries (n = r·round_size, and max_episodes) and only
at the episodes 0..n−1 in index order, so workers, completion order and resumes cannot change a decision.
α = P(verdict "broken" | S ≥ γ + δ) and β = P(verdict "intact" | S ≤ γ − δ); a level still open at
max_episodes is "undetermined". :func:`operating_characteristic` gives the exact error rates of a rule.
Everything here is a pure function of the outcomes, so the engine can call :func:`plan_next` between rounds.
:class:`UntilFailure` is the paper's real-robot design beside it (no test: n trials a level until one is observed
below γ).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.breakpoint import kstar_status, signed_level, verdict_from_ci
from indgen_vla.core.stats.metrics import success_rate

VERDICTS = ("broken", "intact", "undetermined", "continue")
# the paper's real-robot design (§5.3): n trials a level, levels in order, until the first observed failure
UNTIL_FAILURE = "until-failure"
MODES = ("kstar", "curve", UNTIL_FAILURE)
THRESHOLDS = ("wald", "exact")


@dataclass(frozen=True)
class SequentialRule:
    """The per-level decision rule "S < γ" vs "S ≥ γ" at stated error rates α and β."""

    gamma: float = 0.2
    delta: float = 0.1
    alpha: float = 0.025
    beta: float = 0.025
    round_size: int = 5
    max_episodes: int = 50
    thresholds: str = "exact"  # "exact": A, B tuned so the exact OC meets α, β; "wald": Wald's A, B

    def __post_init__(self):
        if not 0 < self.gamma < 1:
            raise ConfigError(f"adaptive gamma must be in (0, 1), got {self.gamma}")
        if not (self.delta > 0 and self.gamma - self.delta > 0 and self.gamma + self.delta < 1):
            raise ConfigError(
                f"indifference half-width delta={self.delta} must be > 0 and keep gamma ± delta inside (0, 1) "
                f"(gamma={self.gamma}); pick a smaller delta"
            )
        for name in ("alpha", "beta"):
            v = getattr(self, name)
            if not 0 < v < 0.5:
                raise ConfigError(f"adaptive {name} must be in (0, 0.5), got {v}")
        if isinstance(self.round_size, bool) or not isinstance(self.round_size, int) or self.round_size < 1:
            raise ConfigError(f"adaptive round size must be a positive integer, got {self.round_size!r}")
        if (
            isinstance(self.max_episodes, bool)
            or not isinstance(self.max_episodes, int)
            or self.max_episodes < 1
        ):
            raise ConfigError(
                f"adaptive max episodes (--episodes) must be a positive integer, got {self.max_episodes!r}"
            )
        if self.thresholds not in THRESHOLDS:
            raise ConfigError(f"unknown SPRT thresholds {self.thresholds!r}; use 'wald' or 'exact'")

    @property
    def p_broken(self) -> float:
        """The success rate that H_broken names: γ − δ."""
        return self.gamma - self.delta

    @property
    def p_intact(self) -> float:
        """The success rate that H_intact names: γ + δ."""
        return self.gamma + self.delta

    @property
    def wald_upper(self) -> float:
        """Wald's A = log((1 − β)/α)."""
        return math.log((1 - self.beta) / self.alpha)

    @property
    def wald_lower(self) -> float:
        """Wald's B = log(β/(1 − α))."""
        return math.log(self.beta / (1 - self.alpha))

    @property
    def upper(self) -> float:
        """The threshold in use: Λ ≥ upper decides "broken" (Wald's A, or its exact calibration)."""
        return self.wald_upper if self.thresholds == "wald" else _calibrated(self)[0]

    @property
    def lower(self) -> float:
        """The threshold in use: Λ ≤ lower decides "intact" (Wald's B, or its exact calibration)."""
        return self.wald_lower if self.thresholds == "wald" else _calibrated(self)[1]

    @property
    def step_success(self) -> float:
        """Λ's increment for a success, log((γ − δ)/(γ + δ)) < 0."""
        return math.log(self.p_broken / self.p_intact)

    @property
    def step_failure(self) -> float:
        """Λ's increment for a failure, log((1 − γ + δ)/(1 − γ − δ)) > 0."""
        return math.log((1 - self.p_broken) / (1 - self.p_intact))

    def boundaries(self) -> list[int]:
        """Episode counts at which the rule may decide: every round_size, and max_episodes."""
        out = list(range(self.round_size, self.max_episodes, self.round_size))
        return [*out, self.max_episodes]

    def llr(self, successes: int, n: int) -> float:
        """Λ_n for `successes` of `n` finished episodes."""
        return successes * self.step_success + (n - successes) * self.step_failure

    def verdict_at(self, successes: int, n: int) -> str:
        """Verdict "broken", "intact" or "continue" from the counts at one look (no truncation)."""
        return _verdict(self.llr(successes, n), self.upper, self.lower)

    def decide(self, outcomes: Sequence[bool | None]) -> Decision:
        """Decide one level from its outcomes in episode-index order (None = error episode, not counted).

        Only complete prefixes ending on a round boundary are looked at; outcomes past the deciding
        boundary are ignored, so a run that went further (or a resume) gives the same decision.
        """
        m = len(outcomes)
        last = 0
        s = n = 0
        for b in self.boundaries():
            if b > m:
                break
            for o in outcomes[last:b]:
                if o is None:
                    continue
                if type(o).__name__ not in ("bool", "bool_", "int") or o not in (0, 1):
                    raise ConfigError(f"episode outcome must be True, False or None (error), got {o!r}")
                n += 1
                s += bool(o)
            last = b
            v = self.verdict_at(s, n) if n else "continue"
            if v != "continue":
                return Decision(v, b, n, s, self.llr(s, n))
            if b == self.max_episodes:
                return Decision("undetermined", b, n, s, self.llr(s, n))
        nxt = next(b for b in self.boundaries() if b > last)
        return Decision("continue", last, n, s, self.llr(s, n), next_boundary=nxt)

    def as_dict(self) -> dict:
        """The rule and its parameters for manifest.json."""
        return {
            "rule": "wald_sprt_truncated_group_sequential",
            "gamma": self.gamma,
            "delta": self.delta,
            "alpha": self.alpha,
            "beta": self.beta,
            "round_size": self.round_size,
            "max_episodes": self.max_episodes,
            "thresholds": self.thresholds,
            "log_threshold_broken": self.upper,
            "log_threshold_intact": self.lower,
        }


RULE_FIELDS = ("gamma", "delta", "alpha", "beta", "round_size", "thresholds")


@dataclass(frozen=True)
class UntilFailure:
    """The paper's real-robot design (§5.3): ``max_episodes`` trials at each level, levels in order, and a direction
    stops at the first level whose observed rate is below γ ("until failure"). No test decides that break: each
    finished level's verdict is its Wilson CI's (``verdict_from_ci``), so a 1-of-10 stop stays "undetermined"."""

    gamma: float = 0.2
    max_episodes: int = 10

    def __post_init__(self):
        if not 0 < self.gamma < 1:
            raise ConfigError(f"gamma must be in (0, 1), got {self.gamma}")
        if (
            isinstance(self.max_episodes, bool)
            or not isinstance(self.max_episodes, int)
            or self.max_episodes < 1
        ):
            raise ConfigError(f"episodes per level must be a positive integer, got {self.max_episodes!r}")

    def decide(self, outcomes: Sequence[bool | None]) -> Decision:
        """One level from its outcomes in episode-index order: open until all ``max_episodes`` finished (errors
        count as finished, not in n), then its CI verdict; ``llr`` is None (no likelihood ratio is tested)."""
        used = list(outcomes[: self.max_episodes])
        n, s = sum(o is not None for o in used), sum(bool(o) for o in used if o is not None)
        if len(used) < self.max_episodes:
            return Decision("continue", len(used), n, s, None, next_boundary=self.max_episodes)
        r = success_rate(s, n)
        verdict = verdict_from_ci(r.ci_low, r.ci_high, self.gamma) if n else "undetermined"
        return Decision(verdict, self.max_episodes, n, s, None)

    def stops(self, d: Decision) -> bool:
        """A direction waits on an open level and stops at the first one observed below γ."""
        return not d.final or (d.n > 0 and d.rate < self.gamma)

    def status_text(self, k: int | None, decisions: Mapping[int, Decision], order: Sequence[int]) -> str:
        """Where the walk stands, with the stop level's CI: the break is observed, not statistically decided."""
        if k is not None:
            d = decisions[k]
            r = success_rate(d.successes, d.n)
            also = "; its CI lies below γ too" if d.verdict == "broken" else ""
            return (f"k* = {signed_level(k)} observed ({d.successes}/{d.n} < γ = {self.gamma:g}, 95 % Wilson CI "
                    f"{100 * r.ci_low:.0f}-{100 * r.ci_high:.0f} %): the paper's fixed design stops there, an "
                    f"observed break, not a statistically decided one{also}")  # fmt: skip
        running = next((j for j in order if j in decisions and not decisions[j].final), None)
        if running is not None:
            return f"no level observed below γ = {self.gamma:g} yet; level {signed_level(running)} is running"
        return f"no level observed below γ = {self.gamma:g} through {signed_level(order[-1])}"


def make_rule(mode: str, gamma: float, delta: float, alpha: float, round_size: int, episodes: int):
    """The rule of ``--adaptive MODE``: the paper's ``UntilFailure`` design, else the SPRT (α = β)."""
    if mode not in MODES:
        raise ConfigError(f"--adaptive must be one of {', '.join(MODES)}, got {mode!r}")
    if mode == UNTIL_FAILURE:
        return UntilFailure(gamma=gamma, max_episodes=episodes)
    return SequentialRule(gamma=gamma, delta=delta, alpha=alpha, beta=alpha, round_size=round_size,
                          max_episodes=episodes)  # fmt: skip


def plan_entry(mode: str, rule: SequentialRule | UntilFailure) -> dict:
    """What a manifest's ``plan.adaptive`` records (resume must match; ``report`` reads it back): the mode and the
    rule's parameters (``until-failure``: γ only; the episodes per level are the plan's ``episodes``)."""
    if mode not in MODES:
        raise ConfigError(f"--adaptive must be one of {', '.join(MODES)}, got {mode!r}")
    fields = ("gamma",) if isinstance(rule, UntilFailure) else RULE_FIELDS
    return {"mode": mode, **{k: getattr(rule, k) for k in fields}}


def rule_from_plan(adaptive: dict, episodes: int) -> SequentialRule | UntilFailure:
    """The rule a run's manifest records (``plan["adaptive"]``), capped at the run's ``--episodes``."""
    if adaptive.get("mode") == UNTIL_FAILURE:
        return UntilFailure(gamma=adaptive["gamma"], max_episodes=episodes)
    return SequentialRule(**{k: adaptive[k] for k in RULE_FIELDS if k in adaptive}, max_episodes=episodes)


@dataclass(frozen=True)
class Decision:
    """One level's sequential state: its verdict and the episodes it used."""

    verdict: str  # "broken" | "intact" | "undetermined" | "continue"
    episodes: int  # planned episodes consumed (indices 0..episodes-1), errors included
    n: int  # finished (non-error) episodes among them
    successes: int
    llr: float | None  # None under the paper's until-failure design (no likelihood ratio is tested)
    next_boundary: int | None = None  # for "continue": how many episodes the next look needs

    @property
    def final(self) -> bool:
        """True once the level needs no more episodes."""
        return self.verdict != "continue"

    @property
    def rate(self) -> float:
        """Success rate of the episodes used (NaN when none finished)."""
        return self.successes / self.n if self.n else float("nan")

    def as_dict(self) -> dict:
        """The per-level record for summary.json."""
        return {
            "decision": self.verdict,
            "episodes_used": self.episodes,
            "n": self.n,
            "successes": self.successes,
            "llr": self.llr,
        }


@dataclass(frozen=True)
class OperatingCharacteristic:
    """Exact probabilities of each verdict, and the expected episodes, at a true success rate p."""

    p: float
    p_broken: float
    p_intact: float
    p_undetermined: float
    expected_episodes: float


def _verdict(lam: float, upper: float, lower: float) -> str:
    if lam >= upper - 1e-12:
        return "broken"
    if lam <= lower + 1e-12:
        return "intact"
    return "continue"


def _oc(rule: SequentialRule, p: float, upper: float, lower: float) -> tuple[float, float, float, float]:
    """(P broken, P intact, P undetermined, E episodes) by dynamic programming over success counts."""
    alive = {0: 1.0}  # successes so far -> probability of still running
    last = 0
    pb = pi = pu = en = 0.0
    for b in rule.boundaries():
        k = b - last
        pmf = [math.comb(k, j) * p**j * (1 - p) ** (k - j) for j in range(k + 1)]
        nxt: dict[int, float] = {}
        for s, w in alive.items():
            for j in range(k + 1):
                nxt[s + j] = nxt.get(s + j, 0.0) + w * pmf[j]
        alive = {}
        for s, w in nxt.items():
            v = _verdict(rule.llr(s, b), upper, lower)
            if v == "broken":
                pb += w
                en += w * b
            elif v == "intact":
                pi += w
                en += w * b
            elif b == rule.max_episodes:
                pu += w
                en += w * b
            else:
                alive[s] = w
        last = b
    return pb, pi, pu, en


def operating_characteristic(rule: SequentialRule, p: float) -> OperatingCharacteristic:
    """Exact OC of the truncated group-sequential rule at true rate p (dynamic programming, no errors)."""
    if not 0 <= p <= 1:
        raise ConfigError(f"true success rate must be in [0, 1], got {p}")
    return OperatingCharacteristic(p, *_oc(rule, p, rule.upper, rule.lower))


@functools.lru_cache(maxsize=64)
def _calibrated(rule: SequentialRule) -> tuple[float, float]:
    """The least conservative thresholds whose exact OC still meets α at γ + δ and β at γ − δ.

    Lowering A only raises P(broken) and lowers P(intact); raising B does the opposite, so alternating
    bisections (A down against α, then B up against β) keep both constraints and converge.
    """
    upper, lower = rule.wald_upper, rule.wald_lower
    for _ in range(6):
        # A down to where P_{γ+δ}(broken) <= α still holds; then B up to where P_{γ−δ}(intact) <= β holds
        new_upper = _bisect(
            lambda a, b=lower: _oc(rule, rule.p_intact, a, b)[0] <= rule.alpha, ok=upper, bad=1e-9
        )
        new_lower = _bisect(
            lambda b, a=new_upper: _oc(rule, rule.p_broken, a, b)[1] <= rule.beta, ok=lower, bad=-1e-9
        )
        if new_upper == upper and new_lower == lower:
            break
        upper, lower = new_upper, new_lower
    return upper, lower


def _bisect(holds, ok: float, bad: float, steps: int = 45) -> float:
    """The point nearest ``bad`` where ``holds`` is still true, given it holds at ``ok`` (monotone between)."""
    for _ in range(steps):
        mid = (ok + bad) / 2
        if holds(mid):
            ok = mid
        else:
            bad = mid
    return ok


def level_order(levels: Iterable[int], signed: bool | None = None) -> dict[str, list[int]]:
    """Visiting order per direction, outward from level 0: {"pos": [0, 1, ...], "neg": [0, -1, ...]}."""
    lv = sorted(set(int(k) for k in levels))
    if not lv:
        raise ConfigError("adaptive evaluation needs at least one level")
    if signed is None:
        signed = any(k < 0 for k in lv)
    out = {"pos": [k for k in lv if k >= 0]}
    if signed:
        out["neg"] = sorted((k for k in lv if k <= 0), reverse=True)
    return {d: o for d, o in out.items() if o}


def kstar_from_decisions(decisions: Mapping[int, Decision], order: Sequence[int], gamma: float) -> int | None:
    """Point k* in one direction: the first level decided broken, or left undetermined with rate < γ.

    An undetermined level used all max_episodes, so this is the fixed design's rule there. None if no
    level in `order` qualifies (or the walk reaches a level that has not been decided).
    """
    for k in order:
        d = decisions.get(k)
        if d is None or not d.final:
            return None
        if d.verdict == "broken" or (d.verdict == "undetermined" and d.n and d.rate < gamma):
            return k
    return None


@dataclass(frozen=True)
class Plan:
    """What to run next: episode indices per level, the decisions so far, and per-direction k*."""

    to_run: dict[int, list[int]]
    decisions: dict[int, Decision]
    kstar: dict[str, dict] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        """True when nothing is left to run."""
        return not self.to_run

    @property
    def episodes_used(self) -> int:
        """Planned episodes consumed by the decisions so far, over all levels."""
        return sum(d.episodes for d in self.decisions.values())


def level_outcomes(episodes) -> dict[int, dict[int, bool | None]]:
    """{level: {episode index: success, or None for an error row}} from an episodes table (one task, one axis)."""
    out: dict[int, dict[int, bool | None]] = {}
    for k, i, ok, st in zip(
        episodes["level"], episodes["episode"], episodes["success"], episodes["status"], strict=True
    ):
        out.setdefault(int(k), {})[int(i)] = bool(ok) if st == "ok" else None
    return out


def outcome_prefix(level_outcomes: Mapping[int, bool | None]) -> list[bool | None]:
    """The outcomes of episodes 0, 1, 2, ... up to the first one not finished yet."""
    out = []
    while len(out) in level_outcomes:
        out.append(level_outcomes[len(out)])
    return out


def plan_next(
    rule: SequentialRule | UntilFailure,
    levels: Iterable[int],
    outcomes: Mapping[int, Mapping[int, bool | None]],
    mode: str = "kstar",
    signed: bool | None = None,
) -> Plan:
    """Given finished episodes {level: {episode_index: success or None (error)}}, say what to run next.

    kstar: walk each direction outward and stop it at its first level decided "broken" (levels past it
    are not run); curve: decide every requested level; until-failure (``UntilFailure``): walk outward the
    same way, each level's ``max_episodes`` at once, and stop at its first level observed below γ. Each level
    still open gets the episodes up to its next boundary that are not finished yet. Pure: the same outcomes
    always give the same plan.
    """
    if mode not in MODES:
        raise ConfigError(f"unknown adaptive mode {mode!r}; use one of {', '.join(MODES)}")
    if (mode == UNTIL_FAILURE) != isinstance(rule, UntilFailure):
        raise ConfigError(f"adaptive mode {mode} goes with {'an UntilFailure' if mode == UNTIL_FAILURE else 'a SequentialRule'} rule")  # fmt: skip
    order = level_order(levels, signed)
    requested = sorted({k for o in order.values() for k in o})
    decisions = {k: rule.decide(outcome_prefix(outcomes.get(k, {}))) for k in requested}
    if mode == "curve":
        active = set(requested)
    else:
        stops = (
            rule.stops if isinstance(rule, UntilFailure) else (lambda d: d.verdict in ("broken", "continue"))
        )
        active = set()
        for seq in order.values():
            for k in seq:
                active.add(k)
                if stops(decisions[k]):
                    break  # a broken level ends the direction; an open one must be decided first
    to_run = {}
    for k in sorted(active):
        d = decisions[k]
        if d.final:
            continue
        done = outcomes.get(k, {})
        need = [i for i in range(d.next_boundary) if i not in done]
        if need:
            to_run[k] = need
    shown = {k: d for k, d in decisions.items() if k in active}
    ks = {}
    for direction, seq in order.items():
        verdicts = {k: shown[k].verdict for k in seq if k in shown}
        # a level with finished episodes ran, even before the rule's first look at it
        ran = [k for k in verdicts if shown[k].episodes or outcomes.get(k)]
        status = kstar_status(verdicts, seq, ran)
        status["k"] = kstar_from_decisions(shown, seq, rule.gamma)
        if isinstance(rule, UntilFailure):
            status["text"] = rule.status_text(status["k"], shown, seq)
        ks[direction] = status
    return Plan(to_run=to_run, decisions=shown, kstar=ks)
