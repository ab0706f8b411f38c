"""scripts/blockenv_table1_doc.py: the paper / before / now rows of docs/blockenv.md's Table 1 comparison."""

import importlib.util
from pathlib import Path

_spec = importlib.util.spec_from_file_location(
    "blockenv_table1_doc", Path(__file__).resolve().parents[2] / "scripts" / "blockenv_table1_doc.py"
)
doc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(doc)


def _entry(rates, brk, l3_seeds, l3_ci, seed_ci):
    levels = {str(k): {"rate": r} for k, r in enumerate(rates)}
    levels["3"].update(per_seed=[{"successes": s} for s in l3_seeds], ci_low=l3_ci[0], ci_high=l3_ci[1],
                       seed_ci_low=seed_ci[0], seed_ci_high=seed_ci[1])  # fmt: skip
    return {"levels": levels, "break_level": brk}


def test_compare_rows_hold_paper_before_now_and_l3_intervals():
    now = {"trm": _entry([1.0, 1.0, 0.9, 0.09], 3, [16, 4, 6], (0.06, 0.12), (None, None)),
           "local_equivariant": _entry([1.0] * 4, None, [100, 100, 100], (0.99, 1.0), (1.0, 1.0))}  # fmt: skip
    before = {"trm": _entry([1.0, 1.0, 1.0, 0.34], 4, [34], (0.3, 0.4), (None, None))}
    lines = doc.compare_lines(before, now)
    assert (
        lines[2]
        == "| trm | 100 / 100 / 92 / 0, L3 | 100 / 100 / 100 / 34, L4 | 100 / 100 / 90 / 9, L3 | 16 / 4 / 6 | 6–12 / — |"
    )
    assert (
        lines[3]
        == "| local_equivariant | (ours) | — | 100 / 100 / 100 / 100, — | 100 / 100 / 100 | 99–100 / 100–100 |"
    )
