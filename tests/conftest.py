"""What ``make test`` exports, as defaults for a bare ``pytest``: MuJoCo renders through EGL, the Hub stays offline,
and one OpenMP/BLAS thread per process (set before any test imports torch): two xdist workers on two cores each
running torch's machine-sized pool oversubscribe the cores, and OpenMP's spinning threads then made
tests/blockenv/test_blockenv.py 115 s instead of 15 s on a loaded 2-core VM (the engine's workers do the same,
engine.local.WORKER_THREAD_ENV)."""

import os

for _name, _value in {
    "MUJOCO_GL": "egl",
    "HF_HUB_OFFLINE": "1",
    "TOKENIZERS_PARALLELISM": "false",
    "OMP_NUM_THREADS": "1",
}.items():
    os.environ.setdefault(_name, _value)
