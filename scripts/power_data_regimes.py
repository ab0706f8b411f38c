"""Power of the data-regime study design (docs/results/data_regimes.md), by simulation; run once before the study."""

import numpy as np
from scipy.stats import binomtest

rng = np.random.default_rng(0)


def power(pa, pb, n=90, alpha=0.05 / 7, reps=2000):
    hits = 0
    for _ in range(reps):
        a = rng.random(n) < pa
        b = rng.random(n) < pb
        d1 = int((a & ~b).sum())
        d2 = int((~a & b).sum())
        if d1 + d2 == 0:
            continue
        hits += binomtest(d1, d1 + d2, 0.5).pvalue < alpha
    return hits / reps


print("0.4 vs 0.8", power(0.4, 0.8))
print("0.5 vs 0.7", power(0.5, 0.7))
print("0.5 vs 0.65", power(0.5, 0.65))
# t-test 3 vs 3 power for effect d (in SD units)
from scipy import stats

for d in (1.5, 2.0, 2.5, 3.0):
    h = 0
    for _ in range(4000):
        x = rng.normal(0, 1, 3)
        y = rng.normal(d, 1, 3)
        h += stats.ttest_ind(y, x).pvalue < 0.05
    print("d", d, h / 4000)
