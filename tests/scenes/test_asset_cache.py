"""scenes/asset_cache.py: the workers' fork server fills MuJoCo's asset cache with the run's first task, and the
workers it forks inherit it. Fresh interpreters, since this process's cache already holds whatever earlier tests
built."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from indgen_vla.core.protocol.plan import WARM_CELL_ENV

pytestmark = pytest.mark.timeout(300)

# imports the preload as multiprocessing's fork server does, then forks a child that reads the cache it inherited
SCRIPT = """
import importlib, json, os, sys
import mujoco
from scenes.family import get_scene

for m in ("indgen_vla.app.engine.local", *get_scene("pick_place").preload):
    importlib.import_module(m)
size = lambda: mujoco.mj_getCacheSize(mujoco.mj_getCache())
r, w = os.pipe()
if os.fork() == 0:
    os.write(w, str(size()).encode())
    os._exit(0)
os.wait()
print(json.dumps({"server": size(), "child": int(os.read(r, 64))}))
"""


def _preload(cell: str | None) -> tuple[dict, str]:
    env = {k: v for k, v in os.environ.items() if k != WARM_CELL_ENV}
    if cell is not None:
        env[WARM_CELL_ENV] = cell
    out = subprocess.run([sys.executable, "-c", SCRIPT], capture_output=True, text=True, timeout=240, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr


def test_the_fork_server_warms_the_first_task_and_its_children_inherit_it():
    sizes, stderr = _preload(json.dumps({"scene": "pick_place", "task": "milk"}))
    assert sizes["server"] > 10_000_000 and sizes["child"] == sizes["server"]  # pick_place: ≈ 90 MB of assets
    assert "warn" not in stderr.lower(), stderr[-2000:]


@pytest.mark.slow  # 7 s: two fresh interpreters
def test_without_a_cell_the_preload_builds_nothing_and_a_bad_one_only_warns():
    assert _preload(None)[0] == {"server": 0, "child": 0}
    sizes, stderr = _preload(json.dumps({"scene": "pick_place", "task": "no_such_task"}))
    assert sizes["server"] == 0 and "asset cache not filled" in stderr
