"""The privileged oracle over LIBERO-Object's tasks x axes x levels on the installed asset tree, N episodes a cell.

Each episode gets ``episode_seed(seed, scene, task, axis, level, i)``, the seed ``indgen certify`` gives it, so a
sweep's episode i is certification's episode i; each row records the oracle's version (``oracle_version``). Rows go to a JSONL file as each cell finishes (a killed sweep
resumes at the first unfinished cell); ``--videos DIR`` writes an agentview MP4 of every failed episode.

    python scripts/sweep_libero_oracle.py --out sweep.jsonl --episodes 10 [--tasks cream_cheese] [--axes pick_y]
    python scripts/sweep_libero_oracle.py --out sweep.jsonl --table     # the markdown table of what is there
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import sys
import time
from collections import Counter
from pathlib import Path

from scenes.family import get_scene

SCENE = "libero_object"


def finger_partners(env) -> list[str]:
    """Names of the bodies a finger touches now (what the gripper landed on, for a failed episode's trace)."""
    import mujoco

    m, d = env._env.sim.model._model, env._env.sim.data._data
    g1, g2 = d.contact.geom1[: d.ncon], d.contact.geom2[: d.ncon]
    mask = env._finger_mask
    other = [b for a, b in zip(g1, g2, strict=True) if mask[a] and not mask[b]]
    other += [a for a, b in zip(g1, g2, strict=True) if mask[b] and not mask[a]]
    return sorted(
        {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g])) or "?" for g in other}
    )


def run_cell(job: tuple) -> dict:
    """Run ``episodes`` oracle episodes of one (task, axis, level); failures carry their failure mode."""
    task, axis, level, episodes, seed, videos = job
    import numpy as np

    from indgen_vla.core.protocol.seeding import episode_seed
    from scenes.oracles import oracle_for
    from scenes.planning import resolve_scene_plan
    from scenes.privileged import with_privileged

    t0 = time.time()
    try:
        plan = resolve_scene_plan(get_scene(SCENE), task, (axis,), [level])
        env = plan.builder.make_env(task, axis, level, cameras=(), image_size=(128, 128), max_steps=None)
    except Exception as e:  # a level LIBERO cannot build is a finding, not a crash of the sweep
        return {"task": task, "axis": axis, "level": level, "n": 0, "successes": 0, "episodes": [], "seed": seed,
                "error": f"{type(e).__name__}: {e}", "wall_s": round(time.time() - t0, 1)}  # fmt: skip
    policy = oracle_for(get_scene(SCENE))
    eps = []
    try:
        for i in range(episodes):
            s = episode_seed(seed, SCENE, task, axis, level, i)
            obs, _ = env.reset(seed=s, options={"episode": i})
            policy.reset(env.instruction, s)
            frames, trace, info = [], [], {"success": False}
            for t in range(env.max_steps):
                if videos:
                    frames.append(env.render_frame("agentview", (256, 256)))
                if t % 3 == 0:  # a coarse privileged trace, kept for the failed episodes
                    p = env.privileged_state()
                    trace.append([t, policy.phase, *np.round(p.eef_pos, 3).tolist(), *np.round(p.pick.pos, 3).tolist(),
                                  round(p.pick.bottom, 3), round(p.target.grasp_z, 3), int(p.pick.touching_gripper),
                                  round(float(p.gripper_qpos[0]), 3), finger_partners(env)])  # fmt: skip
                action = policy.act([with_privileged(obs, env)])[0, 0]
                obs, _, term, trunc, info = env.step(action)
                if term or trunc:
                    break
            ok = bool(info["success"])
            eps.append({"i": i, "success": ok, "failure": env.failure_mode(ok), "steps": env.steps,
                        "phase": policy.phase, **({} if ok else {"trace": trace})})  # fmt: skip
            if videos and not ok:
                import imageio.v2 as imageio

                Path(videos).mkdir(parents=True, exist_ok=True)
                name = f"{task}_{axis}_{level:+d}_ep{i}.mp4"
                imageio.mimwrite(Path(videos) / name, np.stack(frames), fps=20)
    finally:
        env.close()
    n_ok = sum(e["success"] for e in eps)
    return {"task": task, "axis": axis, "level": level, "n": len(eps), "successes": n_ok, "episodes": eps,
            "seed": seed, "oracle_version": type(policy).version, "wall_s": round(time.time() - t0, 1)}  # fmt: skip


def done_cells(out: Path) -> set[tuple]:
    if not out.is_file():
        return set()
    rows = [json.loads(line) for line in out.read_text().splitlines() if line.strip()]
    return {(r["task"], r["axis"], r["level"], r["n"], r["seed"]) for r in rows}


def table(out: Path) -> str:
    """Markdown: one row per (task, axis) with s/n per level and the failure modes of the failed episodes."""
    from indgen_vla.core.stats.metrics import clopper_pearson_ci

    rows = [json.loads(line) for line in out.read_text().splitlines() if line.strip()]
    cells: dict[tuple, dict] = {}
    for r in rows:
        cells[(r["task"], r["axis"], r["level"])] = r
    by: dict[tuple, list] = {}
    for (t, a, _k), r in sorted(cells.items()):
        by.setdefault((t, a), []).append(r)
    lines = ["| task | axis | levels: successes/n | failures (mode x count @ level) |", "|---|---|---|---|"]
    tot_s = tot_n = 0
    for (t, a), rs in by.items():
        rs.sort(key=lambda r: r["level"])
        fails = Counter((e["failure"], r["level"]) for r in rs for e in r["episodes"] if not e["success"])
        tot_s += sum(r["successes"] for r in rs)
        tot_n += sum(r["n"] for r in rs)
        lv = " ".join(
            f"{r['level']:+d}: " + (f"{r['successes']}/{r['n']}" if "error" not in r else "no build")
            for r in rs
        )
        fl = (
            ", ".join(f"{m} x{c} @ {k:+d}" for (m, k), c in sorted(fails.items(), key=lambda x: x[0][1]))
            or "-"
        )
        lines.append(f"| {t} | {a} | {lv} | {fl} |")
    lo, hi = clopper_pearson_ci(tot_s, tot_n) if tot_n else (0.0, 0.0)
    lines.append("")
    lines.append(f"Pooled over every cell above: {tot_s}/{tot_n} episodes succeeded (95 % CI {lo:.3f}-{hi:.3f}; "
                 "unpaired, all tasks).")  # fmt: skip
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", required=True, help="JSONL file of finished cells (appended; resumes)")
    ap.add_argument("--tasks", default="all", help="comma-separated tasks (default: all ten)")
    ap.add_argument("--axes", default="pick_y,goal_y,scale,distractor", help="comma-separated axes")
    ap.add_argument("--levels", default=None, help="comma-separated levels (default: each axis's range)")
    ap.add_argument("--episodes", type=int, default=10, help="episodes per cell")
    ap.add_argument(
        "--seed", type=int, default=0, help="certification seed (episode seeds as indgen certify's)"
    )
    ap.add_argument("--workers", type=int, default=1, help="processes, one cell each")
    ap.add_argument("--videos", default=None, help="folder for an MP4 of each failed episode")
    ap.add_argument("--table", action="store_true", help="print the markdown table of --out and exit")
    ap.add_argument("--deadline", type=float, default=None, help="start no cell after this many seconds")
    ap.add_argument("--first", default=None, help="task:axis whose cells run first")
    a = ap.parse_args(argv)
    out = Path(a.out)
    if a.table:
        print(table(out))
        return 0
    import scenes
    from indgen_vla.core.protocol.axis_ref import AxisRef
    from scenes.axes import get_successor

    tasks = list(scenes.get_scene(SCENE).tasks) if a.tasks == "all" else tuple(a.tasks.split(","))
    have = done_cells(out)
    jobs = []
    for axis in a.axes.split(","):
        levels = (
            [int(x) for x in a.levels.split(",")]
            if a.levels
            else list(get_successor(AxisRef.parse(axis)).axis.default_levels())
        )
        for k in levels:
            for t in tasks:
                if (t, axis, k, a.episodes, a.seed) not in have:
                    jobs.append((t, axis, k, a.episodes, a.seed, a.videos))
    if a.first:
        ft, fa = a.first.split(":")
        jobs.sort(key=lambda j: (j[0], j[1]) != (ft, fa))
    print(f"{len(jobs)} cells to run ({len(have)} done)", flush=True)
    ctx = mp.get_context("spawn")
    t0 = time.time()
    with ctx.Pool(a.workers, maxtasksperchild=8) as pool, out.open("a") as f:
        pending = [pool.apply_async(run_cell, (j,)) for j in jobs[: a.workers]]
        nxt = len(pending)

        def finished():
            while pending:
                time.sleep(0.2)
                for w in [w for w in pending if w.ready()]:
                    pending.remove(w)
                    if nxt < len(jobs) and (a.deadline is None or time.time() - t0 < a.deadline):
                        pending.append(pool.apply_async(run_cell, (jobs[nxt],)))
                        nxt_inc()
                    yield w.get()

        def nxt_inc():
            nonlocal nxt
            nxt += 1

        for r in finished():
            f.write(json.dumps(r) + "\n")
            f.flush()
            os.fsync(f.fileno())
            modes = Counter(e["failure"] for e in r["episodes"] if not e["success"])
            print(f"{r['task']} {r['axis']} {r['level']:+d}: {r['successes']}/{r['n']} {dict(modes) or ''} "
                  f"{r.get('error', '')}({r['wall_s']:.0f} s)", flush=True)  # fmt: skip
    print(f"{len(jobs) - nxt} cells not started (deadline)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
