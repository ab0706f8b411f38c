"""scenes/robosuite_kernels.py: the fork server loads every numba overload a worker's episodes use, so no worker
loads (or compiles) one itself. A fresh interpreter, since any earlier episode in this process would already hold
the overloads and hide a missing one."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.timeout(300)

SCRIPT = """
import json, sys
import numpy as np
import scenes, scenes.robosuite_kernels as k
from scenes.planning import scene_levels

loaded = {f.__name__: sorted(map(str, f.signatures)) for f in k.KERNELS}
used = {}
for scene in sys.argv[1:]:
    builder = scene_levels(scenes.get_scene(scene), ["pick_y"])
    env = builder.make_env(list(scenes.get_scene(scene).tasks)[0], "pick_y", 1, cameras=(), image_size=(64, 64), max_steps=10)
    env.reset(seed=0)
    for _ in range(4):
        env.step(np.array([0.2, -0.1, 0.1, 0.0, 0.0, 0.1, 1.0], dtype=np.float32))
    env.close()
    used[scene] = {f.__name__: sorted(map(str, f.signatures)) for f in k.KERNELS}
print(json.dumps({"loaded": loaded, "used": used}))
"""


@pytest.mark.slow  # ~9 s (a fresh interpreter builds two scenes); it guards a start-up cost, not an outcome
def test_the_fork_servers_kernels_cover_a_real_episode(mini):
    """After real steps of the built-in and LIBERO scenes the kernels hold exactly the overloads the module
    loaded: a layout robosuite or a scene starts to pass differently shows up here as a new signature."""
    from scenes.family import get_scene

    assert "scenes.robosuite_kernels" in get_scene("pick_place").preload
    assert "scenes.robosuite_kernels" in get_scene("libero_object").preload
    proc = subprocess.run([sys.executable, "-c", SCRIPT, "pick_place", "libero_object"], capture_output=True,
                          text=True, timeout=240, env={**os.environ, "MUJOCO_GL": "egl"})  # fmt: skip
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert all(out["loaded"].values()), out["loaded"]  # numba on: every kernel holds its overloads
    for scene, used in out["used"].items():
        assert used == out["loaded"], (scene, used, out["loaded"])
