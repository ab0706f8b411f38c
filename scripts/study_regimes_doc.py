"""docs/results/data_regimes.md from the study's comparisons: the pre-specified protocol, then what the data show."""

from __future__ import annotations

import time
from pathlib import Path

from scenes.family import get_scene

DOC = Path(__file__).resolve().parents[1] / "docs" / "results" / "data_regimes.md"


def _protocol() -> str:
    """The pre-specified protocol section of the committed document (everything before "## Result")."""
    text = DOC.read_text()
    head = text.split("## Result", 1)[0]
    return head.split("## Question", 1)[1] if "## Question" in head else head


def _headline(cmp: dict, axis: str, primary: bool) -> str:
    """One paragraph per axis: the pre-specified endpoints first, then the per-level tests."""
    ax = cmp["axes"][axis]
    sl = ax["seed_level"]
    area = sl["ood_area"]
    role = "primary" if primary else "secondary"
    lines = [f"- **{axis}** ({role}). {cmp['verdicts'][axis]}"]
    lines.append(
        f"  OOD mean success per seed: h-only {', '.join(f'{v:.2f}' for v in area['a'])}; "
        f"h+mg {', '.join(f'{v:.2f}' for v in area['b'])}."
    )
    return "\n".join(lines)


def feasibility(results: dict, axes: list[str]) -> str:
    """Which evaluated levels the oracle's certificate covers (a failure at an uncertified level may be the scene's)."""
    import json
    from pathlib import Path

    from scenes.certificates import certified_levels, find_certification

    parts = []
    for axis in axes:
        manifest = json.loads((Path(results[axis][0]["runs_a"][0]) / "manifest.json").read_text())
        scene, (task, *_), levels = (
            manifest["scene"],
            manifest["plan"]["tasks"],
            manifest["plan"]["levels"][axis],
        )
        cert = find_certification(get_scene(scene), task, axis)
        ok = set(certified_levels(cert)) if cert else set()
        missing = [k for k in levels if k not in ok]
        parts.append(f"`{axis}` ({scene}/{task}): " + ("every evaluated level certified" if not missing else
                     f"levels {', '.join(f'{k:+d}' for k in missing)} not certified when this was written"))  # fmt: skip
    return (
        "Feasibility (oracle certificates, one-sided 95 % Clopper-Pearson lower bound ≥ 0.95, "
        "scenes/certification): " + "; ".join(parts) + "."
    )


def wall_text(wall: float, invocations: int, unrecorded: bool = False) -> str:
    """How long the study took, as the clock saw it (a lower bound when earlier invocations were not recorded)."""
    text = ("at least " if unrecorded else "") + f"{wall / 60:.1f} min"
    if invocations > 1:
        text += f" over {invocations} invocations (resumed)"
    text += ", on a 2-core CPU machine shared with other jobs"
    if unrecorded:
        text += ("; invocations before the per-invocation clock (2026-11-23, session 6) counted only when they "
                 "reached the document, so the earlier training and pick_y runs (logged 16:15-20:53 UTC) are "
                 "mostly missing")  # fmt: skip
    return text + "."


def render(
    results: dict, axes: list[str], args, wall: float, invocations: int, unrecorded: bool = False
) -> str:
    """The whole document; ``results`` maps axis -> (compare.json dict, compare.md text)."""
    primary = results[axes[0]][0]
    area = primary["axes"][axes[0]]["seed_level"]["ood_area"]
    sig = [r for r in primary["axes"][axes[0]]["levels"] if r["p_holm"] < primary["alpha"]]
    if sig:
        status = "MimicGen data changed success on at least one level of the primary axis (see below)."
    elif not (area["tost_p"] < primary["alpha"]):
        status = ("No difference was detected, and equivalence was not shown: this design cannot say that "
                  "MimicGen data does not help (see the power section of the protocol).")  # fmt: skip
    else:
        status = f"No level differs, and the regimes are equivalent within ±{primary['margin']:.2f} in OOD mean success."
    status = f"Primary axis {axes[0]}: {status[0].lower()}{status[1:]}"
    for axis in axes[1:]:  # a secondary finding belongs in the first lines too, labelled as secondary
        cmp = results[axis][0]
        if any(r["p_holm"] < cmp["alpha"] for r in cmp["axes"][axis]["levels"]):
            status += f" Secondary axis {cmp['verdicts'][axis]}"
    lines = [
        "# Data regimes: human-only vs human+MimicGen (pick_place, object-observing ACT)", "",
        f"**Status: run {time.strftime('%Y-%m-%d')} under the protocol below, pre-specified before the run. {status}**",
        "", f"`scripts/study_data_regimes.py --episodes {args.episodes} --seeds {args.seeds}`: wall time "
        + wall_text(wall, invocations, unrecorded), "",
        "## Question", "", _protocol().strip(), "",
        "## Result", "",
        *(_headline(results[a][0], a, i == 0) for i, a in enumerate(axes)), "",
    ]  # fmt: skip
    lines += [feasibility(results, axes), ""]
    if len(axes) == 1:
        lines += [f"No secondary axis was run (the protocol's `scale` is optional; `--axes {axes[0]},scale` adds "
                  "it: finished runs are reused).", ""]  # fmt: skip
    for axis in axes:
        md = results[axis][1]
        lines += ["#" + ln if ln.startswith("#") else ln for ln in md.splitlines()]
        lines.append("")
    return "\n".join(lines) + "\n"
