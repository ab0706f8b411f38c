"""Commit a finished `indgen blockenv reproduce` run: copy it into docs/results and fill docs/blockenv.md's table.

The table sets the paper, the run committed before issue 15 (read from git at ``--before``) and this run side by
side (L0–L3 %, break level, L3 per seed, L3 intervals).

Usage: python scripts/blockenv_table1_doc.py RUN_DIR [--before COMMIT]
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

from indgen_vla.app.blockenv.ablate import replace_section
from indgen_vla.app.blockenv.reproduce import PAPER, render_markdown
from indgen_vla.core.errors import ConfigError

ROOT = Path(__file__).resolve().parent.parent
BEGIN, END = "<!-- table1-compare -->", "<!-- table1-compare:end -->"
BEFORE = "e175962"  # the last Table 1 committed before issue 15


def cells(table: dict, method: str) -> str:
    """'L0 / L1 / L2 / L3, break' of one method, or '—' where the table lacks it."""
    if method not in table:
        return "—"
    e, b = table[method], table[method]["break_level"]
    return (
        " / ".join(f"{100 * e['levels'][str(k)]['rate']:.0f}" for k in range(4))
        + f", {'—' if b is None else f'L{b}'}"
    )


def compare_lines(before: dict, after: dict) -> list[str]:
    lines = ["| method | paper | before issue 15 | now | now, L3 per seed (of 100) | now, L3 95 % CI: Wilson / t over seeds |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for m, e in after.items():
        p = PAPER.get(m)
        paper = (" / ".join(f"{v:g}" for v in p[0]) + f", {p[1]}") if p else "(ours)"
        l3 = e["levels"]["3"]
        seeds = " / ".join(str(q["successes"]) for q in l3["per_seed"])
        t = (
            "—"
            if l3["seed_ci_low"] is None
            else f"{100 * l3['seed_ci_low']:.0f}–{100 * l3['seed_ci_high']:.0f}"
        )
        lines.append(f"| {m} | {paper} | {cells(before, m)} | {cells(after, m)} | {seeds} | "
                     f"{100 * l3['ci_low']:.0f}–{100 * l3['ci_high']:.0f} / {t} |")  # fmt: skip
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run", type=Path, help="the reproduce --out folder")
    ap.add_argument("--before", default=BEFORE, help=f"commit holding the earlier table (default {BEFORE})")
    args = ap.parse_args()
    if not (args.run / "table1_run.json").is_file():
        sys.exit(f"error: {args.run} holds no table1_run.json; pass the --out folder of a finished reproduce")
    result = json.loads((args.run / "table1_run.json").read_text())
    res = ROOT / "docs/results"
    for src, dst in (("table1.json", "blockenv_table1.json"), ("table1_run.json", "blockenv_table1_run.json"),
                     ("table1.png", "blockenv_table1.png")):  # fmt: skip
        shutil.copyfile(args.run / src, res / dst)
    (res / "blockenv_table1.md").write_text(render_markdown(result))
    try:
        shown = subprocess.check_output(
            ["git", "show", f"{args.before}:docs/results/blockenv_table1.json"], cwd=ROOT
        )
    except (subprocess.CalledProcessError, FileNotFoundError):
        sys.exit(
            f"error: cannot read docs/results/blockenv_table1.json at {args.before}; pass --before COMMIT"
        )
    lines = compare_lines(json.loads(shown), result["methods"])
    try:
        replace_section(ROOT / "docs/blockenv.md", BEGIN, END, "\n".join(lines) + "\n", "table1-compare")
    except ConfigError as e:
        sys.exit(f"error: {e}")
    print("\n".join(lines))
    print(f"wall {result['wall_s'] / 60:.1f} min")


if __name__ == "__main__":
    main()
