"""Digest of run directories without their volatile fields, to show a refactor left behaviour byte-identical.

Usage: ``python scripts/run_digest.py RUN_DIR [RUN_DIR ...]`` prints one line per run: a SHA-256 over the
episodes (sorted by key; ``run_id`` and ``wall_s`` dropped), summary.json (``run_id``/times dropped) and report.md
(the run id and the directory path blanked), then a hash of all of them. Two checkouts that give the same line for
the same command made the same episodes, records and reports.
"""

from __future__ import annotations

import hashlib
import json
import re
import sys
from pathlib import Path

VOLATILE_COLUMNS = ("run_id", "wall_s")
VOLATILE_KEYS = ("run_id", "created", "wall_s", "path", "run_dir")


def _scrub(obj):
    """Drop volatile keys from nested JSON (run ids, timestamps, wall times, absolute paths)."""
    if isinstance(obj, dict):
        return {k: _scrub(v) for k, v in obj.items() if k not in VOLATILE_KEYS}
    if isinstance(obj, list):
        return [_scrub(v) for v in obj]
    return obj


def run_digest(run: Path) -> dict[str, str]:
    """Per-file SHA-256 of a run (or ``indgen report --out``) directory's outcome-bearing files, volatile
    fields removed; a file the directory lacks is left out."""
    import pandas as pd

    out = {}
    if (run / "episodes.parquet").is_file():
        ep = pd.read_parquet(run / "episodes.parquet").drop(columns=list(VOLATILE_COLUMNS), errors="ignore")
        ep = ep.sort_values(["task", "axis", "level", "episode"]).reset_index(drop=True)
        out["episodes"] = hashlib.sha256(ep.to_csv(index=False).encode()).hexdigest()[:16]
    if (run / "summary.json").is_file():
        summary = json.loads((run / "summary.json").read_text())
        out["summary"] = hashlib.sha256(json.dumps(_scrub(summary), sort_keys=True).encode()).hexdigest()[:16]
    if (run / "report.md").is_file():
        manifest = run / "manifest.json"
        run_id = json.loads(manifest.read_text()).get("run_id") if manifest.is_file() else None
        text = (run / "report.md").read_text().replace(str(run), "RUN")
        text = re.sub(r"\d{4}-\d\d-\d\dT[\d:+.]+", "TIME", text.replace(run_id, "RUNID") if run_id else text)
        out["report"] = hashlib.sha256(text.encode()).hexdigest()[:16]
    return out


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__.strip().splitlines()[2], file=sys.stderr)
        return 2
    total = hashlib.sha256()
    for arg in argv:
        d = run_digest(Path(arg))
        if not d:
            print(
                f"error: {arg} has no episodes.parquet, summary.json or report.md; pass run directories",
                file=sys.stderr,
            )
            return 2
        if not d:
            print(
                f"error: {arg} holds no episodes.parquet, summary.json or report.md; pass run directories",
                file=sys.stderr,
            )
            return 2
        total.update(json.dumps(d, sort_keys=True).encode())
        print(f"{arg}: " + " ".join(f"{k}={v}" for k, v in d.items()))
    print(f"all: {total.hexdigest()[:16]}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
