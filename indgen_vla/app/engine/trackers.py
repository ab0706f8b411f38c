"""``--log trackio`` / ``--log wandb``: a run's (or a checkpoint series') numbers in an experiment tracker.

Logged per run, at its training step (a series) or step 0: each level's success rate with its Wilson 95 % CI and n
(``AXIS/L<k>/success``, ``…/ci_low``, ``…/ci_high``, ``…/n``), the failure modes' shares, k* per direction
(``AXIS/kstar_pos``; a number only when decided: "none in range" and "undetermined" stay in the table), a table with
one row per level (rates, CIs, the pooled tasks, the level's verdict) and each axis's verdict in words, and the example
videos when the run recorded some. The run's config and protocol fingerprint are the tracker run's config. Both are
optional extras (``pip install 'indgen-vla[trackio]'`` / ``[wandb]``): trackio writes a local project (``TRACKIO_DIR``),
W&B honours ``WANDB_MODE=offline``. Nothing here sends anything the tracker would not.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from indgen_vla.core.errors import ConfigError
from indgen_vla.core.protocol.fingerprint import digest
from indgen_vla.core.reporting.summary import summarize
from indgen_vla.core.runs.records import RunDir

TRACKERS = ("trackio", "wandb")
INSTALL = {"trackio": "pip install 'indgen-vla[trackio]' (or pip install trackio)",
           "wandb": "pip install 'indgen-vla[wandb]' (or pip install wandb)"}  # fmt: skip
VIDEOS_PER_RUN = 8  # example videos logged per run at most


def tracker_module(kind: str):
    """The tracker's package, imported; a kind that is no tracker, or one not installed, is one ``ConfigError`` line
    (callers check it before a run, so a missing extra costs no episodes)."""
    if kind not in TRACKERS:
        raise ConfigError(f"--log must be one of {', '.join(TRACKERS)}, got {kind!r}")
    import importlib

    try:
        return importlib.import_module(kind)
    except ImportError:
        raise ConfigError(f"--log {kind} needs the {kind} package; {INSTALL[kind]}") from None


def run_record(run_dir: str | Path) -> dict[str, Any]:
    """What a tracker gets from one run directory: ``metrics`` (flat numbers), ``rows`` (one per level), ``verdicts``
    (axis -> words), ``config`` (the evaluate config, fingerprint and its digest) and ``videos`` (paths)."""
    run = RunDir.open(run_dir)
    m = run.manifest
    s = summarize(run.episodes(), m, (m.get("config") or {}).get("gamma", 0.2))
    metrics: dict[str, float] = {}
    rows, verdicts = [], {}
    for axis, a in s["axes"].items():
        tasks = ", ".join(a.get("pooled_tasks") or [])
        for r in a["levels"]:
            if r["n"]:
                key = f"{axis}/L{r['level']}"
                metrics |= {f"{key}/success": r["rate"], f"{key}/ci_low": r["ci_low"], f"{key}/ci_high": r["ci_high"],
                            f"{key}/n": r["n"]}  # fmt: skip
                for mode, count in (r.get("failures") or {}).items():
                    metrics[f"{key}/failure/{mode}"] = count / r["n"]
            rows.append([axis, r["level"], r["n"], r["successes"], _num(r["rate"]), _num(r["ci_low"]),
                         _num(r["ci_high"]), bool(r.get("insufficient")), tasks])  # fmt: skip
        for side, k in (a.get("break_level") or {}).items():
            if isinstance(k, int):
                metrics[f"{axis}/kstar_{side}"] = k
        v = a.get("verdict")
        verdicts[axis] = (
            v if isinstance(v, str) else "; ".join(f"{side}: {t}" for side, t in (v or {}).items())
        )
    fp = m.get("fingerprint")
    config = {"policy": m.get("policy"), "scene": m.get("scene"), "run_dir": str(run.path), "run_id": m.get("run_id"),
              "config": m.get("config"), "fingerprint": fp, "fingerprint_digest": digest(fp) if fp else None}  # fmt: skip
    videos = (
        sorted((run.path / "videos").rglob("*.mp4"))[:VIDEOS_PER_RUN]
        if (run.path / "videos").is_dir()
        else []
    )
    return {"metrics": metrics, "rows": rows, "verdicts": verdicts, "config": config, "videos": videos}


COLUMNS = ["axis", "level", "n", "successes", "rate", "ci_low", "ci_high", "insufficient", "tasks"]


def _num(x: float) -> float | None:
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else float(x)


def _run_id(project: str, name: str) -> str:
    """A stable tracker run id for one series (so each new checkpoint resumes the same tracker run)."""
    return hashlib.sha256(f"{project}/{name}".encode()).hexdigest()[:16]


def log_runs(
    kind: str, entries: Sequence[tuple[int | None, str | Path]], *, project: str = "indgen", name: str | None = None,
    skip: Iterable[int] = (), directory: str | Path | None = None,
) -> list[int]:  # fmt: skip
    """Log each (step, run directory) of ``entries`` (step None: 0) into one tracker run; returns the steps logged.

    ``skip``: steps logged before (a series logs each checkpoint once). ``directory``: wandb's local dir."""
    mod = tracker_module(kind)
    todo = [(0 if s is None else int(s), Path(p)) for s, p in entries if s is None or s not in set(skip)]
    if not todo:
        return []
    records = [(s, run_record(p)) for s, p in todo]
    name = name or Path(todo[0][1]).name
    config = records[-1][1]["config"] | {"runs": [str(p) for _, p in todo]}
    if kind == "wandb":
        run = mod.init(project=project, name=name, id=_run_id(project, name), resume="allow", config=config,
                       dir=str(directory) if directory else None)  # fmt: skip
    else:
        run = mod.init(project=project, name=name, config=config, resume="allow")
    try:
        for step, rec in records:
            payload: dict[str, Any] = dict(rec["metrics"])
            payload["levels"] = mod.Table(columns=COLUMNS, data=rec["rows"])
            for v in rec["videos"]:
                payload[f"video/{v.parent.name}/{v.stem}"] = mod.Video(str(v), caption=v.stem, format="mp4")
            for axis, text in rec["verdicts"].items():
                if kind == "wandb":
                    run.summary[f"{axis}/verdict"] = text
                else:
                    payload[f"{axis}/verdict"] = mod.Markdown(f"**{axis}** (step {step}): {text}")
            mod.log(payload, step=step)
    finally:
        mod.finish()
    return [s for s, _ in records]
