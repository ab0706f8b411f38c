"""Many certificates at once: every level job of several (task, axis) pairs in one pool of worker processes.

``indgen certify --task all`` certifies one task after another, each with at most one process per level; a
protocol of 10 tasks x 3 axes x 7 levels keeps 16 cores busy only when all 210 level jobs share one pool. Each
finished level is merged into its own certify.json at once (``indgen_vla.app.certify.certify_levels.Pending``), so a killed batch resumes
like ``certify`` does, mid-level included (``indgen_vla.app.certify.partial``).
"""

from __future__ import annotations

import dataclasses
import multiprocessing as mp
import time
from pathlib import Path
from typing import TYPE_CHECKING

from indgen_vla.app.certify.certify_config import CertifyPlan, CertifyRule
from indgen_vla.app.certify.certify_levels import LevelJob, _certify_job, level_line, prepare
from indgen_vla.app.certify.suite import write_summary
from indgen_vla.core.errors import ConfigError
from scenes.certificates import cert_path

if TYPE_CHECKING:
    from scenes.family import Scene


def _job(item: tuple[int, LevelJob]) -> tuple[int, dict]:
    index, job = item
    return index, _certify_job(job)


def certify_many(
    scene: Scene, pairs: list[tuple[str, str]], plan: CertifyPlan, rule: CertifyRule, *, workers: int = 1,
    root: str | Path | None = None, deadline_s: float | None = None, log=print,
) -> list[dict]:  # fmt: skip
    """Certify (or resume) ``plan``'s levels of every (task, axis) in ``pairs`` of ``scene`` under ``root`` (default:
    where evaluate looks, ``scenes.certificates.cert_path``) and ``rule`` (its ``seed``: the first seed block; its
    ``held_out``: re-run the levels certified only in-sample on a fresh block, ``scenes.heldout``); with
    ``deadline_s`` no new level starts after that many seconds (those running finish), so a time-boxed chunk ends
    with whole levels. Returns the certificates as they stand."""
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    pend = [
        prepare(
            scene,
            dataclasses.replace(plan, task=task, axes=(axis,)),
            rule,
            cert_path(scene, task, axis, root=root),
            log=log,
        )  # fmt: skip
        for task, axis in pairs
    ]
    # pair-major: a chunk cut short leaves whole certificates (every level of a pair) rather than scattered levels
    items = [(i, j) for i, p in enumerate(pend) for j in p.jobs]
    t0, nxt = time.time(), 0

    def merge(index: int, row: dict) -> None:
        p = pend[index]
        p.log = None  # one line here instead
        p.merge(row)
        if log:
            log(level_line(scene.name, p.cert["task"], p.cert["axis"], row))

    if workers == 1:
        while nxt < len(items) and (deadline_s is None or time.time() - t0 < deadline_s):
            nxt += 1
            merge(*_job(items[nxt - 1]))
    else:
        ctx = mp.get_context("spawn")
        with ctx.Pool(workers, maxtasksperchild=4) as pool:
            waiting = [pool.apply_async(_job, (item,)) for item in items[:workers]]
            nxt = len(waiting)
            while waiting:
                time.sleep(0.2)
                for w in [w for w in waiting if w.ready()]:
                    waiting.remove(w)
                    merge(*w.get())
                    if nxt < len(items) and (deadline_s is None or time.time() - t0 < deadline_s):
                        waiting.append(pool.apply_async(_job, (items[nxt],)))
                        nxt += 1
    if log and nxt < len(items):
        log(f"deadline: {len(items) - nxt} level jobs not started (run again to go on)")
    if root is not None:
        write_summary(root)
    return [p.result() for p in pend]
