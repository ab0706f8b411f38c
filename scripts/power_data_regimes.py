"""Power of the data-regime study design (docs/results/data_regimes.md), by simulation; run once before the study.

.venv/bin/python scripts/power_data_regimes.py
"""

import numpy as np
from scipy import stats


def paired_level_power(pa: float, pb: float, n: int = 90, alpha: float = 0.05 / 7, reps: int = 2000) -> float:
    """Stratified (pooled-discordant) exact McNemar at the smallest Holm threshold, independent outcomes."""
    rng = np.random.default_rng(0)
    hits = 0
    for _ in range(reps):
        a, b = rng.random(n) < pa, rng.random(n) < pb
        d1, d2 = int((a & ~b).sum()), int((~a & b).sum())
        hits += d1 + d2 > 0 and stats.binomtest(d1, d1 + d2, 0.5).pvalue < alpha
    return hits / reps


def seed_level_power(d: float, k: int = 3, reps: int = 4000) -> float:
    """Two-sample t-test, k vs k training seeds, for a difference of ``d`` between-seed standard deviations."""
    rng = np.random.default_rng(1)
    return float(np.mean([stats.ttest_ind(rng.normal(d, 1, k), rng.normal(0, 1, k)).pvalue < 0.05
                          for _ in range(reps)]))  # fmt: skip


if __name__ == "__main__":
    for pa, pb in ((0.4, 0.8), (0.5, 0.7), (0.5, 0.65)):
        print(f"per level, 90 pairs: {pa:.2f} vs {pb:.2f}: power {paired_level_power(pa, pb):.2f}")
    for d in (1.5, 2.0, 2.5, 3.0):
        print(f"3 vs 3 seeds, difference {d} SD: power {seed_level_power(d):.2f}")
