import math

import numpy as np
import pytest

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.stats.breakpoint import (
    Cell,
    break_point,
    break_point_difference,
    cells_from_records,
    kstar_spread,
    kstar_status,
    verdict_from_ci,
)
from indgen_vla.core.stats.crossing import crossing, isotonic_crossing, logistic_fit, pava_decreasing


def _sig(z):
    return 1 / (1 + math.exp(-z))


def test_verdicts_from_wilson_cis():
    g = 0.2
    # Wilson 95 % intervals (metrics.wilson_ci): 0/50 -> (0, 0.0714), 40/50 -> (0.670, 0.888),
    # 10/50 -> (0.112, 0.330)
    assert verdict_from_ci(0.0, 0.0714, g) == "broken"
    assert verdict_from_ci(0.670, 0.888, g) == "intact"
    assert verdict_from_ci(0.112, 0.330, g) == "undetermined"
    assert verdict_from_ci(0.2, 0.5, g) == "intact"  # lower bound equal to γ counts as intact
    with pytest.raises(ConfigError):
        verdict_from_ci(0.1, 0.3, 0)


def test_kstar_status_cases():
    pos = [0, 1, 2, 3]
    assert (
        kstar_status({0: "intact", 1: "intact", 2: "broken", 3: "broken"}, pos)["text"]
        == "k* = +2, determined"
    )
    st = kstar_status({0: "intact", 1: "undetermined", 2: "undetermined", 3: "broken"}, pos)
    assert (st["earliest"], st["latest"], st["determined"], st["text"]) == (1, 3, False, "k* ∈ [+1, +3]")
    neg = kstar_status({0: "intact", -1: "undetermined", -2: "broken"}, [0, -1, -2, -3])
    assert neg["text"] == "k* ∈ [-2, -1]"
    none = kstar_status({0: "intact", 1: "intact"}, [0, 1])
    assert none["determined"] and none["text"] == "no break through +1, determined"
    open_ = kstar_status({0: "intact", 1: "undetermined"}, [0, 1])
    assert open_["latest"] is None and not open_["determined"] and "at or beyond +1" in open_["text"]
    # levels planned but not run are named as such, never counted as tested
    planned = {0: "intact", 1: "undetermined", 2: "undetermined", 3: "undetermined"}
    assert kstar_status(planned, pos, run=[0, 1])["text"] == (
        "k* at or beyond +1 (no level through +1 is decided broken; +2, +3 not run)"
    )
    assert kstar_status(planned, pos)["text"] == "k* at or beyond +1 (no level through +3 is decided broken)"
    hole = kstar_status({0: "intact", 1: "undetermined", 2: "broken"}, pos, run=[0, 2])
    assert hole["text"] == "k* ∈ [+1, +2] (+1 not run)"


def test_pava_by_hand():
    # 0.9, 0.5, 0.7, 0.1 with equal weights: 0.5 and 0.7 pool to 0.6
    blocks = pava_decreasing(np.array([0.9, 0.5, 0.7, 0.1]), np.ones(4))
    assert blocks == [(0, 0, 0.9), (1, 2, pytest.approx(0.6)), (3, 3, 0.1)]
    # weighted: 0.5 (w 20) + 0.7 (w 10) -> 17/30; 0.1 (w 30) + 0.15 (w 5) -> 3.75/35 (same as scikit-learn's
    # IsotonicRegression(increasing=False), checked once by hand in a throwaway venv)
    y, w = np.array([0.9, 0.5, 0.7, 0.1, 0.15, 0.05]), np.array([10.0, 20, 10, 30, 5, 10])
    vals = [v for _, _, v in pava_decreasing(y, w)]
    assert vals == [0.9, pytest.approx(17 / 30), pytest.approx(3.75 / 35), 0.05]


def test_isotonic_crossing_by_hand():
    x = np.array([0.0, 1.0, 2.0, 3.0])
    n = np.full(4, 10.0)
    # rates 0.9, 0.5, 0.7, 0.1 -> blocks at x = 0 (0.9), 1.5 (0.6), 3 (0.1); γ = 0.2 between 1.5 and 3:
    # 1.5 + (0.6 - 0.2)/(0.6 - 0.1)·1.5 = 2.7
    assert isotonic_crossing(x, np.array([9.0, 5, 7, 1]), n, 0.2) == pytest.approx(2.7)
    assert isotonic_crossing(x, np.array([9.0, 9, 9, 9]), n, 0.2) == math.inf
    assert isotonic_crossing(x, np.array([1.0, 0, 0, 0]), n, 0.2) == -math.inf


def test_logistic_crossing_on_exact_data_recovers_truth():
    # S(x) = σ(2 − 1.5x): crosses 0.2 at x = (2 − logit 0.2)/1.5 = (2 + 1.3863)/1.5 = 2.2575
    x = np.arange(5.0)
    n = np.full(5, 1e6)
    s = np.array([_sig(2 - 1.5 * v) for v in x]) * n
    a, b, ok = logistic_fit(x, s, n)
    assert ok and a == pytest.approx(2, abs=1e-6) and b == pytest.approx(-1.5, abs=1e-6)
    xc, method, _ = crossing(x, s, n, 0.2)
    assert method == "logistic"
    assert xc == pytest.approx((2 + math.log(4)) / 1.5, abs=1e-6)


def test_fallback_to_isotonic_and_reasons():
    x = np.arange(4.0)
    n = np.full(4, 20.0)
    # separated data (20/20, 20/20, 0/20, 0/20): no logistic MLE -> isotonic, crossing 1 + 0.8 = 1.8
    xc, method, why = crossing(x, np.array([20.0, 20, 0, 0]), n, 0.2)
    assert (method, xc) == ("isotonic", pytest.approx(1.8)) and "separated" in why
    # success rising with the level: wrong slope
    _, method, why = crossing(x, np.array([2.0, 6, 10, 14]), n, 0.2)
    assert method == "isotonic" and "wrong sign" in why
    # a cliff the logistic cannot follow: 0.95 flat then 0.05 flat (large n) -> lack of fit
    big = np.full(6, 2000.0)
    s = np.array([0.95, 0.95, 0.95, 0.05, 0.05, 0.05]) * big
    s[2] = 0.90 * 2000  # no separation
    _, method, why = crossing(np.arange(6.0), s, big, 0.2)
    assert method == "isotonic" and "lack of fit" in why
    with pytest.raises(ConfigError, match="logistic break point unavailable"):
        crossing(x, np.array([20.0, 20, 0, 0]), n, 0.2, method="logistic")


def _cells(curve, n, rng=None, step=0.025):
    out = []
    for k, p in curve.items():
        s = int(round(p * n)) if rng is None else int(rng.binomial(n, p))
        out.append(Cell(level=k, param=step * k, successes=s, n=n))
    return out


def test_break_point_shape_directions_and_param():
    curve = {k: _sig(2 - 1.5 * abs(k)) for k in range(-3, 4)}
    bp = break_point(_cells(curve, 100000), 0.2, n_boot=200, seed=1)
    true = (2 + math.log(4)) / 1.5
    assert set(bp) == {"pos", "neg"}
    assert bp["pos"]["level"] == pytest.approx(true, abs=0.01)
    assert bp["neg"]["level"] == pytest.approx(-true, abs=0.01)
    assert bp["pos"]["param"] == pytest.approx(0.025 * true, abs=0.001)
    lo, hi = bp["neg"]["ci"]["level"]
    assert lo < -true < hi and hi - lo < 0.1
    assert bp["pos"]["method"] == "logistic" and bp["pos"]["crossing"] == "inside"
    # one-sided axis, no crossing in range -> None with "above"
    flat = break_point([Cell(k, k, 9, 10) for k in range(3)], 0.2, n_boot=50)
    assert set(flat) == {"pos"} and flat["pos"]["level"] is None and flat["pos"]["crossing"] == "above"


def test_bootstrap_is_seeded_and_covers_truth():
    curve = {k: _sig(2 - 1.5 * k) for k in range(5)}
    true = (2 + math.log(4)) / 1.5
    a = break_point(_cells(curve, 200, np.random.default_rng(0)), 0.2, n_boot=300, seed=7)
    b = break_point(_cells(curve, 200, np.random.default_rng(0)), 0.2, n_boot=300, seed=7)
    assert a == b
    covered = 0
    for rep in range(40):
        bp = break_point(_cells(curve, 200, np.random.default_rng(100 + rep)), 0.2, n_boot=200, seed=rep)
        lo, hi = bp["pos"]["ci"]["level"]
        covered += lo is not None and hi is not None and lo <= true <= hi
    assert covered >= 34  # nominal 95 %: 38/40 expected; 34 allows Monte Carlo noise


def test_cluster_bootstrap_over_tasks_is_wider_than_pooled():
    rng = np.random.default_rng(5)
    recs = []
    for t, shift in enumerate([-1.0, 0.0, 1.0]):  # tasks break at different levels
        for k in range(5):
            p = _sig(2 + shift - 1.5 * k)
            for _i in range(100):
                recs.append(
                    {
                        "task": f"t{t}",
                        "level": k,
                        "param": 0.1 * k,
                        "success": rng.random() < p,
                        "status": "ok",
                    }
                )
    recs.append({"task": "t0", "level": 0, "param": 0.0, "success": True, "status": "error"})
    pooled = cells_from_records(recs)
    by_task = cells_from_records(recs, ["task"])
    assert sum(c.n for c in pooled) == 1500 and len(by_task) == 15
    wp = break_point(pooled, 0.2, n_boot=300, seed=0)["pos"]
    wt = break_point(by_task, 0.2, n_boot=300, seed=0)["pos"]
    assert wp["level"] == pytest.approx(wt["level"])
    width = lambda r: r["ci"]["level"][1] - r["ci"]["level"][0]  # noqa: E731
    assert width(wt) > 1.5 * width(wp)
    assert "cluster" in wt["resampled"]
    with pytest.raises(ConfigError, match="lacks column 'success'"):
        cells_from_records([{"level": 0, "param": 0.0}])


def test_difference_of_break_points():
    # A crosses γ at |k| = (1.5 + log 4)/1.5 = 1.92, B at (3 + log 4)/1.5 = 2.92: one level later
    a = {k: _sig(1.5 - 1.5 * abs(k)) for k in range(-3, 4)}
    b = {k: _sig(3.0 - 1.5 * abs(k)) for k in range(-3, 4)}
    d = break_point_difference(_cells(a, 20000), _cells(b, 20000), 0.2, n_boot=200, seed=0)
    assert d["pos"]["level"] == pytest.approx(1.0, abs=0.01)
    assert d["neg"]["level"] == pytest.approx(-1.0, abs=0.01)
    assert d["pos"]["param"] == pytest.approx(0.025, abs=0.001)
    lo, hi = d["pos"]["ci"]["level"]
    assert lo < 1.0 < hi and lo > 0.8
    lo, hi = d["neg"]["ci"]["level"]
    assert lo < -1.0 < hi and hi < -0.8


def test_logistic_fit_matches_direct_likelihood_maximisation():
    from scipy.optimize import minimize

    x = np.array([0.0, 1, 2, 3, 4])
    n = np.array([50.0, 50, 40, 50, 30])
    s = np.array([47.0, 41, 20, 9, 2])

    def nll(t):
        eta = t[0] + t[1] * x
        return float(np.sum(n * np.logaddexp(0, eta) - s * eta))

    ref = minimize(nll, [0.0, 0.0], method="BFGS", options={"gtol": 1e-10}).x
    a, b, ok = logistic_fit(x, s, n)
    assert ok and (a, b) == (pytest.approx(ref[0], abs=1e-5), pytest.approx(ref[1], abs=1e-5))


def test_fixed_run_status_from_summary_levels():
    from indgen_vla.core.stats.breakpoint import fixed_run_status

    rows = [
        {"level": -2, "rate": 0.0, "ci_low": 0.0, "ci_high": 0.0714, "n": 50},
        {"level": -1, "rate": 0.2, "ci_low": 0.112, "ci_high": 0.330, "n": 50},
        {"level": 0, "rate": 0.8, "ci_low": 0.670, "ci_high": 0.888, "n": 50},
        {"level": 1, "rate": 0.8, "ci_low": 0.670, "ci_high": 0.888, "n": 50},
        {"level": 2, "rate": 0.0, "ci_low": 0.0, "ci_high": 0.0714, "n": 50},
    ]
    st = fixed_run_status(rows, 0.2)
    assert st["verdicts"] == {-2: "broken", -1: "undetermined", 0: "intact", 1: "intact", 2: "broken"}
    assert st["kstar"]["pos"]["k"] == 2 and st["kstar"]["pos"]["text"] == "k* = +2, determined"
    # level -1 (rate 0.2, not below γ) might be the break: k* ∈ [-2, -1], point estimate -2
    assert st["kstar"]["neg"]["k"] == -2 and st["kstar"]["neg"]["text"] == "k* ∈ [-2, -1]"


def test_separated_data_interval_covers_the_bracketing_levels():
    cells = [Cell(k, 0.5 * k, s, 50) for k, s in zip(range(4), [50, 50, 0, 0], strict=True)]
    bp = break_point(cells, 0.2, n_boot=100)["pos"]
    assert bp["method"] == "isotonic" and bp["level"] == pytest.approx(1.8)
    assert bp["ci"]["level"] == [1.0, 2.0] and bp["ci"]["param"] == [0.5, 1.0]


def test_two_stage_bootstrap_over_seeds_then_tasks():
    from indgen_vla.core.stats.breakpoint import _boot_weights

    clusters = [(s, t) for s in ("seed0", "seed1") for t in ("a", "b", "c")]
    w = _boot_weights(clusters, 500, np.random.default_rng(0))
    assert w.shape == (500, 6) and (w.sum(1) == 6).all()  # 2 seeds drawn, 3 tasks within each copy
    per_seed = np.stack([w[:, :3].sum(1), w[:, 3:].sum(1)], axis=1)
    assert set(np.unique(per_seed)) <= {0, 3, 6}  # a seed is drawn 0, 1 or 2 times, whole
    assert (per_seed == 0).any() and (per_seed == 6).any()
    cells = [
        Cell(k, 0.1 * k, int(round(40 * _sig(2 + 0.5 * i - 1.5 * k))), 40, cl)
        for i, cl in enumerate(clusters)
        for k in range(5)
    ]
    bp = break_point(cells, 0.2, n_boot=200, seed=3, cluster_names=("run", "task"))["pos"]
    assert bp["resampled"] == "run → task → episodes within levels"
    assert bp == break_point(cells, 0.2, n_boot=200, seed=3, cluster_names=("run", "task"))["pos"]


@pytest.mark.parametrize(
    "ks, text",
    [
        # ten tasks: sorted outward 1 1 2 2 2 2 2 3 none none -> the 5th and 6th are both L2
        ([1, 2, 2, None, 2, 1, None, 2, 3, 2], "L1 ×2, L2 ×5, L3 ×1, none ×2 (10 tasks; median L2)"),
        ([1, None], "L1 ×1, none ×1 (2 tasks; median L1 to none)"),  # even count, middle pair differs
        ([-2, -1, -1], "L−1 ×2, L−2 ×1 (3 tasks; median L−1)"),  # outward is by |k|
        ([-1, "undetermined", None], "L−1 ×1, none ×1, undetermined ×1 (3 tasks)"),  # no median while open
        (["undetermined", "undetermined"], "undetermined ×2 (2 tasks)"),  # all open: no median
        ([], "no tasks"),
    ],
)
def test_kstar_spread_counts_each_tasks_break_and_its_median(ks, text):
    assert kstar_spread(ks, minus="−") == text


def test_zero_one_rates_that_are_not_monotone_and_their_difference_get_the_bracket_too():
    """0/5, 5/5, 0/5: the logistic slope has the wrong sign (so not "separated"), the isotonic crossing is 1.4, and
    every rate is 0 or 1, so the episode bootstrap gave the 95 % interval [1.4, 1.4] of zero width. It covers the
    bracketing levels [1, 2] now, and B − A against 5/5, 5/5, 0/5 (crossing 1.8, interval [1, 2]) covers [−1, +1],
    not the zero-width [−0.4, −0.4] the independent bootstraps gave."""
    a = [Cell(k, 0.5 * k, s, 5) for k, s in zip(range(3), [5, 5, 0], strict=True)]
    b = [Cell(k, 0.5 * k, s, 5) for k, s in zip(range(3), [0, 5, 0], strict=True)]
    bp = break_point(b, 0.2, n_boot=100)["pos"]
    assert "wrong sign" in bp["why"] and bp["level"] == pytest.approx(1.4)
    assert bp["ci"]["level"] == [1.0, 2.0] and bp["ci"]["param"] == [0.5, 1.0]
    d = break_point_difference(a, b, 0.2, n_boot=100, seed=0)["pos"]
    assert d["level"] == pytest.approx(-0.4)
    assert d["ci"]["level"] == [-1.0, 1.0] and d["ci"]["param"] == [-0.5, 0.5]
