"""``indgen reference RUN...``: the black-box regime of appendix B (Definition 3).

Each run directory holds one reference policy evaluated on canonical configurations: the (task, level) cells of
one axis. T0 is the configuration with the highest mean success over the reference policies, chosen on the
even-numbered episodes only; the ordering of the levels around T0 (success falls as the configuration moves
away from T0) is then tested on the odd-numbered episodes, which played no part in choosing T0.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError, RunDirError
from indgen_vla.core.reporting.report import insufficient_text, run_label
from indgen_vla.core.runs.records import RunDir, write_result
from indgen_vla.core.stats.metrics import (
    below_floor,
    blackbox_reference,
    cochran_armitage,
    monotone_decreasing_test,
    success_rate,
)

SPLIT = "T0 chosen on even episode indices; ordering tested on odd episode indices"


def _pick_axis(tables: list, axis: str | None) -> str:
    """The axis every run evaluated: the one given, or the only one they share."""
    shared = set.intersection(*(set(df["axis"].unique()) for df in tables))
    if axis is not None:
        if axis not in shared:
            raise ConfigError(
                f"--axis {axis}: not evaluated by every run (shared: {', '.join(sorted(shared)) or 'none'})"
            )
        return axis
    if len(shared) != 1:
        raise ConfigError(
            f"the runs share axes {', '.join(sorted(shared)) or '(none)'}; choose one with --axis"
        )
    return next(iter(shared))


def _counts(df, task: str, level: int, parity: int) -> tuple[int, int]:
    """(successes, finished) of one configuration on the episodes of one parity (0 even, 1 odd)."""
    d = df[
        (df["task"] == task) & (df["level"] == level) & (df["episode"] % 2 == parity) & (df["status"] == "ok")
    ]
    return int(d["success"].sum()), len(d)


def black_box_reference(
    tables: list,
    labels: list[str],
    axis: str | None = None,
    task: str | None = None,
    level: int | None = None,
) -> dict:
    """Choose T0 among the (task, level) configurations on held-in episodes, then test the level ordering
    around it on held-out episodes, per reference policy and direction (the reference.json dict). ``level``
    restricts the candidates to that level (e.g. 0: the canonical configurations, unperturbed); the ordering is
    still tested over every level of T0's task.

    Ties in mean success go to the configuration listed first: by task name, then by |level|, then level.
    """
    if not tables:
        raise ConfigError("indgen reference needs at least one run directory")
    axis = _pick_axis(tables, axis)
    tables = [df[df["axis"] == axis] for df in tables]
    if task is not None:
        known = set.intersection(*(set(df["task"].unique()) for df in tables))
        if task not in known:
            raise ConfigError(
                f"--task {task}: not evaluated on {axis} by every run (shared: {', '.join(sorted(known))})"
            )
        tables = [df[df["task"] == task] for df in tables]
    cells = set.intersection(
        *({(t, int(k)) for t, k in zip(df["task"], df["level"], strict=True)} for df in tables)
    )
    if level is not None and not any(k == level for _, k in cells):
        raise ConfigError(f"--level {level}: no run evaluated level {level} on {axis}")
    configs, rows = {}, []
    for t, k in sorted(cells, key=lambda c: (c[0], abs(c[1]), c[1])):
        if level is not None and k != level:
            continue
        held_in = [_counts(df, t, k, 0) for df in tables]
        if any(n == 0 for _, n in held_in):
            continue  # a policy without a finished even episode here cannot vote on this configuration
        rates = [s / n for s, n in held_in]
        configs[(t, k)] = rates
        rows.append({"task": t, "level": k, "successes": [s for s, _ in held_in], "n": [n for _, n in held_in],
                     "mean_success": sum(rates) / len(rates)})  # fmt: skip
    if not configs:
        raise RunDirError(f"no configuration on {axis} has finished even-numbered episodes in every run; "
                          "evaluate at least 2 episodes per level")  # fmt: skip
    (t0, k0), mean = blackbox_reference(configs)
    rows.sort(key=lambda c: (c["task"], c["level"]))
    out: dict[str, Any] = {"axis": axis, "split": SPLIT, "policies": labels, "configurations": rows,
                           "reference": {"task": t0, "level": k0, "mean_success": mean}, "ordering": {},
                           "candidate_level": level}  # fmt: skip
    levels = sorted(k for t, k in cells if t == t0)
    for label, df in zip(labels, tables, strict=True):
        held_out = []
        for k in levels:
            s, n = _counts(df, t0, k, 1)
            r = success_rate(s, n)
            held_out.append({"level": k, "offset": k - k0, "n": n, "successes": s, "rate": r.rate,
                             "ci_low": r.ci_low, "ci_high": r.ci_high, "insufficient": below_floor(n)})  # fmt: skip
        out["ordering"][label] = {"levels": held_out, "tests": _ordering_tests(held_out)}
    return out


def _ordering_tests(levels: list[dict]) -> dict:
    """Monotone (isotonic LRT) and linear (Cochran–Armitage) decrease away from T0, per direction."""
    res = {}
    for side, keep in (("pos", lambda d: d >= 0), ("neg", lambda d: d <= 0)):
        rows = sorted(
            (r for r in levels if keep(r["offset"]) and not r["insufficient"]), key=lambda r: abs(r["offset"])
        )
        if len(rows) < 2:
            continue
        x, n = [r["successes"] for r in rows], [r["n"] for r in rows]
        mono = monotone_decreasing_test(x, n)
        ca = cochran_armitage([abs(r["offset"]) for r in rows], x, n)
        res[side] = {"offsets": [r["offset"] for r in rows], "monotone_p": mono.p_decreasing,
                     "monotone_method": mono.method, "cochran_armitage_p": ca.p_decreasing}  # fmt: skip
    return res


def render_markdown(res: dict) -> str:
    """reference.md: the configurations with their held-in counts, T0, and the held-out ordering tests."""
    ref = res["reference"]
    lines = [f"# Black-box reference level on `{res['axis']}`", "",
             f"{SPLIT}. Reference policies: {', '.join(res['policies'])}. Mean success = mean over policies of "
             "each policy's rate on the even episodes (n per policy shown).", "",
             f"**T0 = task `{ref['task']}`, level {ref['level']}** (mean success {100 * ref['mean_success']:.0f}% "
             "on the even episodes)" + (f", chosen among the level-{res['candidate_level']} configurations only."
                                         if res.get("candidate_level") is not None else "."), "",
             "| task | level | " + " | ".join(res["policies"]) + " | mean success |",
             "|---|---|" + "---|" * (len(res["policies"]) + 1)]  # fmt: skip
    for c in res["configurations"]:
        cells = " | ".join(f"{s}/{n}" for s, n in zip(c["successes"], c["n"], strict=True))
        lines.append(f"| {c['task']} | {c['level']} | {cells} | {100 * c['mean_success']:.0f}% |")
    lines += ["", "## Ordering on the held-out (odd) episodes", "",
              "One-sided tests that success falls with the distance from T0, per direction: monotone "
              "(isotonic likelihood-ratio, permutation p) and linear (Cochran–Armitage); unpaired, not corrected "
              "for multiplicity across policies. Levels with n < 5 are left out.", ""]  # fmt: skip
    for label, o in res["ordering"].items():
        lines += [f"### {label}", "", "| level | offset from T0 | success (held-out) |", "|---|---|---|"]
        for r in o["levels"]:
            cell = (
                insufficient_text({**r, "planned": None, "errors": 0})
                if r["insufficient"]
                else (
                    f"{100 * r['rate']:.0f}% [{100 * r['ci_low']:.0f}, {100 * r['ci_high']:.0f}] (n={r['n']})"
                )
            )
            lines.append(f"| {r['level']} | {r['offset']:+d} | {cell} |")
        for side, t in o["tests"].items():
            lines.append(f"\n{'+' if side == 'pos' else '−'} side (offsets {t['offsets']}): monotone decrease "
                         f"p = {t['monotone_p']:.2g} ({t['monotone_method']}), linear trend p = "
                         f"{t['cochran_armitage_p']:.2g}")  # fmt: skip
        if not o["tests"]:
            lines.append("\nno direction has two levels with enough held-out data: the ordering is untested")
        lines.append("")
    return "\n".join(lines)


def reference_dir(first_run: str | Path, out: str | Path | None = None) -> Path:
    """Where reference.json/.md go: ``out``, else FIRST_RUN/reference."""
    return Path(out) if out else Path(first_run) / "reference"


def write_reference(
    runs: list[str | Path], *, axis: str | None = None, task: str | None = None, level: int | None = None,
    out: str | Path | None = None,
) -> dict[str, Any]:  # fmt: skip
    """``indgen reference``: T0 and the ordering test of the reference policies' runs, written to ``out`` (default
    FIRST_RUN/reference) as reference.json and reference.md; return the result."""
    runs = [RunDir.open(p) for p in runs]
    labels = [run_label(r) for r in runs]
    if len(set(labels)) < len(labels):
        labels = [f"{lbl} ({r.path.name})" for lbl, r in zip(labels, runs, strict=True)]
    res = black_box_reference([r.episodes() for r in runs], labels, axis, task, level)
    write_result(reference_dir(runs[0].path, out), "reference", res, render_markdown(res))
    return res
