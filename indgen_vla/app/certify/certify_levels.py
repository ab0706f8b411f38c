"""Certificates of an axis's levels (``indgen certify``): the privileged oracle's episodes of each level
(``certify_level``), the certificate being made and resumed (``prepare``, ``Pending``) and the command's driver
(``certify``) over a scene resolved by the caller and a ``CertifyConfig``.

A level is certified (the paper's Assumption 2, stated statistically) when the one-sided 95 %
Clopper–Pearson lower bound of the oracle's success rate is >= the threshold (0.95: 59/59 episodes).
Episodes run one after another up to ``n_max`` and stop as soon as a failure makes certification
unreachable even if every remaining episode succeeded (scenes/certification/README.md). Certification is
per (scene, task, axis, component steps), physics only, resumable, and deterministic: episode i of level
k's attempt on seed block b gets ``episode_seed(b, scene, task, axis, level, i)``. Each attempt draws a block the
level never used and spends its share of the error (``scenes.heldout``), so retrying never certifies by luck.
"""

from __future__ import annotations

import dataclasses
import json
import multiprocessing as mp
import queue
import time
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path
from typing import TYPE_CHECKING

from indgen_vla.app.certify.certify_config import CertifyConfig, CertifyPlan, CertifyRule
from indgen_vla.app.certify.partial import EpisodeLog, partial_path
from indgen_vla.core.errors import ConfigError, EpisodeUnavailableError, RunDirError
from indgen_vla.core.protocol.seeding import episode_seed
from scenes.axes import successor_steps
from scenes.certificates import (
    THRESHOLD,
    Rule,
    asset_stamp,
    load_certification,
    lower_bound,
    row_oracle_version,
    same_assets,
    stale_failure,
    write_json_atomic,
)
from scenes.heldout import (
    ALPHA,
    HELD_OUT,
    IN_SAMPLE,
    RULE,
    SPENDING,
    attempt_alpha,
    attempt_confidence,
    basis,
    burn_block,
    burnt_blocks,
    fixed_states_basis,
    ledger,
    next_block,
    spent_attempts,
)
from scenes.oracles import oracle_for, oracle_identity, oracle_scripts
from scenes.planning import resolve_scene_plan
from scenes.privileged import with_privileged

if TYPE_CHECKING:
    from indgen_vla.core.protocol.plan import LevelBuilder
    from scenes.family import Scene


class NoOracleError(ConfigError):
    """The scene's oracle has no script for the task: its levels cannot be certified, only reported uncertified."""


def run_oracle_episode(env, policy, seed: int, episode: int | None = None) -> tuple[bool, int]:
    """One oracle episode, passing privileged state the way the engine does; returns (success, steps)."""
    obs, _ = env.reset(seed=seed, options=None if episode is None else {"episode": episode})
    policy.reset(env.instruction, seed)
    info = {"success": False}
    for _ in range(env.max_steps):
        obs = with_privileged(obs, env)
        action = policy.act([obs])[0, 0]
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    return bool(info["success"]), env.steps


def level_row(
    level: int, param: float, results: list[tuple[bool, int]], rule: Rule, wall_s: float, unavailable: int = 0,
    oracle_version: int | None = None, infeasible: str = "",
) -> dict:  # fmt: skip
    """The certification row of one level from its episodes' (success, steps); ``unavailable``: the seeds skipped
    because their initial state cannot hold the level (a key only when some were); ``oracle_version``: the oracle
    that ran them (``scenes.oracles.oracle_identity``; a failure by another version is re-tried); ``infeasible``: why
    too few seeds hold the level to certify it (the level is then ``failed`` whatever its episodes gave)."""
    n, successes = len(results), sum(ok for ok, _ in results)
    status = "failed" if infeasible else rule.status(successes, n)
    return {
        "level": level, "param": param, "n": n, "successes": successes, "rate": successes / n if n else 0.0,
        "lower_bound": round(lower_bound(successes, n, rule.confidence), 6), "status": status,
        "certified": status == "certified", "feasible": status == "certified",
        "stopped_early": n < rule.n_max, "mean_steps": sum(s for _, s in results) / n if n else 0.0,
        "wall_s": round(wall_s, 1), **({"unavailable": unavailable} if unavailable else {}),
        **({"infeasible": infeasible} if infeasible else {}),
        **({} if oracle_version is None else {"oracle_version": int(oracle_version)}),
    }  # fmt: skip


@dataclasses.dataclass(frozen=True)
class LevelJob:
    """One attempt at one level (``prepare`` lists them): the plan's ``builder`` builds its env as ``evaluate`` builds
    it, episode i on seed block ``block``; ``partial``/``key``: the episode file a killed run left under the same key
    (``indgen_vla.app.certify.partial``). Picklable: it travels to pool workers."""

    builder: LevelBuilder
    task: str
    axis: str
    level: int
    block: int
    max_steps: int | None
    rule: Rule
    partial: Path | None = None
    key: str = ""


def certify_level(job: LevelJob, on_episode=None) -> dict:
    """Run oracle episodes of one level under ``job.rule`` (sequentially, stopping early on futility);
    ``on_episode(level, successes, n)`` hears of each finished episode. A seed whose initial state cannot hold the
    level (``EpisodeUnavailableError``: a RoboCasa kitchen too narrow for pick_x, a LIBERO state that throws its moved
    object) is skipped and counted; more such seeds than the rule's ``n_max`` make the level ``failed``, with the
    reason in its row's ``infeasible``. The episodes a killed run finished under the same key are reused."""
    t0 = time.time()
    scene, task, axis, level, rule = job.builder.scene, job.task, job.axis, job.level, job.rule
    log = EpisodeLog(job.partial, job.key)
    results, infeasible = log.results, ""
    env = job.builder.make_env(task, axis, level, cameras=(), image_size=(128, 128), max_steps=job.max_steps)
    try:
        policy = oracle_for(job.builder.family)  # the family's own (RoboCasa: PandaOmron's 12-d arm script)
        while not infeasible and not rule.stop(sum(ok for ok, _ in results), len(results)):
            i = len(results) + log.unavailable
            try:
                log.add(
                    *run_oracle_episode(env, policy, episode_seed(job.block, scene, task, axis, level, i), i)
                )
            except EpisodeUnavailableError as e:
                log.add(None)
                if log.unavailable > rule.n_max:
                    infeasible = f"{log.unavailable} of {i + 1} seeds cannot hold this level, e.g. {e}"
                continue
            if on_episode is not None:
                on_episode(level, sum(ok for ok, _ in results), len(results))
        param = env.axis_param
    finally:
        env.close()
    return level_row(
        level,
        param,
        results,
        rule,
        time.time() - t0,
        log.unavailable,
        oracle_identity(job.builder.family)["version"],
        infeasible,
    )


_EVENTS = None  # in a pool worker: the queue its episodes are reported on (``_init_worker``)


def _init_worker(events) -> None:
    global _EVENTS
    _EVENTS = events


def _certify_job(job: LevelJob, report=None) -> dict:
    """One level job of ``prepare`` (in a pool worker, its episodes are reported on the worker's queue)."""
    if report is None and _EVENTS is not None:
        report = lambda *event: _EVENTS.put(event)  # noqa: E731
    return certify_level(job, on_episode=report)


def level_line(scene: str, task: str, axis: str, row: dict) -> str:
    """One finished level, e.g. ``stack/orange_on_blue/stack level 0: 59/59 CP95 lower 0.951 -> certified (oracle
    v1, 80 s)``."""
    made = f"oracle v{row['oracle_version']}, " if "oracle_version" in row else ""
    why = f"; infeasible: {row['infeasible']}" if row.get("infeasible") else ""
    return (f"{scene}/{task}/{axis} level {row['level']}: {row['successes']}/{row['n']} "
            f"CP95 lower {row['lower_bound']:.3f} -> {row['status']} ({made}{row['wall_s']:.0f} s){why}")  # fmt: skip


def _key(cert: dict) -> tuple:
    """What must match for a stored level to be reused: component steps, the rule's threshold and the episode
    length (each attempt's block and confidence are its row's own, ``scenes.heldout``)."""
    return (
        json.dumps(cert.get("steps"), sort_keys=True), float(cert.get("threshold", THRESHOLD)),
        cert.get("max_steps"),
    )  # fmt: skip


@dataclasses.dataclass
class Pending:
    """One certificate being made (``prepare``): its scene, its dict, its file, the requested levels and their level
    jobs; ``merge`` takes each finished level's row (written at once, its partial episode file then removed)."""

    scene: Scene
    cert: dict
    path: Path | None
    levels: list[int]
    jobs: list[LevelJob]
    log: object = None
    watch: object = None
    # level -> (earlier attempts, this attempt's header): the ledger each finished row carries (``scenes.heldout``)
    attempts: dict = dataclasses.field(default_factory=dict)

    def merge(self, row: dict) -> None:
        cert = self.cert
        if int(row["level"]) in self.attempts:
            row = with_attempt(row, *self.attempts[int(row["level"])])
            states = self.scene.fixed_state_count
            if states:  # LIBERO: blocks repeat its fixed states; a full pass is exhaustive (scenes.heldout)
                row = fixed_states_basis(row, states)
        rows = {int(r["level"]): r for r in cert["levels"]}
        rows[int(row["level"])] = row
        cert["levels"] = [rows[k] for k in sorted(rows)]
        cert["wall_s"] = round(cert["wall_s"] + row.get("wall_s", 0.0), 1)
        if self.path is not None:
            write_json_atomic(self.path, cert)
            partial_path(self.path, int(row["level"])).unlink(missing_ok=True)
        if self.watch is not None:
            self.watch.level(row)
        elif self.log:
            self.log(level_line(cert["scene"], cert["task"], cert["axis"], row))

    def result(self) -> dict:
        out = dict(self.cert)
        out["levels"] = [r for r in self.cert["levels"] if int(r["level"]) in self.levels]
        return out


def builtin_assets() -> dict:
    """What a built-in scene's certificate records of its asset tree: robosuite's own models, at its version."""
    try:
        v = version("robosuite")
    except PackageNotFoundError:
        v = "unknown"
    return {"tree": "robosuite's bundled models (built-in scene)", "robosuite": v}


def with_attempt(row: dict, earlier: list[dict], attempt: dict) -> dict:
    """``row`` with its seed block, its attempts (the earlier ones and this one, with its outcome) and, when
    certified, ``certified_on``: held-out when this attempt drew a block nothing had used and spent its share of
    the error (``scenes.heldout``)."""
    done = {**attempt, "n": row["n"], "successes": row["successes"], "status": row["status"]}
    out = {**row, "block": attempt["block"], "attempts": [*earlier, done]}
    out.pop("certified_on", None)
    if row["status"] == "certified":
        out["certified_on"] = HELD_OUT if attempt["held_out"] and attempt["alpha"] > 0 else IN_SAMPLE
    return out


def certify(
    scene: Scene, config: CertifyConfig, path: str | Path | None = None, *, log=None, watch=None
) -> dict:
    """Certify the requested levels of ``config``'s axis for one task of ``scene`` (the family as the caller
    resolved it, with its options); with ``path`` (a certify.json) reuse the levels already decided there under the
    same steps/rule (with ``--held-out``, re-run on a fresh block the levels certified only in-sample), and the
    finished episodes of a level a killed run left half done, and write after every level. ``log`` gets a line per
    event; ``watch`` (``indgen_vla.app.certify.display.CertifyDisplay``), when given, hears of the levels about to
    run, each episode and each finished level instead of the per-level lines."""
    p = prepare(scene, config.plan, config.rule, path, log=log, watch=watch)
    workers = config.run.workers
    if workers == 1 or len(p.jobs) <= 1:
        for j in p.jobs:
            p.merge(_certify_job(j, None if watch is None else watch.episode))
    else:
        _run_pool(p.jobs, min(workers, len(p.jobs)), p.merge, watch)
    return p.result()


def prepare(
    scene: Scene,
    plan: CertifyPlan,
    rule: CertifyRule,
    path: str | Path | None = None,
    *,
    log=None,
    watch=None,
) -> Pending:
    """Check the request (resolved as ``evaluate`` resolves it: ``scenes.planning.resolve_scene_plan``), read what
    ``path`` already holds, and list the level jobs still to run."""
    task = scene.resolve_task(plan.task)
    ref = plan.axis
    if ref is None:
        raise ConfigError("indgen certify needs --axis, e.g. --axis pick_y")
    scene.check_axis(ref)
    name, axis = scene.name, ref.name
    if not oracle_scripts(scene, task):
        raise NoOracleError(
            f"{name}/{task}: standin:oracle has no script for this task, so its levels stay uncertified "
            "(evaluate warns); certify a task the oracle scripts"
        )
    first = Rule(threshold=rule.threshold, confidence=attempt_confidence(1), n_max=rule.episodes or 0)
    # the family's (and task's) own steps, the levels' range and condition 2, before any episode runs
    resolved = resolve_scene_plan(
        scene, task, (ref,), plan.levels, plan.step, plan.axes_preset, certificates=False
    )
    resolved.builder.check_ready()
    successor = resolved.builder.successor(task, axis)
    spec, lv = successor.axis, list(resolved.levels[axis])
    cert = {
        "scene": name, "task": task, "axis": axis, "step": spec.step, "unit": spec.unit,
        "steps": successor_steps(successor), "seed": rule.seed, "max_steps": plan.max_steps,
        "rule": {**first.as_dict(), "name": RULE, "alpha": ALPHA, "spending": SPENDING},
        "episodes": first.n_max, "threshold": first.threshold, "wall_s": 0.0, "levels": [],
        "oracle": oracle_identity(scene),
    }  # fmt: skip
    version = cert["oracle"]["version"]
    stamp = asset_stamp(scene)
    cert["assets"] = stamp if stamp is not None else builtin_assets()
    path = Path(path) if path is not None else None
    done, old_rows = _reuse(cert, path, stamp, first.n_max, rule.held_out, log)
    todo = [k for k in lv if k not in done]
    if log and set(done) & set(lv):
        log(f"{name}/{task}/{axis}: reusing levels {sorted(set(done) & set(lv))} from {path}")
    if watch is not None:
        watch.start(todo, [r for r in cert["levels"] if int(r["level"]) in set(lv) - set(todo)], first.n_max)
    jobs, attempts = [], {}
    for k in todo:  # each attempt on its own never-used block, at its own share of the error (scenes.heldout)
        row = old_rows.get(k)
        part = None if path is None else partial_path(path, k)
        j = spent_attempts(row) + 1
        level_rule = Rule(
            threshold=rule.threshold, confidence=attempt_confidence(j), n_max=rule.episodes or 0
        )
        needed = Rule(threshold=rule.threshold, confidence=attempt_confidence(j)).n_max
        head = [*_key(cert), task, (stamp or {}).get("stat_sha256"), version]
        block = next_block(row, burnt_blocks(cert, k), rule.seed)
        if _burn_stale_partial(cert, k, part, json.dumps([*head, block, level_rule.n_max])):
            block = next_block(row, burnt_blocks(cert, k), rule.seed)
        key = json.dumps([*head, block, level_rule.n_max])  # a killed attempt resumes on its own block
        attempts[k] = (list((row or {}).get("attempts", ())), {
            "attempt": j, "block": block, "held_out": True, "alpha": attempt_alpha(j) if level_rule.n_max >= needed
            else 0.0, "confidence": level_rule.confidence, "n_max": level_rule.n_max, "oracle": cert["oracle"],
        })  # fmt: skip
        jobs.append(LevelJob(resolved.builder, task, axis, k, block, plan.max_steps, level_rule, part, key))
        if log and j > 1:
            log(f"{name}/{task}/{axis} level {k}: held-out attempt {j} on seed block {block} (confidence "
                f"{level_rule.confidence:.5f}: {needed}/{needed} certifies)")  # fmt: skip
    return Pending(scene, cert, path, lv, jobs, log, watch, attempts)


def _reuse(
    cert: dict, path: Path | None, stamp: dict | None, n_max: int, held_out: bool, log
) -> tuple[dict, dict]:
    """What ``path`` already holds for ``cert`` (its rows, ledgers and burnt blocks copied into ``cert``): the levels
    decided there that need no new attempt, and every stored row by level."""
    done: dict[int, dict] = {}
    old_rows: dict[int, dict] = {}
    if path is None or not path.is_file():
        return done, old_rows
    try:
        old = load_certification(path)
    except RunDirError:
        old = {}
    version = cert["oracle"]["version"]
    if old and not same_assets(old, stamp):
        if log:
            log(f"{path}: made on other asset files than {stamp['root']} holds now; certifying again")
    elif old and _key(old) == _key(cert) and old.get("task") == cert["task"]:
        # each row keeps the version that made it; a failure by another version is tried again
        rows = [{**r, "oracle_version": row_oracle_version(r, old), "attempts": ledger(r, old)}
                for r in old["levels"]]  # fmt: skip
        old_rows = {int(r["level"]): r for r in rows}
        cert["burnt"] = old.get("burnt") or {}
        done = {int(r["level"]): r for r in rows if not stale_failure(r, None, version)
                and (r.get("status") in ("certified", "failed") or r["n"] >= n_max)
                and not (held_out and r.get("status") == "certified" and basis(r) == IN_SAMPLE)}  # fmt: skip
        cert["wall_s"] = float(old.get("wall_s", 0.0))
        cert["levels"] = sorted(rows, key=lambda r: r["level"])
        retry = sorted(int(r["level"]) for r in rows if stale_failure(r, None, version))
        if retry and log:
            log(f"{cert['scene']}/{cert['task']}/{cert['axis']}: levels {retry} failed under an older oracle; "
                f"trying them again with oracle v{version} on held-out seed blocks")  # fmt: skip
    elif old and log:
        log(f"{path}: made under other steps/rule/episode length; replacing it")
    return done, old_rows


def _burn_stale_partial(cert: dict, level: int, part: Path | None, key: str) -> bool:
    """A killed attempt's episodes under another key (oracle, rule: not reused) were still looked at: burn their
    block so no attempt draws it again; True when it did."""
    if part is None or not part.is_file():
        return False
    try:
        old = json.loads(part.read_text().splitlines()[0])["key"]
        block = json.loads(old)[-2]
    except (ValueError, KeyError, IndexError, TypeError):
        return False
    if old == key or not isinstance(block, int):
        return False
    burn_block(cert, level, block, "a killed attempt's episodes (another oracle or rule) looked at it")
    return True


def _run_pool(jobs: list[LevelJob], workers: int, merge, watch) -> None:
    """One level per job in spawned processes; their episodes reach ``watch`` over a queue while they run."""
    ctx = mp.get_context("spawn")
    events = ctx.Queue() if watch is not None else None

    def drain() -> None:
        while events is not None:
            try:
                watch.episode(*events.get_nowait())
            except queue.Empty:
                return

    with ctx.Pool(workers, initializer=_init_worker, initargs=(events,)) as pool:
        rows = pool.imap_unordered(_certify_job, jobs, chunksize=1)
        for _ in jobs:
            while True:
                try:
                    row = rows.next(timeout=0.25)
                    break
                except mp.TimeoutError:
                    drain()
            drain()
            merge(row)
