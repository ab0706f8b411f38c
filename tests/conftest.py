"""The test session's defaults. What ``make test`` exports, for a bare ``pytest`` too: MuJoCo renders through EGL,
the Hub stays offline, and one OpenMP/BLAS thread per process (set before any test imports torch): two xdist workers
on two cores each running torch's machine-sized pool oversubscribe the cores, and OpenMP's spinning threads then made
tests/indgen_vla/app/blockenv/test_blockenv.py 115 s instead of 15 s on a loaded 2-core VM (the engine's workers do the same,
engine.local.WORKER_THREAD_ENV)."""

import os

for _name, _value in {
    "MUJOCO_GL": "egl",
    "HF_HUB_OFFLINE": "1",
    "TOKENIZERS_PARALLELISM": "false",
    "OMP_NUM_THREADS": "1",
}.items():
    os.environ.setdefault(_name, _value)


_frozen_at = 0  # len(sys.modules) when this process last froze what it holds


def pytest_runtest_setup(item):
    """Freeze (``gc.freeze``) what is alive after a test imported a large library: a full collection otherwise
    rescans every object of torch, lerobot and robosuite (~600k), and robosuite's ``MjSim.free`` runs one at each
    env close and LIBERO hard reset (0.3 s each once lerobot is imported: 28 s of 110 s over four scene and engine
    files). Collected first, so only what outlives the imports (modules, caches, open fixtures) is frozen."""
    import gc
    import sys

    global _frozen_at
    if len(sys.modules) > _frozen_at + 100:
        gc.collect()
        gc.freeze()
        _frozen_at = len(sys.modules)
