"""Print the held-out rule's false-certification probability (scenes.heldout) by exact binomial enumeration: the
chance that some of k attempts certifies a level whose oracle succeeds with rate p, beside keeping the best of k
attempts at the old fixed 59/59. scenes/certification/README.md quotes this table (tests/scenes/test_heldout.py
checks it).

    python scripts/certification_error_rate.py [--p 0.95] [--attempts 1 2 3 5 10]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from scenes.certificates import episodes_needed  # noqa: E402
from scenes.heldout import attempt_alpha, attempt_confidence, false_certification, naive_false_certification  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--p", type=float, default=0.95, help="the oracle's true success rate (default 0.95)")
    ap.add_argument("--attempts", type=int, nargs="+", default=[1, 2, 3, 5, 10])
    a = ap.parse_args()
    print("| attempt j | alpha_j | episodes (all must succeed) |\n|---|---|---|")
    for j in range(1, 5):
        print(f"| {j} | {attempt_alpha(j):.6g} | {episodes_needed(0.95, attempt_confidence(j))} |")
    print(f"\n| attempts | this rule | best of k at 59/59 |   (p = {a.p})\n|---|---|---|")
    for k in a.attempts:
        print(
            f"| {k} | {100 * false_certification(a.p, k):.2f} % | {100 * naive_false_certification(a.p, k):.2f} % |"
        )


if __name__ == "__main__":
    main()
