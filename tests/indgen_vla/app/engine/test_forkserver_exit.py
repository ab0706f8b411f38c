"""The workers' fork server skips its interpreter teardown (``forkserver_exit``); a coordinator that imports the module
keeps its own."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[4]
CHILD = """
import multiprocessing as mp, sys
from multiprocessing import forkserver
ctx = mp.get_context("forkserver")
ctx.set_forkserver_preload(sys.argv[1:])
forkserver.ensure_running()
p = ctx.Process(target=print)  # the server has preloaded once it forked a child
p.start(); p.join()
forkserver._forkserver._stop()  # as at the coordinator's exit: the server sees EOF and exits
"""


def _teardown_ran(tmp_path: Path, *preload: str) -> bool:
    marker = tmp_path / "teardown"
    marker.unlink(missing_ok=True)
    env = {**os.environ, "PYTHONPATH": str(ROOT), "INDGEN_TEST_ATEXIT_MARKER": str(marker)}
    subprocess.run([sys.executable, "-c", CHILD, *preload], env=env, cwd=ROOT, check=True, timeout=120)
    return marker.exists()


def test_fork_server_leaves_without_its_teardown(tmp_path):
    assert _teardown_ran(
        tmp_path, "tests.fixtures.atexit_marker"
    )  # the marker works: a plain server tears down
    assert not _teardown_ran(
        tmp_path, "tests.fixtures.atexit_marker", "indgen_vla.app.engine.forkserver_exit"
    )


def test_importing_it_elsewhere_changes_nothing(tmp_path):
    marker = tmp_path / "teardown"
    env = {**os.environ, "PYTHONPATH": str(ROOT), "INDGEN_TEST_ATEXIT_MARKER": str(marker)}
    code = "import tests.fixtures.atexit_marker, indgen_vla.app.engine.forkserver_exit; raise SystemExit(3)"
    assert subprocess.run([sys.executable, "-c", code], env=env, cwd=ROOT, timeout=60).returncode == 3
    assert marker.exists()  # its exit code and atexit handlers are its own
