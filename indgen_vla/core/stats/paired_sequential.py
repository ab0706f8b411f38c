"""A sequential comparison of two checkpoints on paired episodes that may stop early: a two-sided sequential
sign test (an SPRT on which checkpoint is ahead in the pairs that differ), on binary success or on progress.

Pair i runs both checkpoints from the same initial state (same seed). Under H0 (the checkpoints are
exchangeable on each initial state) every pair that differs favours B with chance 1/2, independently, whatever
the success rates, the levels or the look schedule: the signs are a fair coin sequence. The rule tracks the
log-likelihood ratios of "B ahead with chance θ" and "A ahead with chance θ" against 1/2 and stops when either
reaches the threshold. On progress scores more pairs differ than on 0/1 success (two failures at different
stages now count), so evidence arrives faster at the same false-positive guarantee. docs/adaptive.md
("Partial credit") has the rule, its error check and the measured savings.

False positives: ``worst_case_fpr`` is the exact probability under H0 that the rule ever stops, when it looks
after every pair and every pair differs — any other look schedule or fewer differing pairs only removes
chances to cross, so it bounds the rule's false-positive rate for every pair of checkpoints and every
stream; ``thresholds="exact"`` lowers Ville's anytime threshold log(2/α) until that bound is α.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from indgen_vla.core.errors import ConfigError

VERDICTS = ("b_better", "a_better", "undetermined", "continue")


@dataclass(frozen=True)
class PairedSequentialRule:
    """Stop when the pairs that differ favour one checkpoint strongly enough; two-sided level ``alpha``."""

    alpha: float = 0.05  # two-sided false-positive rate, guaranteed (see the module docstring)
    theta: float = 0.7  # the alternative: P(better checkpoint ahead | the pair differs)
    round_size: int = 5  # pairs per look
    max_pairs: int = 200  # truncation: "undetermined" (no difference detected) after this many pairs
    thresholds: str = "exact"  # "exact": calibrated worst-case FPR = alpha; "ville": log(2/alpha)

    def __post_init__(self):
        if not 0 < self.alpha < 0.5:
            raise ConfigError(f"sequential comparison alpha must be in (0, 0.5), got {self.alpha}")
        if not 0.5 < self.theta < 1:
            raise ConfigError(f"theta (P(better ahead | pair differs)) must be in (0.5, 1), got {self.theta}")
        for name in ("round_size", "max_pairs"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise ConfigError(f"{name} must be a positive integer, got {v!r}")
        if self.thresholds not in ("exact", "ville"):
            raise ConfigError(f"unknown thresholds {self.thresholds!r}; use 'exact' or 'ville'")

    @property
    def up(self) -> float:
        """LLR increment for a pair won by the side tested: log(2θ)."""
        return math.log(2 * self.theta)

    @property
    def down(self) -> float:
        """LLR increment for a pair lost by the side tested: log(2(1 − θ))."""
        return math.log(2 * (1 - self.theta))

    @property
    def threshold(self) -> float:
        """Stop when either side's LLR reaches this."""
        ville = math.log(2 / self.alpha)
        return ville if self.thresholds == "ville" else _calibrated(self)

    def llrs(self, a_ahead: int, b_ahead: int) -> tuple[float, float]:
        """(LLR "A better", LLR "B better") after these counts of differing pairs."""
        return (a_ahead * self.up + b_ahead * self.down, b_ahead * self.up + a_ahead * self.down)

    def decide(self, pairs: Sequence[tuple[float, float] | None]) -> PairedDecision:
        """Decide from pairs (score A, score B) in episode-index order (None: a pair with an error, skipped);
        looks at every ``round_size`` pairs and at ``max_pairs`` only, so later pairs never change a decision."""
        thr = self.threshold
        a = b = last = 0
        looks = [*range(self.round_size, self.max_pairs, self.round_size), self.max_pairs]
        for look in looks:
            if look > len(pairs):
                break
            for p in pairs[last:look]:
                if p is not None:
                    a += p[0] > p[1]
                    b += p[1] > p[0]
            last = look
            la, lb = self.llrs(a, b)
            if lb >= thr - 1e-12:
                return PairedDecision("b_better", look, a, b)
            if la >= thr - 1e-12:
                return PairedDecision("a_better", look, a, b)
            if look == self.max_pairs:
                return PairedDecision("undetermined", look, a, b)
        return PairedDecision("continue", last, a, b)

    def worst_case_fpr(self, threshold: float | None = None) -> float:
        """Exact P(stop | H0) looking after every pair, every pair differing: the bound on the FPR."""
        return _worst_case_fpr(
            self.up, self.down, self.max_pairs, self.threshold if threshold is None else threshold
        )


@dataclass(frozen=True)
class PairedDecision:
    """The rule's verdict, the pairs it used and the differing pairs each side won."""

    verdict: str
    pairs: int
    a_ahead: int
    b_ahead: int

    @property
    def final(self) -> bool:
        return self.verdict != "continue"

    def as_dict(self) -> dict:
        return {
            "decision": self.verdict,
            "pairs_used": self.pairs,
            "a_ahead": self.a_ahead,
            "b_ahead": self.b_ahead,
        }


def _worst_case_fpr(up: float, down: float, steps: int, thr: float) -> float:
    """Dynamic programming over the fair ±1 walk of (a_ahead, b_ahead) with absorption at either threshold."""
    import numpy as np

    alive = np.zeros(steps + 2)  # alive[b]: P(b_ahead = b after m differing pairs, not stopped)
    alive[0] = 1.0
    b = np.arange(steps + 2)
    stopped = 0.0
    for m in range(1, steps + 1):
        alive = 0.5 * alive + 0.5 * np.concatenate(([0.0], alive[:-1]))
        a = m - b
        cross = (np.maximum(a * up + b * down, b * up + a * down) >= thr - 1e-12) & (b <= m)
        stopped += float(alive[cross].sum())
        alive[cross] = 0.0
    return stopped


@functools.lru_cache(maxsize=64)
def _calibrated(rule: PairedSequentialRule) -> float:
    """The lowest threshold whose worst-case FPR is still <= alpha (the FPR falls as the threshold rises)."""
    ok, bad = math.log(2 / rule.alpha), 0.0  # Ville: log(2/α) always holds
    for _ in range(50):
        mid = (ok + bad) / 2
        if _worst_case_fpr(rule.up, rule.down, rule.max_pairs, mid) <= rule.alpha:
            ok = mid
        else:
            bad = mid
    return ok
