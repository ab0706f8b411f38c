"""Benchmark: vectorised BlockEnv environment steps per second on one core (target ≥ 100k/s).

Usage: .venv/bin/python scripts/bench_blockenv.py [--batch 4096] [--level 5] [--seconds 3]
Prints one JSON line: steps_per_s for random actions and for oracle-driven episodes.
"""

from __future__ import annotations

import argparse
import json
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from indgen_vla.app.blockenv.env import BlockEnv, BlockEnvConfig, oracle_actions  # noqa: E402


def _rate(env: BlockEnv, batch: int, level: int, seconds: float, policy) -> float:
    rng = np.random.default_rng(0)
    steps, t0 = 0, time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        env.reset(np.full(batch, level), rng)
        arms = rng.integers(0, 2, batch)
        while not env.done.all():
            steps += int((~env.done).sum())
            env.step(policy(env, rng, arms))
    return steps / (time.perf_counter() - t0)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--batch", type=int, default=4096)
    p.add_argument("--level", type=int, default=5)
    p.add_argument("--seconds", type=float, default=3.0)
    a = p.parse_args()
    env = BlockEnv(BlockEnvConfig(grid_size=12))
    g = env.cfg.grid_size

    def rand(e, rng, _arms):
        return np.stack(
            [rng.integers(0, g, a.batch), rng.integers(0, g, a.batch), rng.integers(0, 2, a.batch)], 1
        )

    out = {"batch": a.batch, "level": a.level,
           "random_steps_per_s": round(_rate(env, a.batch, a.level, a.seconds, rand)),
           "oracle_steps_per_s": round(_rate(env, a.batch, a.level, a.seconds,
                                             lambda e, rng, arms: oracle_actions(e.grids, arms)))}  # fmt: skip
    print(json.dumps(out))


if __name__ == "__main__":
    main()
