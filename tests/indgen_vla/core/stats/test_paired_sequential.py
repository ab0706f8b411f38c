"""The sequential sign test on paired episodes: its worst-case false-positive bound against brute-force
enumeration, a Monte Carlo check under H0, and its decisions on hand-made pair streams."""

import itertools
import math

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.paired_sequential import PairedSequentialRule


def test_worst_case_fpr_matches_enumeration():
    rule = PairedSequentialRule(alpha=0.2, theta=0.8, round_size=1, max_pairs=10, thresholds="ville")
    thr = rule.threshold
    assert thr == pytest.approx(math.log(2 / 0.2))
    hits = 0
    for signs in itertools.product([0, 1], repeat=10):  # 1 = B ahead; every pair differs, a look after each
        a = b = 0
        for s in signs:
            a, b = a + (1 - s), b + s
            if max(rule.llrs(a, b)) >= thr - 1e-12:
                hits += 1
                break
    assert rule.worst_case_fpr() == pytest.approx(hits / 2**10)
    assert rule.worst_case_fpr() <= 0.2  # Ville's inequality


def test_calibrated_threshold_keeps_alpha_and_is_less_conservative():
    ville = PairedSequentialRule(max_pairs=60, thresholds="ville")
    exact = PairedSequentialRule(max_pairs=60)
    assert exact.threshold <= ville.threshold
    assert ville.worst_case_fpr() <= exact.worst_case_fpr() <= 0.05


def test_monte_carlo_fpr_under_h0_with_ties_and_progress_scores():
    rule = PairedSequentialRule(max_pairs=60)
    rng = np.random.default_rng(0)
    stops = 0
    for _ in range(2000):  # exchangeable pairs: the same score distribution, shared difficulty, many ties
        shared = rng.integers(0, 6, 60)
        a = np.minimum(5, shared + rng.integers(0, 2, 60))
        b = np.minimum(5, shared + rng.integers(0, 2, 60))
        stops += rule.decide(list(zip(a.tolist(), b.tolist(), strict=True))).verdict in (
            "a_better",
            "b_better",
        )
    assert stops / 2000 <= 0.05 + 3 * math.sqrt(0.05 * 0.95 / 2000)


def test_decisions_on_hand_streams():
    rule = PairedSequentialRule(alpha=0.05, theta=0.7, round_size=5, max_pairs=50)
    wins = [(0, 3)] * 50  # B ahead on every pair
    d = rule.decide(wins)
    need = math.ceil(rule.threshold / math.log(1.4))  # B's LLR grows by log(2θ) per pair won
    assert d.verdict == "b_better" and d.pairs == 5 * math.ceil(need / 5) and d.b_ahead == d.pairs
    assert (
        rule.decide(wins[: d.pairs]) == d and rule.decide(wins + [(5, 0)] * 10) == d
    )  # later pairs never matter
    assert rule.decide([(5, 0)] * 50).verdict == "a_better"
    ties = rule.decide([(2, 2)] * 50)
    assert ties.verdict == "undetermined" and ties.pairs == 50 and ties.a_ahead == ties.b_ahead == 0
    assert rule.decide([(0, 1)] * 4).verdict == "continue"  # no look before round_size pairs
    assert rule.decide([None] * 5 + wins).pairs == d.pairs + 5  # error pairs keep their index, count nothing
    binary = rule.decide([(False, True)] * 50)
    assert binary == d  # on success pairs it is the sequential form of McNemar's sign test


@pytest.mark.parametrize("kw", [{"alpha": 0.6}, {"theta": 0.5}, {"round_size": 0}, {"max_pairs": True},
                                {"thresholds": "wald"}])  # fmt: skip
def test_bad_rules_refused(kw):
    with pytest.raises(ConfigError):
        PairedSequentialRule(**kw)
