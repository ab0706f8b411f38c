"""Every printed rate is a claim: the "cannot answer" first lines, the named pools, the CIs beside compare's counts
and the plots' n and tasks (hand-computed values)."""

from __future__ import annotations

import pytest

from indgen_vla.core.comparison.two_runs import pairing_note, render_markdown, tasks_text
from indgen_vla.core.reporting.caveats import (
    axis_caveats,
    best_holm_p,
    break_undecidable,
    compare_caveats,
    design_caveats,
    needed_for_break,
    needed_pairs,
    rate_text,
    report_caveats,
)
from indgen_vla.core.reporting.figures import count_note, curve_note
from indgen_vla.core.reporting.report import render_markdown as report_md
from indgen_vla.core.stats.contrasts import t0_lines
from indgen_vla.core.stats.metrics import pooled_text


def test_best_holm_p_is_m_times_the_all_discordant_mcnemar_p():
    assert best_holm_p(5, 2) == pytest.approx(
        2 * 2 * 0.5**5
    )  # 0.125: what compare printed at 5 pairs, 2 levels
    assert best_holm_p(5, 1) == pytest.approx(0.0625)
    assert needed_pairs(1, 0.05) == 6  # 2 * 0.5**6 = 0.031 < 0.05 <= 2 * 0.5**5
    assert needed_pairs(2, 0.05) == 7  # 4 * 0.5**7 = 0.031 < 0.05 <= 4 * 0.5**6 = 0.0625


def test_wilson_break_floor_is_16_episodes_at_gamma_02():
    # Wilson's upper end for 0/n is z²/(n + z²) (z² = 3.8415): below 0.2 iff n > 4 z² = 15.37
    assert break_undecidable(15, 0.2) and not break_undecidable(16, 0.2)
    assert needed_for_break(0.2) == 16


def _row(level, s, n, lo, hi, pairs=None):
    r = {
        "level": level,
        "param": float(level),
        "n": n,
        "successes": s,
        "rate": s / n,
        "ci_low": lo,
        "ci_high": hi,
        "errors": 0,
    }
    if pairs is not None:
        r["vs_t0"] = {"n_pairs": pairs, "p": 1.0}
    return r


def _axis(t0_successes: int, n: int) -> dict:
    return {"signed": False, "pooled_tasks": ["bread", "milk"],
            "levels": [_row(0, t0_successes, n, 0.0, 0.2775), _row(1, 0, n, 0.0, 0.2775, pairs=n)],
            "vs_t0": {"holm_over": [1]}, "break_level": {"pos": 0}}  # fmt: skip


def test_axis_caveats_name_run_axis_n_ci_and_tasks():
    lines = axis_caveats("standin:random", "pick_y", _axis(0, 10), 0.2, "wilson")
    assert lines[0].startswith(
        "**Cannot answer** (standin:random, `pick_y`, pooled over 2 tasks: bread, milk): T0 succeeds in 0/10"
    )
    assert "0% [0, 28], Wilson 95 % CI" in lines[0]
    assert (
        lines[1].startswith("**Too few episodes**")
        and "n ≥ 16" in lines[1]
        and "not a statistically decided break" in lines[1]
    )
    assert len(lines) == 2  # 10 pairs, one level: 2 * 0.5**10 < 0.05, the T0 test can answer


def test_no_observed_break_gets_no_sentence_about_an_observed_k_star():
    """10/10 at every level: no level can be decided broken at n = 10, but no k* was read off an observed rate
    either (k* is "no break", every level intact), so the line must not say "the k* below is the first level whose
    observed rate is under γ"."""
    a = _axis(10, 10)
    a["levels"][1].update(successes=10, rate=1.0, ci_low=0.7225, ci_high=1.0)
    (line,) = [x for x in axis_caveats("A", "x", a, 0.2, "wilson") if x.startswith("**Too few episodes**")]
    assert "first level whose observed rate" not in line and "n ≥ 16" in line
    assert "had one fallen under γ, its break would only have been observed" in line


def test_an_adaptive_axis_gets_no_wilson_break_caveat():
    """Under --adaptive the sequential rule decides a break (0/15 is "decided below γ by the sequential rule"): the
    line that no level can be decided broken at n < 16 was false there; the T0 lines stay."""
    a = _axis(0, 10)
    a["levels"][1]["sequential"] = {"verdict": "broken", "n": 10}
    lines = axis_caveats("A", "x", a, 0.2, "wilson")
    assert lines[0].startswith("**Cannot answer**") and not any("Too few episodes" in x for x in lines)


def test_axis_caveats_no_power_against_t0_and_none_for_a_sound_study():
    five = axis_caveats("A", "x", _axis(5, 5), 0.2, "wilson")
    assert any(
        x.startswith("**No power against T0**") and "Holm p = 0.0625" in x and "≥ 6 pairs" in x for x in five
    )
    sound = _axis(40, 40)
    sound["levels"][1].update(successes=40, rate=1.0)
    assert axis_caveats("A", "x", sound, 0.2, "wilson") == []


def test_a_study_below_the_data_floor_everywhere_says_so_first():
    a = _axis(3, 3)
    for r in a["levels"]:
        r["insufficient"] = True  # 3 < 5 finished episodes: no rate is printed
    a["levels"][1]["vs_t0"]["p"] = float("nan")  # and no test (summary: NaN below the floor)
    (line,) = axis_caveats("real", "stack", a, 0.2, "wilson")
    assert line.startswith(
        "**Too few episodes** (real, `stack`, pooled over 2 tasks: bread, milk): every level is below the data floor"
    )
    assert "at most n = 3 a level" in line


def test_design_caveats_bound_any_outcome_of_the_plan():
    assert design_caveats("s", 4, 2, 0.2)[0].endswith("plan --episodes 5 or more.")
    ten = design_caveats("s", 10, 1, 0.2)  # one level surely tested: 2 · 0.5**10 < 0.05 can answer
    assert len(ten) == 1 and "even 0/10 leaves the Wilson 95 % CI above γ = 0.2" in ten[0]
    assert design_caveats("s", 10, 1, 0.2, break_by_ci=False) == []  # an SPRT decides a break its own way
    assert design_caveats("s", 16, 5, 0.2) == []  # 0/16 is below γ; 5 · 2 · 0.5**16 = 1.5e-4 < 0.05
    (power,) = design_caveats("s", 6, 5, 0.2, break_by_ci=False)  # 5 · 2 · 0.5**6 = 0.156; 0.5**8 < 0.005
    assert (
        power.startswith("**No power against T0** (s)") and "Holm p = 0.156" in power and "≥ 8 pairs" in power
    )


def _compare(paired: bool, n: int) -> dict:
    row = {"level": 0, "n_a": n, "successes_a": n, "rate_a": 1.0, "n_b": n, "successes_b": 0, "rate_b": 0.0,
           "pairs": n, "a_only": n, "b_only": 0, "p_value": 0.0625, "p_holm": 0.125}  # fmt: skip
    ax = {"levels": [row, {**row, "level": 1}], "break_level_a": {"pos": None}, "break_level_b": {"pos": 0},
          "tasks": "task milk"}  # fmt: skip
    return {"test": "mcnemar_exact" if paired else "boschloo", "paired": paired, "axes": {"d": ax}}


def test_compare_first_lines_say_a_powerless_comparison_cannot_answer():
    res = _compare(True, 5)
    text = render_markdown(res, "A", "B", "no level differs")
    first = text.splitlines()[2]
    assert first.startswith("**Cannot answer** (`d`): at most 5 episode pairs a level and Holm over 2 levels")
    assert "Holm p = 0.125" in first
    assert "| 0 | 5/5 = 100% [57, 100] | 0/5 = 0% [0, 43] |" in text  # Wilson: 5/(5 + z²) = 0.566
    assert "A and B: successes/n = rate [Wilson 95 % CI]; task milk." in text
    assert compare_caveats(_compare(True, 10)) == []  # 2 * 2 * 0.5**10 < 0.05
    assert compare_caveats(_compare(False, 5)) == []  # Boschloo 5/5 vs 0/5: p = 0.0079, Holm 0.016


def test_compare_helpers_say_paired_and_tasks():
    assert rate_text(0, 0) == "0/0" and rate_text(5, 5) == "5/5 = 100% [57, 100]"
    assert tasks_text(["milk"], ["milk"]) == "task milk"
    assert (
        tasks_text(["a"], ["b", "c"])
        == "A: task a; B: pooled over 2 tasks: b, c (rates pool different tasks)"
    )
    assert pairing_note({"paired": True}).startswith("paired")
    assert pairing_note({"paired": False, "test": "boschloo"}).startswith("unpaired: Boschloo")


def test_pools_are_named_in_terminal_and_report():
    assert pooled_text(["milk"]) == "task milk"
    assert pooled_text(["bread", "milk"]) == "pooled over 2 tasks: bread, milk"
    assert pooled_text(list("abcd")) == "pooled over 4 tasks: a, b, c, d"
    assert pooled_text(list("abcdefg")) == "pooled over 7 tasks: a, b, c and 4 more"  # long lists: 3 named
    assert pooled_text([]) == "tasks unknown"
    a = _axis(0, 10)
    a["levels"][1]["vs_t0"].update(
        delta=0.0, ci=[-0.28, 0.28], discordant=[0, 0], p_holm=1.0, unpaired=[0, 0]
    )
    a["vs_t0"].update(verdict="no level differs from T0", margin=None)
    assert t0_lines(a)[0].startswith("change from T0 (paired within task, pooled over 2 tasks: bread, milk)")
    s = {
        "gamma": 0.2,
        "ci": "wilson",
        "axes": {"pick_y": {**a, "kstar_status": {}, "trend": {}, "monotone": {}}},
    }
    text = report_md([("standin:random", s)], "Report")
    assert text.splitlines()[2].startswith("**Cannot answer** (standin:random, `pick_y`")


def test_plot_notes_carry_n_and_tasks():
    assert count_note([10, 10], ["milk"]) == "n = 10 per level; task milk"
    assert count_note([5, 10], ["bread", "milk"]) == "n = 5–10 per level; pooled over 2 tasks: bread, milk"
    assert count_note([3], list("abcde")) == "n = 3 per level; pooled over 5 tasks: a, b, c and 2 more"
    assert curve_note([_axis(0, 10)]) == "n = 10 per level; pooled over 2 tasks: bread, milk"


def test_a_declared_blind_policy_comes_first_and_an_undeclared_one_is_unknown():
    s = {"gamma": 0.2, "ci": "wilson", "axes": {"pick_y": _axis(0, 10)}}  # T0 0/10: its own caveats follow
    own = report_caveats([("r", s)])
    assert not any("declares" in line for line in own)  # no field: a run made before it, unknown
    assert report_caveats([("r", {**s, "reads_observations": True})]) == own
    blind = report_caveats([("r", {**s, "reads_observations": False})])
    assert (
        blind[0].startswith("**Cannot answer** (r): the policy declares it reads no observation")
        and blind[1:] == own
    )
    res = {"axes": {}, "reads_observations": {"a": None, "b": False}}
    assert [line[:24] for line in compare_caveats({**res, "label_b": "B"})] == ["**Cannot answer** (B): t"]
    assert compare_caveats({**res, "label_b": "oracle"})[0].startswith(
        "**Cannot answer** (oracle (B)): the policy"
    )
    assert compare_caveats({"axes": {}}) == []


def test_a_smoke_run_says_not_a_measurement_before_any_rate(tmp_path):
    """A ``--smoke`` run's manifest says "not a measurement"; its summary carries that and report.md (and the
    terminal, from the same caveats) opens with it, where before only report.html's subtitle said so."""
    from indgen_vla.core.reporting.summary import summarize
    from indgen_vla.core.runs.records import EpisodeRecord, RunDir

    smoke = "not a measurement (--smoke: a smoke run, e.g. an image policy on placeholder assets)"
    for name, extra in (("real", {}), ("smoke", {"measurement": smoke})):
        run = RunDir.create_or_resume(tmp_path / name, {"plan": {"tasks": ["milk"]}, "policy": "p", **extra})
        run.append([EpisodeRecord(run_id="r", policy="p", data_regime="", scene="s", task="milk", axis="scale",
                                  level=0, param=1.0, episode=i, seed=i, success=True, steps=1, status="ok",
                                  error="") for i in range(10)])  # fmt: skip
        s = summarize(run.episodes(), run.manifest)
        lines = report_caveats([("p", s)])
        if extra:
            assert s["measurement"] == smoke and lines[0] == (
                "**Not a measurement** (p): --smoke: a smoke run, e.g. an image policy on placeholder assets; "
                "its rates are not the policy's."
            )
            assert report_md([("p", s)]).split("\n")[2] == lines[0]
        else:
            assert "measurement" not in s and not any("measurement" in line for line in lines)


def test_a_run_on_placeholder_assets_says_so_unless_it_is_a_smoke_run():
    """A run whose manifest records placeholder assets (RoboCasa's boxes, LIBERO's miniature tree) opens with that
    line; a --smoke run says "Not a measurement" instead, not both."""
    levels = [
        {"level": 0, "n": 10, "successes": 10, "rate": 1.0, "ci_low": 0.72, "ci_high": 1.0, "errors": 0}
    ]
    base = {"axes": {}, "reads_observations": None, "placeholder_assets": True}
    (line,) = report_caveats([("oracle", base)])
    assert line.startswith("**Placeholder assets** (oracle): the scene was simulated with placeholder assets")
    smoke = report_caveats([("p", {**base, "measurement": "not a measurement (--smoke: x)"})])
    assert smoke == ["**Not a measurement** (p): --smoke: x; its rates are not the policy's."]
    assert report_caveats([("oracle", {**base, "placeholder_assets": False})]) == [] and levels
