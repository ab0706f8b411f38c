"""``indgen certify --evaluation-states --run DIR``: run the privileged oracle on the exact initial states a run's
episodes started from and record which it solved, so ``report`` can tell a policy's failure on a state the oracle
solves from a failure on a state it does not (possibly not solvable at all: a different finding).

The states are the run's own: each (task, axis, level, episode, seed) row of its ``episodes.parquet`` is reset
exactly as ``evaluate`` reset it (``env.reset(seed=seed, options={"episode": episode})``, the run's scene options,
steps and episode length) and the oracle plays it. ``DIR/oracle_states.json`` (``ORACLE_STATES``) holds one entry
per state, written after each level, so a killed run resumes; ``--episodes n`` keeps episodes 0..n-1.
"""

from __future__ import annotations

import datetime as _dt
import json
from pathlib import Path

from indgen_vla.app.certify.certify_levels import run_oracle_episode
from indgen_vla.core.errors import ConfigError, EpisodeUnavailableError
from indgen_vla.core.reporting.oracle_states import ORACLE_STATES
from indgen_vla.core.runs.records import RunDir, atomic_write_json
from scenes.family import Scene
from scenes.oracles import oracle_for, oracle_identity
from scenes.planning import resolve_scene_plan


def certify_evaluation_states(
    run_dir: str | Path, family: Scene, *, episodes: int | None = None, log=print
) -> dict:
    """Play the oracle on the initial states of the run at ``run_dir`` (episodes 0..``episodes``-1 of every
    planned cell) of ``family`` (the run's scene) and write ``oracle_states.json`` there; returns its content."""
    run = RunDir(run_dir)
    m = run.manifest
    df = run.episodes()
    if not len(df):
        raise ConfigError(f"{run_dir} has no episodes yet; run evaluate first")
    if episodes is not None and episodes < 1:
        raise ConfigError(f"--episodes must be >= 1, got {episodes}")
    plan, scene, config = m.get("plan") or {}, m["scene"], m.get("config") or {}
    if scene != family.name:
        raise ConfigError(f"{run_dir} is a run of scene {scene}, not {family.name}; pass its own scene")
    options = {k: config[k] for k in ("split", "obj_registries") if config.get(k) is not None}
    rows = df[df["shared_from"].fillna("") == ""] if "shared_from" in df else df  # a shared T0 is its owner's
    rows = rows[["task", "axis", "level", "episode", "seed"]].drop_duplicates()
    if episodes is not None:
        rows = rows[rows["episode"] < episodes]
    path = run.path / ORACLE_STATES
    have = json.loads(path.read_text()) if path.is_file() else {}
    ident = oracle_identity(family)
    if have and have.get("oracle", {}).get("code_hash") != ident["code_hash"]:
        if log:
            log(f"{path}: made by another oracle ({have.get('oracle')}); playing every state again")
        have = {}
    states = {(s["task"], s["axis"], int(s["level"]), int(s["episode"])): s for s in have.get("states", [])}
    out = {"scene": scene, "run_seed": m.get("seed"), "oracle": ident, "states": []}
    for (task, axis), group in rows.groupby(["task", "axis"], sort=True):
        levels = sorted({int(k) for k in group["level"]})
        sp = resolve_scene_plan(family, task, (axis,), levels, plan.get("step"), plan.get("axes_preset"),
                                certificates=False, options=options or None)  # fmt: skip
        for level in levels:
            todo = group[(group["level"] == level)].sort_values("episode")
            todo = [r for r in todo.itertuples() if (task, axis, level, int(r.episode)) not in states]
            if not todo:
                continue
            env = sp.builder.make_env(task, axis, level, cameras=(), image_size=(128, 128),
                                      max_steps=plan.get("max_steps"))  # fmt: skip
            try:
                policy = oracle_for(sp.builder.family)
                for r in todo:
                    try:
                        ok, steps = run_oracle_episode(env, policy, int(r.seed), int(r.episode))
                    except EpisodeUnavailableError:
                        ok, steps = None, 0
                    states[(task, axis, level, int(r.episode))] = {
                        "task": task, "axis": axis, "level": level, "episode": int(r.episode),
                        "seed": int(r.seed), "solved": ok, "steps": steps,
                    }  # fmt: skip
            finally:
                env.close()
            out["states"] = [states[k] for k in sorted(states)]
            out["made"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
            atomic_write_json(path, out)
            if log:
                done = [states[(task, axis, level, int(r.episode))]["solved"] for r in todo]
                log(f"{scene}/{task}/{axis} level {level}: the oracle solved {sum(d is True for d in done)} of "
                    f"{len(done)} evaluated states" + (f" ({sum(d is None for d in done)} unavailable)"
                                                       if None in done else ""))  # fmt: skip
    out["states"] = [states[k] for k in sorted(states)]
    return out
