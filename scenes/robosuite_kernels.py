"""robosuite's numba kernels, loaded once in the workers' fork server (a ``preload`` module of the robosuite families).

robosuite 1.4 jit-compiles its controller math (``utils/control_utils.py``, ``utils/transform_utils.py``) with an
on-disk cache. Every worker process used to load those kernels at its first control step (numba's CPU target set-up
plus the cached machine code: 0.6-1.2 CPU-s per worker on a 2-core VM), or, on a fresh install whose cache is
empty, compile them, all workers at once. Importing this module calls each kernel once with the argument types the
scenes pass (dtype, dimensions and memory layout pick the overload), so the fork server holds them and every worker
it forks inherits them. ``tests/scenes/test_robosuite_kernels.py`` checks that a real episode of the built-in and
the LIBERO scenes loads no overload beyond these.
"""

from __future__ import annotations

import warnings

import numpy as np
from robosuite.utils import control_utils, transform_utils

KERNELS = (
    control_utils.nullspace_torques,
    control_utils.opspace_matrices,
    control_utils.orientation_error,
    transform_utils.mat2quat,
    transform_utils.quat2mat,
)


def load_kernels() -> None:
    """Call each kernel with the layouts the OSC step uses (built-in fast path and robosuite's own controller)."""
    f, eye7 = np.asfortranarray, np.eye(7)
    jac = f(np.eye(6, 7))
    control_utils.nullspace_torques(f(eye7), eye7.copy(), np.zeros(7), np.zeros(7), np.zeros(7))
    control_utils.opspace_matrices(f(eye7), jac, f(jac[:3]), f(jac[3:]))
    control_utils.orientation_error(np.eye(3), np.eye(3))
    transform_utils.mat2quat(np.eye(3))  # contiguous rotation matrix
    transform_utils.mat2quat(np.eye(4)[:3, :3])  # a strided view of a pose matrix (LIBERO's observables)
    transform_utils.quat2mat(np.array([0.0, 0.0, 0.0, 1.0]))


try:  # an optimisation: a failure here must not stop the fork server (workers then load the kernels themselves)
    load_kernels()
except Exception as e:  # numba typing/compile errors have no common base below Exception
    warnings.warn(f"robosuite's numba kernels not preloaded ({type(e).__name__}: {e}); each worker loads its own",
                  stacklevel=1)  # fmt: skip
