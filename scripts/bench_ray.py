"""Benchmark the Ray backend against the local one on this machine: the same oracle episodes of ``pick_place`` with
``--sims`` simulators either way (default 2; local: that many worker processes, the policy in the main process; Ray:
a local Ray instance with one CPU more, that many simulator actors and 1 policy actor), reporting Ray's start, each
run's wall time, the episodes per second once every simulator has finished one episode, and one policy call's round
trip through a policy actor. The records of both must be equal. Runs take turns (local, Ray, local, Ray ...; one Ray
instance, its start timed apart), so each pair sees the same load: the ratio's median and [min, max] over
``--repeats`` pairs. Each local run starts its own fork server (stopped after each run) and its workers while the
policy loads (``EarlyWorkers``), as an ``indgen evaluate`` does; Ray's actors start in each run too. ``--forward-ms``
adds a forward of that many ms to every policy call (a sleep: a GPU's forward leaves the CPU free), once per cheap and
per slow policy; ``--load-s`` a load of that many seconds once per run (a VLA's weights: both backends build their
simulators' first scenes meanwhile); ``--busy N`` keeps N busy-looping processes at the default priority beside the
paired runs (a box running something else: Ray's workers used to start at nice 15 and starve). ``--nodes 1,2,3``: the
throughput curve on a ``ray.cluster_utils.Cluster`` of that many 2-CPU nodes (a policy actor and a simulator each),
all on this machine. Prints one JSON object on its last line (docs/results/benchmarks/speed.md).

    .venv/bin/python scripts/bench_ray.py [--episodes 8] [--sims 2] [--max-steps 40] [--repeats 3]
                                          [--forward-ms 0,50] [--calls 300] [--nodes 1,2,3] [--load-s 0]
                                          [--busy 0] [--worker-niceness 0]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time
from pathlib import Path

from scenes.family import get_scene

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("HF_HUB_OFFLINE", "1")
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

ROW = ("task", "axis", "level", "episode", "seed", "success", "steps", "status", "failure")


def _jobs(episodes: int, sims: int = 2):
    import scenes
    from indgen_vla.app.engine.config import EvalConfig, plan_episodes

    task = list(scenes.get_scene("pick_place").tasks)[0]
    cfg = EvalConfig.from_flat(policy="standin:oracle", scene="pick_place", axes=("pick_y",), out="-",
                               episodes=episodes, workers=sims, backend="ray")  # fmt: skip
    return cfg, plan_episodes(cfg, [task], {"pick_y": [0]}, {(task, "pick_y", 0): 0.0})


def _timed(run, sims: int = 2) -> dict:
    """Wall time of ``run(on_record)``, and episodes/s after the first ``sims`` finished (every simulator warm)."""
    stamps: list[float] = []
    records: list = []

    def on_record(r) -> None:
        stamps.append(time.perf_counter())
        records.append(r)

    t0 = time.perf_counter()
    run(on_record)
    wall = time.perf_counter() - t0
    first = stamps[min(sims, len(stamps)) - 1]
    steady = (len(stamps) - sims) / (stamps[-1] - first) if len(stamps) > sims else float("nan")
    return {"wall_s": round(wall, 2), "first_round_s": round(first - t0, 2), "episodes_per_s": round(steady, 3),
            "rows": sorted(tuple(getattr(r, k) for k in ROW) for r in records)}  # fmt: skip


def round_trip_ms(calls: int) -> dict:
    """One ``act`` of a trivial policy: called in process vs from another actor on this node, over the policy
    actor's socket (``ray_channel``, the default road) and through a Ray actor call (``INDGEN_RAY_SOCKET=0``)."""
    import numpy as np
    import ray

    from indgen_vla.app.engine.ray_backend import _node, _PolicyActor, _PolicyClient
    from indgen_vla.app.engine.ray_channel import connect
    from indgen_vla.core.protocol.interface import Observation
    from policy_wrappers.specs import load_policy

    obs = Observation({}, np.zeros(8, np.float32), "pick")
    direct = load_policy("standin:random")
    direct.reset("pick", seed=0)
    t0 = time.perf_counter()
    for _ in range(calls):
        direct.act([obs])
    in_process = (time.perf_counter() - t0) / calls * 1e3

    @ray.remote(num_cpus=0)
    class Caller:
        def time_calls(self, actor, spec, n: int, socket: bool) -> list[float]:
            channel = connect(ray.get(actor.channel.remote()), _node()) if socket else None
            assert channel is not None or not socket, "no socket to the policy actor on this node"
            client = _PolicyClient(actor, 0, spec, channel)
            client.reset("pick", seed=0)
            out = []
            for _ in range(n):
                t = time.perf_counter()
                client.act([obs])
                out.append((time.perf_counter() - t) * 1e3)
            return out

    actor = ray.remote(num_cpus=0, max_concurrency=4)(_PolicyActor).remote(
        lambda: load_policy("standin:random"), 32, 0.005
    )
    spec = ray.get(actor.hello.remote())
    ray.get(actor.set_clients.remote(1))  # as the supervisor tells it: one simulator
    out = {"in_process_ms": round(in_process, 3), "calls": calls}
    caller = Caller.remote()
    for road, socket in (("socket", True), ("actor", False)):
        times = sorted(ray.get(caller.time_calls.remote(actor, spec, calls, socket)))
        out[f"through_{road}_median_ms"] = round(statistics.median(times), 3)
        out[f"through_{road}_p90_ms"] = round(times[int(0.9 * len(times))], 3)
    return out


class SlowOracle:
    """The oracle with a load of ``load_s`` seconds (once per ``run``) and a forward of ``forward_s`` seconds per call
    (sleeps, as a GPU's load and forward leave the CPU free); the same decisions, so records stay equal across
    backends."""

    loaded: set = set()  # the runs whose weights this process holds

    def __init__(self, forward_s: float = 0.0, load_s: float = 0.0, run: str = ""):
        if load_s and run not in SlowOracle.loaded:
            SlowOracle.loaded.add(run)  # a VLA's load: once per run and process, not per instance
            time.sleep(load_s)
        from scenes.tabletop.oracle import OraclePolicy

        self.inner, self.forward_s = OraclePolicy(), forward_s
        self.spec = self.inner.spec

    def reset(self, instruction: str, seed: int | None = None) -> None:
        self.inner.reset(instruction, seed=seed)

    def act(self, observations):
        if self.forward_s:
            time.sleep(self.forward_s)
        return self.inner.act(observations)

    def close(self) -> None:
        self.inner.close()


def _ratio(xs: list[float]) -> dict:
    xs = sorted(xs)
    return {
        "median": round(statistics.median(xs), 3),
        "min": round(xs[0], 3),
        "max": round(xs[-1], 3),
        "n": len(xs),
    }


def paired(args, jobs, rc, cfg, meta, replan, forward_ms: float) -> dict:
    """Local and Ray in turn, ``args.repeats`` pairs, one policy: walls, steady rates and their ratios."""
    from functools import partial
    from multiprocessing import forkserver

    from indgen_vla.app.engine.local import EarlyWorkers, Handoff, LocalOptions, run_local
    from indgen_vla.app.engine.ray_backend import run_ray

    def local(rec, make) -> None:
        """As ``indgen evaluate`` runs locally: workers start, and build their first scenes, while the policy loads
        in this process; ``run_local`` then adopts both."""
        early = EarlyWorkers(rc, jobs, args.sims)
        loaded = [make()]
        options = LocalOptions(workers=args.sims, replan_steps=replan)
        run_local(jobs, rc, lambda: loaded.pop() if loaded else make(), meta, rec, options,
                  handoff=Handoff(early=early.take(rc)))  # fmt: skip

    runs: dict[str, list[dict]] = {"local": [], "ray": []}
    rows = None
    for k in range(args.repeats):
        for name in ("local", "ray"):
            make = partial(SlowOracle, forward_ms / 1000.0, args.load_s, f"{name}-{k}")
            if name == "local":
                r = _timed(lambda rec, make=make: local(rec, make), args.sims)
                forkserver._forkserver._stop()  # the next local run starts its fork server, as a CLI run does
            else:
                r = _timed(
                    lambda rec, make=make: run_ray(jobs, rc, cfg, meta, rec, replan, make_policy=make),
                    args.sims,
                )
            got = r.pop("rows")
            assert rows is None or got == rows, "the Ray backend recorded other outcomes than the local one"
            rows = got
            r["load_1min"] = round(os.getloadavg()[0], 2)
            runs[name].append(r)
    pairs = list(zip(runs["local"], runs["ray"], strict=True))
    return {"forward_ms": forward_ms, "load_s": args.load_s, "local": runs["local"], "ray": runs["ray"],
            "wall_ratio_ray_over_local": _ratio([b["wall_s"] / a["wall_s"] for a, b in pairs]),
            "steady_ratio_local_over_ray": _ratio([a["episodes_per_s"] / b["episodes_per_s"] for a, b in pairs])}  # fmt: skip


def node_curve(args, jobs, rc, cfg, meta, replan, nodes: list[int], forward_ms: float) -> list[dict]:
    """Episodes/s on a cluster of 1..N nodes of 2 CPUs (head with none), ``--workers auto``: a simulator and a
    policy actor per node, all on this machine (what a node adds when the policy, not the CPU, bounds a simulator)."""
    import dataclasses
    from functools import partial

    import ray
    from ray.cluster_utils import Cluster

    from indgen_vla.app.engine.ray_backend import run_ray

    make = partial(SlowOracle, forward_ms / 1000.0)
    auto = dataclasses.replace(cfg, run=dataclasses.replace(cfg.run, workers="auto"))
    c = Cluster(initialize_head=True, head_node_args={"num_cpus": 0, "include_dashboard": False})
    out = []
    try:
        os.environ["RAY_ADDRESS"] = c.address
        for n in range(1, max(nodes) + 1):
            c.add_node(num_cpus=2)
            c.wait_for_nodes()
            if n not in nodes:
                continue
            stats: dict = {}
            r = _timed(
                lambda rec, s=stats: run_ray(jobs, rc, auto, meta, rec, replan, make_policy=make, stats=s), n
            )  # a simulator per node
            r.pop("rows")
            out.append({"nodes": n, **r, "policy_actors": stats.get("policy_actors"),
                        "episodes_per_node": stats.get("episodes_per_node"),
                        "load_1min": round(os.getloadavg()[0], 2)})  # fmt: skip
            if ray.is_initialized():
                ray.shutdown()
    finally:
        os.environ.pop("RAY_ADDRESS", None)
        if ray.is_initialized():
            ray.shutdown()
        c.shutdown()
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=8)
    ap.add_argument("--sims", type=int, default=2,
                    help="simulators either way: local workers, Ray simulator actors (Ray: a CPU more)")  # fmt: skip
    ap.add_argument("--max-steps", type=int, default=40)
    ap.add_argument("--calls", type=int, default=300)
    ap.add_argument("--repeats", type=int, default=3, help="pairs (local, Ray) run in turn")
    ap.add_argument(
        "--forward-ms", default="0,50", help="comma list: a forward of this many ms per policy call"
    )
    ap.add_argument(
        "--nodes", default="", help="comma list of node counts for the cluster curve (e.g. 1,2,3)"
    )
    ap.add_argument(
        "--nodes-forward-ms", type=float, default=50.0, help="the policy's forward in the node curve"
    )
    ap.add_argument("--load-s", type=float, default=0.0,
                    help="the policy's load in seconds, once per run (a sleep: a VLA's weights reaching a GPU)")  # fmt: skip
    ap.add_argument("--busy", type=int, default=0, help="busy-looping processes beside the paired runs")
    ap.add_argument("--worker-niceness", type=int, default=None,
                    help="the Ray workers' niceness (default run_ray's, 0; Ray's own default is 15)")  # fmt: skip
    ap.add_argument("--nodes-episodes", type=int, default=12, help="episodes of each node-curve run")
    args = ap.parse_args()

    import ray

    from indgen_vla.app.engine.ray_cluster import LOCAL_SYSTEM_CONFIG
    from indgen_vla.app.engine.rollout import RunMeta, RunnerConfig
    from scenes.planning import scene_levels
    from scenes.tabletop.oracle import OraclePolicy

    if not 1 <= args.sims <= args.episodes:
        ap.error(f"--sims {args.sims}: give 1 to {args.episodes} simulators (no more than --episodes)")
    cfg, jobs = _jobs(args.episodes, args.sims)
    rc = RunnerConfig(levels=scene_levels(get_scene("pick_place"), ["pick_y"]), cameras=(), image_size=(64, 64),
                      max_steps=args.max_steps, privileged=True)  # fmt: skip
    meta = RunMeta("bench", "standin:oracle", "", "pick_place")
    replan = OraclePolicy.spec.replan_steps
    result = {"machine": f"{platform.machine()} {os.cpu_count()} cores", "ray": ray.__version__,
              "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "episodes": len(jobs),
              "max_steps": args.max_steps, "sims": args.sims, "replan_steps": replan,
              "load_1min_start": round(os.getloadavg()[0], 2)}  # fmt: skip
    forwards = [float(x) for x in args.forward_ms.split(",") if x.strip()]
    if forwards:
        busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.busy)]
        result["busy_processes"] = args.busy
        try:
            t0 = time.perf_counter()
            system = dict(LOCAL_SYSTEM_CONFIG)  # the local instance run_ray would start
            if args.worker_niceness is not None:
                system["worker_niceness"] = args.worker_niceness
            result["worker_niceness"] = system["worker_niceness"]
            ray.init(
                address="local",
                num_cpus=args.sims + 1,  # the simulators and the policy actor
                include_dashboard=False,
                log_to_driver=False,
                _system_config=system,
            )
            result["ray_init_s"] = round(time.perf_counter() - t0, 2)
            result["policies"] = []
            for f in forwards:  # each policy's pairs as they finish: a run cut short keeps the ones before it
                result["policies"].append(paired(args, jobs, rc, cfg, meta, replan, f))
                print(json.dumps({**result, "partial": True}), flush=True)
            result["policy_round_trip"] = round_trip_ms(args.calls)
        finally:
            ray.shutdown()
            for b in busy:
                b.kill()
    if args.nodes:
        _, curve_jobs = _jobs(args.nodes_episodes)
        nodes = [int(x) for x in args.nodes.split(",")]
        result["node_curve"] = node_curve(
            args, curve_jobs, rc, cfg, meta, replan, nodes, args.nodes_forward_ms
        )
    result["load_1min_end"] = round(os.getloadavg()[0], 2)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
