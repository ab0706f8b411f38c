"""Group comparisons (one run per training seed) on hand-built episode tables."""

import math

import pandas as pd
import pytest
from scipy import stats
from scipy.stats import binomtest

from indgen_vla.core.comparison.two_groups import compare_groups, render_markdown, verdict
from indgen_vla.core.errors import RunDirError


def table(outcomes: dict[int, list[int]], seed0: int = 100) -> pd.DataFrame:
    """Episode rows of one run: level -> per-episode success (episode i has seed seed0 + i at every level)."""
    rows = [
        {"scene": "pick_place", "task": "milk", "axis": "pick_y", "level": k, "param": 0.025 * k, "episode": i,
         "seed": seed0 + i, "success": bool(s), "status": "ok"}
        for k, outs in outcomes.items()
        for i, s in enumerate(outs)
    ]  # fmt: skip
    return pd.DataFrame(rows)


def test_paired_levels_pool_discordant_pairs_over_seeds():
    a1 = table({-1: [1, 0, 0, 0], 0: [1, 1, 1, 1], 1: [1, 1, 0, 0]})
    b1 = table({-1: [1, 1, 1, 0], 0: [1, 1, 1, 1], 1: [1, 1, 0, 0]})
    a2 = table({-1: [0, 0, 0, 0], 0: [1, 1, 1, 1], 1: [0, 1, 0, 0]})
    b2 = table({-1: [1, 1, 1, 1], 0: [1, 1, 1, 1], 1: [1, 0, 0, 0]})
    res = compare_groups([a1, a2], [b1, b2], margin=0.1)
    assert res["test"] == "mcnemar_exact_stratified" and res["strata"] == 2
    lv = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    # level -1: seed 1 has 0 A-only / 2 B-only, seed 2 has 0 / 4 -> Binomial(6, 1/2): p = 2 * 0.5**6
    assert (lv[-1]["a_only"], lv[-1]["b_only"], lv[-1]["pairs"]) == (0, 6, 8)
    assert lv[-1]["p_value"] == pytest.approx(2 * 0.5**6)
    assert lv[1]["a_only"] == lv[1]["b_only"] == 1 and lv[1]["p_value"] == 1.0
    assert lv[0]["p_value"] == 1.0 and (lv[-1]["successes_a"], lv[-1]["successes_b"]) == (1, 7)
    # Holm over the three levels: the smallest p is multiplied by 3
    assert lv[-1]["p_holm"] == pytest.approx(3 * 2 * 0.5**6)
    sl = res["axes"]["pick_y"]["seed_level"]
    # OOD area (levels -1, 1): A seed 1 = (0.25 + 0.5)/2, seed 2 = (0 + 0.25)/2; B = (0.75+0.5)/2, (1+0.25)/2
    assert sl["ood_area"]["a"] == pytest.approx([0.375, 0.125]) and sl["ood_area"]["b"] == pytest.approx(
        [0.625] * 2
    )
    welch = stats.ttest_ind([0.625, 0.625], [0.375, 0.125], equal_var=False)
    assert sl["ood_area"]["diff"] == pytest.approx(0.375)
    assert (sl["ood_area"]["ci"][0] > 0) == (welch.pvalue < 0.05)
    # 4 episodes a level: below the 5-episode data floor, so no seed has a k* (report says "undetermined" too)
    assert sl["kstar_neg"]["a"] == sl["kstar_pos"]["b"] == ["undetermined"] * 2
    assert math.isnan(sl["kstar_pos"]["diff"]) and math.isnan(sl["kstar_pos"]["ci"][0])
    text = verdict({**res, "alpha": 0.05}, "h-only", "h+mg")
    assert "no level differs after Holm" in text and "+37.5 points" in text and "2 vs 2 seeds" in text
    res["verdict"] = text
    assert "(undetermined: a level before the break is below the 5-episode data floor)" in text
    md = render_markdown(res, "h-only", "h+mg")
    assert (
        "| -1 | 8 | 1/8 = 12% [2, 47] | 7/8 = 88% [53, 98] | 0 | 6 |" in md
    )  # Wilson, scipy: 1/8 -> [.022, .47]
    assert (
        "or K+1 when no level through the last one run (K) breaks" in md
    )  # what a k* of +2 at levels 0..1 is
    assert (
        res["caveats"] == [] and "**Cannot answer**" not in md
    )  # 3 · 2 · 0.5**8 = 0.023 < 0.05 was possible
    assert text.startswith("pick_y (task milk; paired, stratified by seed (2 run pairs)): no level differs")
    assert "| kstar_pos | undetermined, undetermined | undetermined, undetermined | n/a |" in md


def test_seed_kstar_reads_only_levels_above_the_data_floor():
    # gamma 0.2. A seed 1: -1 at 1/5 (20 %, not below) then no break -> -2; +1 at 0/5 -> +1.
    # A seed 2: -1 at 0/5 -> -1; +1 at 2/5 -> +2. B: every level 5/5 -> -2 and +2.
    a1 = table({-1: [1, 0, 0, 0, 0], 0: [1] * 5, 1: [0] * 5})
    a2 = table({-1: [0] * 5, 0: [1] * 5, 1: [1, 1, 0, 0, 0]})
    b1, b2 = (table({-1: [1] * 5, 0: [1] * 5, 1: [1] * 5}) for _ in range(2))
    sl = compare_groups([a1, a2], [b1, b2])["axes"]["pick_y"]["seed_level"]
    assert sl["kstar_neg"]["a"] == [-2, -1] and sl["kstar_neg"]["b"] == [-2, -2]
    assert sl["kstar_pos"]["a"] == [1, 2] and sl["kstar_pos"]["b"] == [2, 2]
    assert sl["kstar_pos"]["diff"] == pytest.approx(0.5)  # mean 2 - mean 1.5
    # a level whose errors leave fewer than half its episodes finished is below the floor as well
    errors = table({0: [1] * 6, 1: [1] * 11}).assign(
        status=["ok"] * 6 + ["ok"] * 5 + ["error"] * 6
    )  # 5 of 11
    sl = compare_groups([errors], [errors])["axes"]["pick_y"]["seed_level"]
    assert sl["kstar_pos"]["a"] == ["undetermined"]


def test_single_pair_is_exact_mcnemar():
    a = table({0: [1] * 6 + [0] * 4, 1: [1, 0, 0, 0, 0, 0, 0, 0, 0, 0]})
    b = table({0: [1] * 10, 1: [1, 1, 1, 1, 1, 1, 1, 1, 0, 0]})
    res = compare_groups([a], [b])
    assert res["test"] == "mcnemar_exact"
    lv = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    assert lv[1]["p_value"] == pytest.approx(stats.binomtest(0, 7, 0.5).pvalue)
    assert math.isnan(res["axes"]["pick_y"]["seed_level"]["ood_area"]["tost_p"])  # one seed: no TOST
    res["verdict"] = verdict({**res, "alpha": 0.05}, "a", "b")
    md = render_markdown(res, "a", "b")  # compare.md says why there is no TOST p instead of printing nan
    assert "TOST p (margin ±0.1): n/a (needs two or more runs per side" in md and "nan" not in md


def test_unpaired_or_unbalanced_groups_are_refused():
    a = table({0: [1, 1]})
    with pytest.raises(RunDirError, match="not paired"):
        compare_groups([a], [table({0: [1, 1]}, seed0=7)])
    with pytest.raises(RunDirError, match="one run per training seed"):
        compare_groups([a, a], [a])


def test_cli_compares_groups(tmp_path, capsys):
    import json

    from indgen_vla.app.cli import main
    from tests.indgen_vla.core.reporting.test_report import make_run

    a = [make_run(tmp_path / f"a{s}", {-1: (2, 10), 0: (10, 10), 1: (3, 10)}) for s in range(2)]
    b = [  # one of B's seeds declares a blind policy: the group is blind (interface.declared_reads)
        make_run(
            tmp_path / f"b{s}",
            {-1: (9, 10), 0: (10, 10), 1: (8, 10)},
            regime="h+mg",
            reads_observations=bool(s),
        )
        for s in range(2)
    ]
    args = ["compare", "--a", *(str(r.path) for r in a), "--b", *(str(r.path) for r in b), "--label-a", "h-only",
            "--label-b", "h+mg", "--out", str(tmp_path / "c")]  # fmt: skip
    assert main(args) == 0
    res = json.loads((tmp_path / "c" / "compare.json").read_text())
    lv = {r["level"]: r for r in res["axes"]["pick_y"]["levels"]}
    # make_run solves episodes 0..s-1: level -1 pairs differ on episodes 2..8 in both seeds -> 0 vs 14 discordant
    assert (lv[-1]["a_only"], lv[-1]["b_only"]) == (0, 14)
    ci = binomtest(18, 20).proportion_ci(method="wilson")  # B: 9 + 9 of 20 pairs
    assert lv[-1]["ci_b"] == [pytest.approx(ci.low), pytest.approx(ci.high)]
    assert (
        f"L-1 (4/20 = 20% [8, 42] vs 18/20 = 90% [{100 * ci.low:.0f}, {100 * ci.high:.0f}]" in res["verdict"]
    )
    assert lv[-1]["p_value"] == pytest.approx(stats.binomtest(0, 14, 0.5).pvalue)
    assert res["test"] == "mcnemar_exact_stratified" and "h+mg" in res["verdicts"]["pick_y"]
    md = (tmp_path / "c" / "compare.md").read_text()
    assert "## Axis `pick_y`" in md and res["reads_observations"] == {"a": None, "b": False}
    page = (tmp_path / "c" / "report.html").read_text()  # its verdicts name the run directories of each side
    verdicts = page[page.index('id="verdicts"') : page.index('id="report"')]
    assert (
        f"A = <code>h-only</code>: <code>{a[0].path}</code>, <code>{a[1].path}</code>; B = <code>h+mg</code>"
        in verdicts
    )
    assert md.splitlines()[2].startswith(
        "**Cannot answer** (h+mg (B)): the policy declares it reads no observation"
    )
    assert main(["compare", str(a[0].path), "--a", str(a[0].path), "--b", str(b[0].path)]) == 2
    assert main(["compare", "--a", str(a[0].path)]) == 2
    capsys.readouterr()
    twice = ["compare", "--a", str(a[0].path), str(tmp_path / "a0" / "."), "--b", *(str(r.path) for r in b)]
    assert main(twice) == 2  # the same run twice would double its evidence
    assert "given twice to --a/--b" in capsys.readouterr().err


def test_verdict_says_why_seeds_without_spread_give_no_interval():
    from indgen_vla.core.comparison.two_groups import axis_verdicts, render_markdown

    nan = math.nan
    area = {"a": [1.0, 1.0], "b": [1.0, 1.0], "diff": 0.0, "ci": [nan, nan], "tost_p": nan}
    result = {"alpha": 0.05, "margin": 0.1, "strata": 2, "verdict": "", "axes": {"pick_y": {
        "levels": [], "seed_level": {"ood_area": area}}}}  # fmt: skip
    text = axis_verdicts(result, "A", "B")["pick_y"]
    assert "do not vary at all" in text and "equivalent" not in text
    assert "n/a (no spread across runs)" in render_markdown(result, "A", "B")


def test_group_comparison_that_cannot_reach_alpha_says_so_first():
    # 2 seeds x 2 episodes a level: 4 pooled pairs, all A-only -> p = 2 · 0.5**4 = 0.125, Holm over 2 levels 0.25
    a, b = table({0: [1, 1], 1: [1, 1]}), table({0: [0, 0], 1: [0, 0]})
    res = compare_groups([a, a.copy()], [b, b.copy()])
    assert res["axes"]["pick_y"]["tasks"] == ["milk"]
    row = res["axes"]["pick_y"]["levels"][0]
    ci = binomtest(4, 4).proportion_ci(method="wilson")
    assert (row["pairs"], row["ci_a"], row["ci_b"][0]) == (
        4,
        [pytest.approx(ci.low), pytest.approx(1.0)],
        0.0,
    )
    assert row["p_holm"] == pytest.approx(0.25)
    (line,) = res["caveats"]
    assert line.startswith(
        "**Cannot answer** (`pick_y`): at most 4 episode pairs a level and Holm over 2 levels"
    )
    assert "Holm p = 0.25 ≥ α = 0.05 (paired exact McNemar, stratified by seed)" in line
    res["verdict"] = verdict(res, "a", "b")
    assert render_markdown(res, "a", "b").splitlines()[2] == line
