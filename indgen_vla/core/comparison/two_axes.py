"""``indgen compare RUN [RUN_B] --axes A_AXIS:B_AXIS``: one axis against another, paired episode by episode.

Episode i of a task has the same seed on every axis and at every level (``plan.plan_jobs``), so level k of
``pick_y+distractor`` and level k of ``pick_y`` start from the same initial state: within one run, or across two
runs evaluated with the same --seed, their episodes pair on (scene, task, level, episode). Per shared level the
exact McNemar test on the discordant pairs, Holm over the levels, Δ = B − A with its paired 95 % interval and an
equivalence test within ±--margin (``contrasts``); ``compare.axes_main`` writes them to compare's own files
(compare.json, compare.md, plots).
"""

from __future__ import annotations

from typing import Any

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.protocol.axis_ref import AxisRef
from indgen_vla.core.reporting.failures import failure_shift
from indgen_vla.core.reporting.partial_credit import compare_progress
from indgen_vla.core.stats.contrasts import ALPHA, AxisPairs, pair_axes, paired_delta
from indgen_vla.core.stats.metrics import compare_paired_levels


def parse_axes(text: str) -> tuple[str, str]:
    """``A_AXIS:B_AXIS`` (axis names never hold ':') -> (A, B)."""
    a, sep, b = text.partition(":")
    if not sep or not a.strip() or not b.strip() or ":" in b:
        raise ConfigError(f"--axes takes A_AXIS:B_AXIS, e.g. --axes pick_y+distractor:pick_y; got {text!r}")
    return a.strip(), b.strip()


def _steps(manifest: dict, axis: str) -> dict[str, float]:
    """Each component's step of ``axis`` as the run recorded it ({} for runs that did not)."""
    succ = ((manifest.get("resolved") or {}).get("environment") or {}).get("successors") or {}
    return dict((succ.get(axis) or {}).get("steps") or {})


def check_plans(ra, rb, ea, eb, axis_a: str, axis_b: str) -> None:
    """Refuse, in one line, axes missing from their run, another scene, and a shared component moved by another step
    (level k would not be the same shift on both axes)."""
    for run, e, axis in ((ra, ea, axis_a), (rb, eb, axis_b)):
        if not (e["axis"] == axis).any():
            have = ", ".join(sorted(set(e["axis"]))) or "none"
            raise RunDirError(
                f"axis {axis!r} has no episodes in {run.path} (its axes: {have}); name one of them"
            )
    sc_a, sc_b = set(ea.loc[ea["axis"] == axis_a, "scene"]), set(eb.loc[eb["axis"] == axis_b, "scene"])
    if not sc_a & sc_b:
        raise RunDirError(f"{axis_a} ran on scene {', '.join(sorted(sc_a))} and {axis_b} on "
                          f"{', '.join(sorted(sc_b))}: episodes of different scenes are not paired")  # fmt: skip
    st_a, st_b = _steps(ra.manifest, axis_a), _steps(rb.manifest, axis_b)
    for comp in sorted(set(st_a) & set(st_b) - {"held_level"}):  # a held level is a start, not a step
        if abs(st_a[comp] - st_b[comp]) > 1e-9 * max(1.0, abs(st_a[comp])):
            raise RunDirError(f"component {comp} moves {st_a[comp]:g} per level on {axis_a} but {st_b[comp]:g} on "
                              f"{axis_b}, so level k is not the same shift; evaluate both with the same "
                              "--axes-preset")  # fmt: skip


def same_start(axis_a: str, axis_b: str) -> bool:
    """Whether level 0 is one environment on both axes: T0, or the same held level of the same held axis (``A@B=j``
    starts at B's level j; ``A@B=0`` at T0)."""

    def start(axis: str) -> tuple[str, int] | None:
        ref = AxisRef.parse(axis)
        return (ref.held, ref.held_level) if ref.held is not None and ref.held_level != 0 else None

    return start(axis_a) == start(axis_b)


def contrast_rows(pairs: AxisPairs, margin: float, alpha: float = ALPHA, same_t0: bool = True) -> list[dict]:
    """compare's paired rows (exact McNemar, Holm over the levels k != 0) plus Δ = B − A, its 95 % interval, the
    paired equivalence test and the episodes left without a partner. Level 0 is T0 on both axes: its row checks the
    pairing (a difference there is run-to-run noise) and stays out of the Holm family (``p_holm`` NaN); where level 0
    differs (``same_t0`` False: two rows of a grid, ``same_start``) it is tested like any other level."""
    rows = compare_paired_levels({k: v for k, v in pairs.pairs.items() if k != 0 or not same_t0})
    if 0 in pairs.pairs and same_t0:  # T0 on both axes: a check of the pairing, outside the tested family
        rows = sorted([*rows, {**compare_paired_levels({0: pairs.pairs[0]})[0], "p_holm": float("nan")}],
                      key=lambda r: r["level"])  # fmt: skip
    for r in rows:
        r["delta"], r["delta_ci"], r["equivalence"] = paired_delta(r, margin, alpha)
        r["unpaired"] = list(pairs.unpaired[r["level"]])
    return rows


def equivalence_sentence(rows: list[dict], margin: float, alpha: float = ALPHA) -> str:
    """Where "no difference" may be said: the levels whose paired equivalence test (two exact one-sided tests) passes."""
    rows = [r for r in rows if r["pairs"] and r["level"] != 0]
    shown = [str(r["level"]) for r in rows if r["equivalence"]["equivalent"]]
    head = f"Equivalence within ±{100 * margin:.0f} pp (paired TOST, α = {alpha:g}, per level)"
    if rows and len(shown) == len(rows):
        return f"{head}: shown at every level k != 0."
    if not shown:
        return f"{head}: not shown at any level."
    rest = [str(r["level"]) for r in rows if not r["equivalence"]["equivalent"]]
    return f"{head}: shown at L{', L'.join(shown)}; not shown at L{', L'.join(rest)}."


def same_rollouts(ea, eb, axis_a: str, axis_b: str) -> int:
    """Level-0 pairs of A and B that are one rollout recorded for both axes (``evaluate``'s shared T0): the same run
    (``run_id``) and the same source axis (``shared_from``, else the row's own axis)."""
    on = ["scene", "task", "episode", "run_id"]

    def t0(e, axis):
        rows = e[(e["axis"] == axis) & (e["level"] == 0) & (e["status"] == "ok")]
        return rows[on].assign(source=rows["shared_from"].where(rows["shared_from"] != "", axis))

    m = t0(ea, axis_a).merge(t0(eb, axis_b), on=on, suffixes=("_a", "_b"))
    return int((m["source_a"] == m["source_b"]).sum())


def as_one_axis(e, axis: str, key: str):
    """``axis``'s episodes renamed ``key``: both sides under one name, so compare's per-axis helpers (progress pairs,
    break points) read the two axes as one."""
    return e[e["axis"] == axis].assign(axis=key)


def compare_axes(
    ea, eb, sa: dict, sb: dict, axis_a: str, axis_b: str, margin: float, alpha: float = ALPHA
) -> dict[str, Any]:
    """The compare.json dict of axis A (episodes ``ea``, summary ``sa``) against axis B (``eb``, ``sb``), but for
    the break point difference (``compare.axes_main`` adds it)."""
    pairs = pair_axes(ea, eb, axis_a, axis_b)
    if not any(pairs.pairs.values()):
        raise RunDirError(f"no finished episode of {axis_a} has a finished partner on {axis_b} (same task, level and "
                          "episode); evaluate both on common tasks and levels")  # fmt: skip
    key = f"{axis_a} vs {axis_b}"
    a, b = sa["axes"][axis_a], sb["axes"][axis_b]
    ra, rb = as_one_axis(ea, axis_a, key), as_one_axis(eb, axis_b, key)
    same_t0 = same_start(axis_a, axis_b)
    rows = contrast_rows(pairs, margin, alpha, same_t0)
    pairing, same = pairs.describe(), same_rollouts(ea, eb, axis_a, axis_b)
    for r in rows:
        if r["level"] == 0 and same:  # a shared T0: these pairs are one rollout, equal by construction
            r["same_rollout"] = same
            pairing += (f"; at level 0, {same} of {r['pairs']} pair(s) are one rollout recorded for both axes (T0 run "
                        "once: episodes.parquet shared_from), equal by construction, so level 0 checks nothing")  # fmt: skip
            if same == r["pairs"]:
                r["p_value"] = float("nan")
    return {
        "test": "mcnemar_exact", "paired": True, "gamma": sa["gamma"], "margin": margin,
        "contrast": {"axis_a": axis_a, "axis_b": axis_b, "paired_on": ["scene", "task", "level", "episode", "seed"],
                     "levels_only_a": list(pairs.only_a), "levels_only_b": list(pairs.only_b), "same_t0": same_t0},
        "axes": {key: {
            "axis_a": axis_a, "axis_b": axis_b, "levels": rows, "break_level_a": a["break_level"],
            "break_level_b": b["break_level"], "failures": failure_shift(a["levels"], b["levels"]),
            "pairing": pairing, "progress": compare_progress(ra, rb, key, True),
            "equivalence": equivalence_sentence(rows, margin, alpha),
        }},
    }  # fmt: skip
