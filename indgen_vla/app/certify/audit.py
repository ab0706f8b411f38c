"""``indgen certify --audit N``: re-run N shipped certified levels, drawn at random, on fresh held-out seeds, and say
whether each still holds, so a user can check the shipped certificates on their own machine and assets.

A level's audit runs ``episodes`` oracle episodes (no early stop) from seed block ``AUDIT_FIRST_BLOCK`` on (blocks
that no certification attempt draws, and never one its ledger used), exactly as ``certify`` runs them. It *holds*
unless the exact one-sided binomial test of "oracle rate >= 0.95" rejects at 5 %: with 20 episodes, 17/20 or more
holds (P(X <= 16 | 20, 0.95) = 0.016); a truly 0.95-feasible level is reported broken with probability <= 5 %.
A LIBERO level is audited only on the asset tree its certificate covers (``scenes.certificates``).
"""

from __future__ import annotations

import datetime as _dt
import json
import multiprocessing as mp
import os
import platform
import random
import time
from pathlib import Path
from typing import TYPE_CHECKING

from scipy.stats import binom

from indgen_vla.app.certify.certify_config import CertifyConfig
from indgen_vla.app.certify.certify_levels import run_oracle_episode
from indgen_vla.core.errors import ConfigError, EpisodeUnavailableError
from indgen_vla.core.protocol.seeding import episode_seed
from indgen_vla.core.resources import certification_dir
from scenes.certificates import level_status, load_certification, shipped_certification
from scenes.heldout import basis, burnt_blocks, next_block
from scenes.oracles import oracle_for
from scenes.planning import resolve_scene_plan

if TYPE_CHECKING:
    from collections.abc import Sequence

    from scenes.family import Scene

AUDIT_FIRST_BLOCK = 1000  # audits draw from here: certification attempts (blocks 1, 2, ...) never meet them
AUDIT_ALPHA = 0.05


def holds(successes: int, n: int, threshold: float = 0.95, alpha: float = AUDIT_ALPHA) -> tuple[bool, float]:
    """(does the audit keep the certificate, the one-sided p-value of "rate >= threshold" given successes/n)."""
    p = float(binom.cdf(successes, n, threshold)) if n else 1.0
    return p >= alpha, p


def shipped_levels(
    root: Path, scenes: list[str] | None = None
) -> list[tuple[str, str, str, int, dict, dict]]:
    """Every certified (scene, task, axis, level, row, cert) under ``root`` at default steps, sorted."""
    out = []
    for path in sorted(Path(root).glob("*/*/*/certify.json")):
        if "@" in path.parent.name:
            continue  # made at other steps: an audit runs the default levels
        cert = load_certification(path)
        if scenes and cert["scene"] not in scenes:
            continue
        for row in cert["levels"]:
            if level_status(row) == "certified":
                out.append((cert["scene"], cert["task"], cert["axis"], int(row["level"]), row, cert))
    return out


def audit_level(family: Scene, task: str, axis: str, level: int, block: int, episodes: int,
                max_steps: int | None) -> dict:  # fmt: skip
    """``episodes`` oracle episodes of one level on ``block`` (unavailable seeds skipped and counted, as certify
    does), in this process."""
    t0, scene = time.time(), family.name
    plan = resolve_scene_plan(family, task, (axis,), [level], certificates=False)
    env = plan.builder.make_env(task, axis, level, cameras=(), image_size=(128, 128), max_steps=max_steps)
    results, unavailable, i = [], 0, 0
    try:
        policy = oracle_for(plan.builder.family)
        while len(results) < episodes and unavailable <= episodes:
            try:
                results.append(
                    run_oracle_episode(env, policy, episode_seed(block, scene, task, axis, level, i), i)
                )
            except EpisodeUnavailableError:
                unavailable += 1
            i += 1
    finally:
        env.close()
    n, s = len(results), sum(ok for ok, _ in results)
    ok, p = holds(s, n)
    return {"scene": scene, "task": task, "axis": axis, "level": level, "block": block, "n": n, "successes": s,
            "unavailable": unavailable, "holds": ok, "p_value": round(p, 6),
            "failed_episodes": [j for j, (good, _) in enumerate(results) if not good],
            "wall_s": round(time.time() - t0, 1)}  # fmt: skip


def _job(args: tuple) -> dict:
    return audit_level(*args)


def audit(
    config: CertifyConfig, scenes: Sequence[Scene], *, root: str | Path | None = None, out: str | Path | None = None,
    log=print,
) -> dict:  # fmt: skip
    """Audit ``config``'s ``--audit`` N certified levels drawn at random (its ``seed``) from the shipped certificates
    under ``root`` (default: the package's) of ``scenes`` (resolved by the caller) that are ready here,
    ``config.audit_episodes`` episodes each; write ``out`` (audit.json) if given; return the result."""
    n, episodes, seed, workers = (
        config.check.audit,
        config.audit_episodes,
        config.rule.seed,
        config.run.workers,
    )
    if n is None:
        raise ConfigError("audit needs --audit N, the number of shipped certified levels to re-run")
    root = Path(root) if root is not None else certification_dir()
    by_name = {s.name: s for s in scenes}
    pool, skipped = [], set()
    for item in shipped_levels(root, list(by_name)):
        sc, _task, _axis, _level, _row, cert = item
        try:
            scene = by_name[sc]
            scene.environment.check_ready()  # e.g. LIBERO without its assets
            ok = (
                scene.committed_certificates
                or shipped_certification(scene, _cert_file(root, cert)) is not None
            )
        except Exception as e:  # a scene this machine cannot run: say so once
            ok = False
            if sc not in skipped and log:
                log(f"audit: {sc} left out ({type(e).__name__}: {e})")
        if not ok:
            skipped.add(sc)
            continue
        pool.append(item)
    if not pool:
        names = config.audit_scenes
        raise ConfigError(f"no shipped certified level under {root} can run here"
                          + (f" for scenes {names}" if names else "") + "; install the scene's assets")  # fmt: skip
    drawn = random.Random(seed).sample(pool, min(n, len(pool)))
    jobs = []
    for sc, task, axis, level, row, cert in drawn:
        block = next_block(row, burnt_blocks(cert, level), AUDIT_FIRST_BLOCK)
        jobs.append((by_name[sc], task, axis, level, block, episodes, cert.get("max_steps")))
    rows = _run(jobs, workers)
    for (_sc, _t, _a, _l, row, _c), r in zip(drawn, rows, strict=True):
        r["basis"] = basis(row)
        if log:
            log(f"audit {r['scene']}/{r['task']}/{r['axis']} level {r['level']} ({r['basis']}): {r['successes']}/"
                f"{r['n']} on block {r['block']} -> {'holds' if r['holds'] else 'DOES NOT HOLD'} "
                f"(p = {r['p_value']:.3g})")  # fmt: skip
    result = {"date": _dt.date.today().isoformat(), "machine": f"{os.cpu_count()} cores, {platform.machine()}, Python {platform.python_version()}",
              "seed": seed, "episodes": episodes, "alpha": AUDIT_ALPHA, "levels": rows}  # fmt: skip
    if out is not None:
        Path(out).parent.mkdir(parents=True, exist_ok=True)
        Path(out).write_text(json.dumps(result, indent=2) + "\n")
    return result


def _cert_file(root: Path, cert: dict) -> Path:
    return root / cert["scene"] / cert["task"] / cert["axis"] / "certify.json"


def _run(jobs: list[tuple], workers: int) -> list[dict]:
    """The jobs' rows in order, one level per process when ``workers`` > 1."""
    if workers == 1 or len(jobs) == 1:
        return [_job(j) for j in jobs]
    with mp.get_context("spawn").Pool(min(workers, len(jobs))) as pool:
        return pool.map(_job, jobs, chunksize=1)
