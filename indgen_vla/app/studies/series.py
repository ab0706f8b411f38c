"""``indgen series``: one evaluate run per checkpoint of a training output, resumable, optionally following a training
that is still writing checkpoints; the series report comes from ``indgen_vla.core.comparison.series_report``.

A run per checkpoint lives in ``OUT/runs/<step>``; a checkpoint whose run finished is skipped on a re-run (its
manifest and summary are there and no planned episode is missing), a killed one resumes where it stopped (evaluate's
own resume). ``OUT/series_protocol.json`` holds the protocol (evaluate's config without policy and out): a re-run
under other flags is refused in one line instead of mixing two protocols in one series.
"""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from indgen_vla.app.engine.config import EvalConfig
from indgen_vla.app.engine.run import evaluate as run_evaluation
from indgen_vla.app.studies.config import SeriesConfig
from indgen_vla.core.errors import ConfigError
from indgen_vla.core.runs.records import MANIFEST, RunDir, atomic_write_json
from scenes.family import Scene

PROTOCOL = "series_protocol.json"
OWN_FIELDS = ("policy", "out")  # what differs from checkpoint to checkpoint


@dataclass(frozen=True)
class Checkpoint:
    """One checkpoint of a training output: its training step and its pretrained_model directory."""

    step: int
    path: Path

    def __post_init__(self) -> None:
        if self.step < 0:
            raise ConfigError(f"checkpoint {self.path}: step must be >= 0, got {self.step}")


def _model_dir(d: Path) -> Path | None:
    """The directory holding config.json: ``d`` itself or its ``pretrained_model`` (LeRobot's checkpoint layout)."""
    for c in (d, d / "pretrained_model"):
        if (c / "config.json").is_file():
            return c
    return None


def _step_of(d: Path, index: int) -> int:
    """The training step a directory names (LeRobot's ``checkpoints/005000``, ``step_5000``), else its index."""
    for part in (d.name, d.parent.name if d.name == "pretrained_model" else ""):
        m = re.fullmatch(r"\D*?(\d+)", part)
        if m:
            return int(m.group(1))
    return index


def find_checkpoints(roots: Sequence[str | Path], *, must_exist: bool = True) -> list[Checkpoint]:
    """The checkpoints of ``roots``: one LeRobot training output (``ROOT/checkpoints/<step>/pretrained_model``; the
    ``last`` link is skipped) or a list of checkpoint directories, in step order; one line refuses anything else."""
    roots = [Path(r).expanduser() for r in roots]
    for r in roots:
        if not r.is_dir():
            raise ConfigError(f"{r}: no such directory; give a LeRobot training output (ROOT/checkpoints/<step>/"
                              "pretrained_model) or checkpoint directories")  # fmt: skip
    if len(roots) == 1 and (roots[0] / "checkpoints").is_dir():
        found = []
        last = (
            roots[0] / "checkpoints" / "last"
        )  # LeRobot points it at a checkpoint once that one is complete
        newest = int(last.resolve().name) if last.is_symlink() and last.resolve().name.isdigit() else None
        for d in sorted((roots[0] / "checkpoints").iterdir()):
            if d.is_symlink() or not d.is_dir() or not d.name.isdigit():
                continue
            if newest is not None and int(d.name) > newest:
                continue  # still being written: the next poll takes it
            m = _model_dir(d)
            if m is not None and (m / "model.safetensors").is_file():
                found.append(Checkpoint(int(d.name), m))
        if not found and must_exist:
            raise ConfigError(f"{roots[0]}/checkpoints holds no <step>/pretrained_model with a config.json yet; "
                              "train first, or pass --follow to wait for the first")  # fmt: skip
        return sorted(found, key=lambda c: c.step)
    out = []
    for i, r in enumerate(roots):
        m = _model_dir(r)
        if m is None:
            raise ConfigError(f"{r} holds no config.json (nor pretrained_model/config.json); point at a LeRobot "
                              "checkpoint directory or a training output with a checkpoints/ folder")  # fmt: skip
        out.append(Checkpoint(_step_of(r, i), m))
    steps = [c.step for c in out]
    if len(set(steps)) != len(steps):
        raise ConfigError(f"two checkpoint directories name the same step ({steps}); name them by step, e.g. "
                          "step_1000, step_2000, or list them in training order without step numbers")  # fmt: skip
    return sorted(out, key=lambda c: c.step)


def protocol_of(cfg: EvalConfig) -> dict:
    """The series' protocol: evaluate's config without what changes per checkpoint."""
    return {k: v for k, v in cfg.flat().items() if k not in OWN_FIELDS}


def check_protocol(out: Path, protocol: dict) -> None:
    """Record the protocol on the first run; refuse a re-run whose protocol differs, naming the first field, once a
    checkpoint's run exists (before that, a corrected command after a failed one records its own)."""
    path = out / PROTOCOL
    if not path.exists() or not any((out / "runs").glob(f"*/{MANIFEST}")):
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(path, protocol)
        return
    was = json.loads(path.read_text())
    now = json.loads(json.dumps(protocol, default=str))  # tuples as lists, as stored
    diff = sorted(k for k in set(was) | set(now) if was.get(k) != now.get(k))
    if diff:
        k = diff[0]
        raise ConfigError(f"{out} is a series run with {k}={was.get(k)!r}, now {now.get(k)!r}; re-run it with the "
                          "same flags, or give a new --out")  # fmt: skip


def run_dir(out: Path, c: Checkpoint) -> Path:
    return out / "runs" / f"{c.step:09d}"


def finished(run: Path) -> bool:
    """A run every planned episode of which finished ok (summary written): a re-run skips it."""
    if not (run / "summary.json").is_file():
        return False
    r = RunDir.open(run)
    plan = r.manifest.get("plan") or {}
    if plan.get(
        "adaptive"
    ):  # the adaptive rule decided it: evaluate's own resume says whether more is needed
        return False
    jobs = r.manifest.get("resolved", {}).get("episodes")
    ok = r.episodes().query("status == 'ok'")
    return jobs is not None and len(ok) >= int(jobs)


def run_series(
    cfg: SeriesConfig, family: Scene, *, evaluate: Callable | None = None, say: Callable[[str], None] = print,
    after_each: Callable[[list[tuple[int, Path]]], None] | None = None,
) -> list[tuple[int, Path]]:  # fmt: skip
    """Evaluate every checkpoint of ``cfg.roots`` under ``cfg.protocol`` into ``cfg.out/runs/<step>``, skipping
    finished runs; with ``cfg.follow``, poll every ``cfg.poll`` seconds for new checkpoints until none came for
    ``cfg.idle_stop``. Returns the (step, run directory) of every checkpoint evaluated, in step order; ``after_each``
    gets them after each run (the series report is rewritten there); ``family``: the protocol's scene family (looked up
    by the API); ``evaluate``: the engine's by default."""
    evaluate = evaluate or run_evaluation
    base, roots, follow, poll_s, idle_stop_s = cfg.protocol, cfg.roots, cfg.follow, cfg.poll, cfg.idle_stop
    out = Path(cfg.out)
    check_protocol(out, protocol_of(base))
    done: dict[int, Path] = {}
    last_new = time.monotonic()
    while True:
        todo = [c for c in find_checkpoints(roots, must_exist=not follow) if c.step not in done]
        skipped = [c for c in todo if finished(run_dir(out, c))]
        if skipped:
            say(f"series: {len(skipped)} checkpoint(s) already evaluated in {out / 'runs'} (steps "
                f"{', '.join(str(c.step) for c in skipped)}): skipped")  # fmt: skip
        for c in skipped:
            done[c.step] = run_dir(out, c)
        for c in todo:
            if c.step in done:
                continue
            say(f"series: step {c.step}: evaluating {c.path}")
            cfg = base.override(policy=f"lerobot:{c.path}", out=str(run_dir(out, c)))
            done[c.step] = evaluate(cfg, family)
            last_new = time.monotonic()
            if after_each is not None:
                after_each(sorted(done.items()))
        if not follow or time.monotonic() - last_new >= idle_stop_s:
            break
        time.sleep(poll_s)
    if not done:
        raise ConfigError(f"no checkpoint found in {', '.join(map(str, roots))}")
    return sorted(done.items())
