"""Partial credit: the exact rank tests against scipy and brute force, level summaries, compare and report on runs
with progress scores, and runs written before the progress column (missing, never 0)."""

import itertools
import json

import numpy as np
import pytest
from scipy import stats

import indgen_vla.core.reporting.partial_credit as P
from indgen_vla.app.cli import main
from indgen_vla.core.comparison.two_runs import compare_summaries
from indgen_vla.core.reporting.partial_credit import (
    STAGES,
    level_progress,
    rank_sum_test,
    sign_test,
    signed_rank_exact,
)
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import EPISODES, RunDir
from tests.indgen_vla.core.runs.test_records import rec


def test_signed_rank_matches_scipy_without_ties_and_brute_force_with_ties():
    d = [3, -1, 4, 2, -5, 6, 7, -8, 9, 10]  # no ties, no zeros: scipy's exact distribution applies
    assert signed_rank_exact(d) == pytest.approx(stats.wilcoxon(d, method="exact").pvalue)
    d = [1, 1, -2, 3, 3, -1, 2, 0, 4]  # ties at midranks, one zero dropped: enumerate all 2^8 sign patterns
    nz = np.array([x for x in d if x])
    r = stats.rankdata(np.abs(nz))
    w, e = r[nz > 0].sum(), r.sum() / 2
    hits = [
        abs(r[np.array(s, bool)].sum() - e) >= abs(w - e) - 1e-9 for s in itertools.product([0, 1], repeat=8)
    ]
    assert signed_rank_exact(d) == pytest.approx(np.mean(hits)) == pytest.approx(36 / 256)
    # hand: one difference +1 of one pair: W+ = 1 of {0, 1} equally likely, p = 1
    assert signed_rank_exact([1]) == 1.0 and signed_rank_exact([0, 0]) == 1.0
    # hand: five differences +1: all ranks 3 (doubled 6); only all-positive/all-negative as extreme: 2/32
    assert signed_rank_exact([1] * 5) == pytest.approx(2 / 32)


def _whole_array_dp(groups):
    """The signed-rank null as first written: every weight added over the whole array (the bit-for-bit reference)."""
    dist = np.zeros(sum(n * r for n, r in groups) + 1)
    dist[0] = 1.0
    for n, r in groups:
        nxt = np.zeros_like(dist)
        for j, q in enumerate(stats.binom.pmf(np.arange(n + 1), n, 0.5)):
            nxt[j * r :] += q * dist[: len(dist) - j * r]
        dist = nxt
    return dist


def test_signed_rank_null_is_bit_identical_to_the_whole_array_dp_cached_or_not():
    rng = np.random.default_rng(3)
    d = list(rng.integers(-5, 6, 520))  # ~470 non-zero differences: a null of > NULL_CACHE_STATES, not cached
    nz = [abs(x) for x in d if x]
    ranks = P._doubled_midranks(nz)
    groups = tuple(sorted((nz.count(v), ranks[v]) for v in set(nz)))
    assert sum(n * r for n, r in groups) > P.NULL_CACHE_STATES
    P._signed_rank_null_cached.cache_clear()
    assert P._signed_rank_null(groups).tobytes() == _whole_array_dp(groups).tobytes()
    assert P._signed_rank_null_cached.cache_info().currsize == 0  # a large null is not kept
    small = ((1, 4000), (3, 7), (2, 1), (2000, 1))  # weights that underflow to 0 (n = 2000), a sparse support
    assert stats.binom.pmf(0, 2000, 0.5) == 0
    assert P._signed_rank_null(small).tobytes() == _whole_array_dp(small).tobytes()
    assert P._signed_rank_null_cached.cache_info().currsize == 1
    w = sum(ranks[abs(x)] for x in d if x > 0)
    total = sum(n * r for n, r in groups)
    sums = np.arange(total + 1)
    want = _whole_array_dp(groups)[np.abs(2 * sums - total) >= abs(2 * w - total)].sum()
    assert signed_rank_exact(d) == float(min(1.0, want))


def test_sign_test_is_mcnemar_on_binary_scores():
    d = [5, 5, 5, -5, 0, 0]
    assert sign_test(d) == pytest.approx(stats.binomtest(3, 4, 0.5).pvalue) == pytest.approx(10 / 16)


def test_rank_sum_exact_matches_scipy_and_brute_force(monkeypatch):
    a, b = [0, 3, 5, 1, 2], [4, 6, 7, 8, 9, 10]
    assert rank_sum_test(a, b) == (pytest.approx(stats.mannwhitneyu(a, b, method="exact").pvalue), "exact")
    a, b = [0, 1, 1, 3, 5, 5], [1, 3, 3, 4, 5, 5, 2]  # ties: all C(13, 6) splits
    pooled = stats.rankdata(a + b)
    w, e = pooled[:6].sum(), 6 * pooled.mean()
    splits = [
        abs(pooled[list(i)].sum() - e) >= abs(w - e) - 1e-9 for i in itertools.combinations(range(13), 6)
    ]
    assert rank_sum_test(a, b)[0] == pytest.approx(np.mean(splits))
    monkeypatch.setattr(P, "MAX_EXACT_STATES", 1)  # force scipy's Monte Carlo permutation test
    p, method = rank_sum_test(a, b)
    assert method == "monte_carlo" and p == pytest.approx(np.mean(splits), abs=0.02)
    assert rank_sum_test([], [1])[0] != rank_sum_test([], [1])[0]  # NaN: nothing to compare


def test_level_progress_counts_scored_ok_rows_only():
    import pandas as pd

    df = pd.DataFrame(
        {"status": ["ok", "ok", "ok", "error", "ok"], "progress": pd.array([0, 3, 5, 2, None], "Int8")}
    )
    p = level_progress(df)
    assert p == {
        "n": 3,
        "mean": pytest.approx(8 / 3),
        "stages": dict(zip(STAGES, [1, 0, 0, 1, 0, 1], strict=True)),
    }
    assert level_progress(df.drop(columns="progress")) is None
    assert level_progress(df.iloc[4:]) is None  # only a missing score: no summary, not a zero


def _run(path, scores, seed_offset=0):
    """A run with episode i of level k scored ``scores[k][i]`` (success = 5; None = not scored)."""
    run = RunDir.create_or_resume(path, {"plan": {"x": 1}, "data_regime": "r", "policy": "standin:noop",
                                         "axes": {"pick_y": {"signed": True}}})  # fmt: skip
    recs = []
    for level, ss in scores.items():
        for i, s in enumerate(ss):
            r = rec(level, i, success=s == 5)
            recs.append(type(r)(**{**r.__dict__, "seed": r.seed + seed_offset, "progress": s}))
    run.append(recs)
    return run


def test_compare_reports_progress_beside_mcnemar(tmp_path, capsys):
    a = _run(tmp_path / "a", {0: [5, 5, 5, 3, 1, 0, 0, 2], 1: [0, 1, 0, 1, 3, 0, 0, 1]})
    b = _run(tmp_path / "b", {0: [5, 5, 5, 4, 3, 1, 3, 2], 1: [3, 3, 2, 4, 3, 1, 2, 3]})
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "mcnemar_exact"  # the binary test stays the primary one
    prog = res["axes"]["pick_y"]["progress"]
    assert prog["test"] == "wilcoxon_signed_rank_exact" and prog["paired"]
    rows = {r["level"]: r for r in prog["levels"]}
    d1 = [3, 2, 2, 3, 0, 1, 2, 2]
    assert (rows[1]["b_higher"], rows[1]["a_higher"], rows[1]["ties"]) == (7, 0, 1)
    assert rows[1]["p_value"] == pytest.approx(2 / 2**7)  # all seven non-zero differences positive
    assert rows[1]["p_value"] == pytest.approx(signed_rank_exact(d1))
    assert rows[1]["mean_a"] == pytest.approx(6 / 8) and rows[1]["mean_b"] == pytest.approx(21 / 8)
    ps = [rows[0]["p_value"], rows[1]["p_value"]]
    assert rows[1]["p_holm"] == pytest.approx(min(1, 2 * min(ps)))  # Holm over the two levels
    # the binary test sees no difference at level 1 (nobody succeeds): progress does
    binary = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    assert binary[1]["p_value"] == 1.0
    md = (tmp_path / "c" / "compare.md").read_text()
    assert "Partial credit (progress 0..5" in md and "Wilcoxon signed-rank" in md
    assert (tmp_path / "c" / "plots" / "pick_y_progress.png").stat().st_size > 0
    # unpaired (other seeds): the rank-sum permutation test on the same scores
    c = _run(tmp_path / "c3", {0: [5, 5, 5, 4, 3, 1, 3, 2], 1: [3, 3, 2, 4, 3, 1, 2, 3]}, seed_offset=7)
    prog = compare_summaries(*(summarize(r.episodes(), r.manifest) for r in (a, c)),
                             episodes=(a.episodes(), c.episodes()))["axes"]["pick_y"]["progress"]  # fmt: skip
    assert prog["test"] == "rank_sum_permutation" and not prog["paired"]
    row1 = next(r for r in prog["levels"] if r["level"] == 1)
    assert row1["p_value"] == pytest.approx(
        rank_sum_test([0, 1, 0, 1, 3, 0, 0, 1], [3, 3, 2, 4, 3, 1, 2, 3])[0]
    )


def test_run_without_the_progress_column_loads_reports_and_compares(tmp_path, capsys):
    import pyarrow.parquet as pq

    a = _run(tmp_path / "a", {0: [5, 5, 0, 3], 1: [0, 1, 5, 3]})
    old = pq.read_table(a.path / EPISODES).drop(["progress"])  # what a release before the column wrote
    pq.write_table(old, a.path / EPISODES)
    df = RunDir.open(a.path).episodes()
    assert df["progress"].isna().all()  # missing, never 0
    assert main(["report", str(a.path)]) == 0
    summary = json.loads((a.path / "summary.json").read_text())
    assert all(r["progress"] is None for r in summary["axes"]["pick_y"]["levels"])
    assert not (a.path / "plots" / "pick_y_progress.png").exists()
    b = _run(tmp_path / "b", {0: [5, 5, 5, 4], 1: [3, 3, 5, 4]})
    assert main(["compare", str(a.path), str(b.path), "--out", str(tmp_path / "c")]) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert res["test"] == "mcnemar_exact" and "unavailable" in res["axes"]["pick_y"]["progress"]
    assert "predates the progress column" in (tmp_path / "c" / "compare.md").read_text()
    RunDir.create_or_resume(a.path, {"plan": {"x": 1}}).append(
        [rec(2, 0)]
    )  # resumes; the new row is unscored
    assert pq.read_table(a.path / EPISODES).column("progress").to_pylist() == [None] * 9


def test_report_shows_mean_progress_and_plot(tmp_path, capsys):
    a = _run(tmp_path / "a", {0: [5, 5, 4, 3], 1: [0, 1, 2, 5]})
    assert main(["report", str(a.path)]) == 0
    md = (a.path / "report.md").read_text()
    assert "Mean progress per level" in md and "| 0 | 4.25 (n = 4) |" in md
    assert (a.path / "plots" / "pick_y_progress.png").stat().st_size > 0
