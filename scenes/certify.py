"""``indgen certify``: run the privileged oracle on every level of an axis and record which levels are feasible.

A level is feasible (the paper's Assumption 2) when the oracle solves at least 95 % of its episodes.
Certification runs physics only (no cameras), one process per worker, and is deterministic: episode i
of level k always gets ``episode_seed(seed, scene, task, axis, level, i)``.
"""

from __future__ import annotations

import dataclasses
import json
import time
from pathlib import Path

from indgen_vla.errors import ConfigError, RunDirError
from indgen_vla.progression import parse_levels
from indgen_vla.seeding import episode_seed

FEASIBLE_RATE = 0.95


def run_oracle_episode(env, policy, seed: int, episode: int | None = None) -> tuple[bool, int]:
    """One oracle episode, passing privileged state the way the engine does; returns (success, steps)."""
    obs, _ = env.reset(seed=seed, options=None if episode is None else {"episode": episode})
    policy.reset(env.instruction, seed)
    info = {"success": False}
    for _ in range(env.max_steps):
        obs = dataclasses.replace(obs, extras={**obs.extras, "privileged": env.privileged_state()})
        action = policy.act([obs])[0, 0]
        obs, _, terminated, truncated, info = env.step(action)
        if terminated or truncated:
            break
    return bool(info["success"]), env.steps


def certify_level(
    scene: str,
    task: str,
    axis: str,
    level: int,
    step: float | None,
    episodes: int,
    seed: int,
    max_steps: int | None,
) -> dict:
    """Run ``episodes`` oracle episodes of one level; returns its certification row."""
    import scenes
    from scenes.oracle import OraclePolicy

    env = scenes.make_env(
        scene, task=task, axis=axis, level=level, step=step, cameras=(), max_steps=max_steps
    )
    try:
        policy = OraclePolicy()
        results = [
            run_oracle_episode(env, policy, episode_seed(seed, scene, task, axis, level, i), i)
            for i in range(episodes)
        ]
        param = env.axis_param
    finally:
        env.close()
    successes = sum(ok for ok, _ in results)
    rate = successes / episodes
    return {
        "level": level,
        "param": param,
        "n": episodes,
        "successes": successes,
        "rate": rate,
        "feasible": rate >= FEASIBLE_RATE,
        "mean_steps": sum(s for _, s in results) / episodes,
    }


def _certify_job(args: tuple) -> dict:
    return certify_level(*args)


def certify(
    scene: str,
    axis: str,
    *,
    task: str | None = None,
    levels: str | list[int] | None = None,
    step: float | None = None,
    episodes: int = 20,
    seed: int = 0,
    max_steps: int | None = None,
    workers: int = 1,
) -> dict:
    """Certify every requested level of ``axis`` on ``scene`` with the oracle; returns the certify.json dict."""
    import scenes
    from scenes.catalog import check_axis_supported, get_scene, resolve_task

    sdef = get_scene(scene)
    task = resolve_task(sdef, task)
    check_axis_supported(sdef, axis)
    scenes.check_ready(scene)
    spec = scenes.get_axis(axis, step)
    lv = parse_levels(levels, spec)
    if episodes < 1:
        raise ConfigError(f"--episodes must be >= 1, got {episodes}")
    if workers < 1:
        raise ConfigError(f"--workers must be >= 1, got {workers}")
    jobs = [(scene, task, axis, k, step, episodes, seed, max_steps) for k in lv]
    t0 = time.time()
    if workers == 1 or len(jobs) == 1:
        rows = [_certify_job(j) for j in jobs]
    else:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(min(workers, len(jobs))) as pool:
            rows = pool.map(_certify_job, jobs, chunksize=1)
    return {
        "scene": scene,
        "task": task,
        "axis": axis,
        "step": spec.step,
        "unit": spec.unit,
        "episodes": episodes,
        "seed": seed,
        "threshold": FEASIBLE_RATE,
        "wall_s": round(time.time() - t0, 1),
        "levels": rows,
    }


def load_certification(path: str | Path) -> dict:
    """Read a certify.json (or the directory holding one) and check its shape."""
    p = Path(path)
    if p.is_dir():
        p = p / "certify.json"
    if not p.is_file():
        raise RunDirError(f"no certification at {p}; run 'indgen certify --scene S --axis A --out DIR' first")
    try:
        cert = json.loads(p.read_text())
    except json.JSONDecodeError as e:
        raise RunDirError(
            f"{p} is not valid JSON ({e.msg} at line {e.lineno}); re-run 'indgen certify'"
        ) from None
    if (
        not isinstance(cert, dict)
        or not {"scene", "axis", "levels"} <= cert.keys()
        or not isinstance(cert["levels"], list)
    ):
        raise RunDirError(f"{p} is not a certification (needs scene, axis, levels); re-run 'indgen certify'")
    for row in cert["levels"]:
        if not isinstance(row, dict) or not {"level", "n", "successes", "rate", "feasible"} <= row.keys():
            raise RunDirError(
                f"{p}: a level row lacks level/n/successes/rate/feasible; re-run 'indgen certify'"
            )
    return cert


def infeasible_levels(cert: dict) -> list[int]:
    """Levels the oracle solved in fewer than 95 % of episodes."""
    return sorted(int(r["level"]) for r in cert["levels"] if not r["feasible"])


def print_table(cert: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(
        title=f"certification: {cert['scene']}/{cert['task']} axis {cert['axis']} "
        f"(step {cert['step']:g} {cert['unit']}, oracle, threshold {cert['threshold']:.0%})"
    )
    for col in ("level", "param", "successes", "rate", "feasible"):
        table.add_column(col, justify="right")
    for r in cert["levels"]:
        table.add_row(
            str(r["level"]),
            f"{r['param']:g}",
            f"{r['successes']}/{r['n']}",
            f"{r['rate']:.0%}",
            "yes" if r["feasible"] else "[red]NO[/red]",
        )
    Console().print(table)


def certify_main(args) -> int:
    """``indgen certify``: write OUT/certify.json and print the table; exit 1 if any level is infeasible."""
    out = Path(args.out)
    cert = certify(
        args.scene,
        args.axis,
        task=args.task,
        levels=args.levels,
        step=args.step,
        episodes=args.episodes,
        seed=args.seed,
        max_steps=args.max_steps,
        workers=args.workers or 1,
    )
    try:
        out.mkdir(parents=True, exist_ok=True)
        (out / "certify.json").write_text(json.dumps(cert, indent=2) + "\n")
    except OSError as e:
        raise RunDirError(f"cannot write {out / 'certify.json'}: {e.strerror}") from None
    print_table(cert)
    bad = infeasible_levels(cert)
    if bad:
        print(f"infeasible levels (oracle < {FEASIBLE_RATE:.0%}): {bad}")
        return 1
    return 0


def certify_all(out_dir: str | Path, episodes: int = 20, workers: int = 1, seed: int = 0) -> list[dict]:
    """Certify every default level of every default axis of every scene; write one folder per (scene, axis)."""
    from scenes.catalog import SCENES

    out_dir = Path(out_dir)
    certs = []
    for sdef in SCENES.values():
        for axis in sdef.axes:
            cert = certify(sdef.name, axis, episodes=episodes, seed=seed, workers=workers)
            d = out_dir / sdef.name / axis
            d.mkdir(parents=True, exist_ok=True)
            (d / "certify.json").write_text(json.dumps(cert, indent=2) + "\n")
            print_table(cert)
            certs.append(cert)
    return certs


def write_summary(out_dir: str | Path) -> Path:
    """Collect every ``<scene>/<axis>/certify.json`` under ``out_dir`` into one markdown table (README.md)."""
    out_dir = Path(out_dir)
    lines = ["| scene / task | axis | step | level: successes/n | feasible |", "|---|---|---|---|---|"]
    for path in sorted(out_dir.glob("*/*/certify.json")):
        c = load_certification(path)
        cells = " ".join(f"{r['level']}: {r['successes']}/{r['n']}" for r in c["levels"])
        bad = infeasible_levels(c)
        lines.append(
            f"| {c['scene']} / {c.get('task', '?')} | {c['axis']} | {c.get('step', 0):g} {c.get('unit', '')} | "
            f"{cells} | {'all' if not bad else 'NOT ' + ', '.join(map(str, bad))} |"
        )
    target = out_dir / "SUMMARY.md"
    target.write_text("\n".join(lines) + "\n")
    return target


def certification_root() -> Path:
    """Where committed certifications live: $INDGEN_CERT_DIR, else the repository's docs/certification."""
    import os

    env = os.environ.get("INDGEN_CERT_DIR")
    return Path(env) if env else Path(__file__).resolve().parent.parent / "docs" / "certification"


def find_certification(
    scene: str, axis: str, step: float | None = None, root: str | Path | None = None
) -> dict | None:
    """The committed certification of (scene, axis) made at this step size, or None if there is none."""
    import scenes

    path = Path(root) if root is not None else certification_root()
    path = path / scene / axis / "certify.json"
    if not path.is_file():
        return None
    cert = load_certification(path)
    want = scenes.get_axis(axis, step).step
    if abs(float(cert.get("step", float("nan"))) - want) > 1e-9:
        return None
    return cert
