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


REAL_ASSETS_SKIP = "LIBERO's complete asset tree is not installed: run 'make libero' or 'indgen setup libero' ('make test' does)"


def complete_libero_tree():
    """Where ``indgen setup libero`` installed LIBERO's complete tree (its listing is the wheels'), else None: the
    tree every ``real_assets`` test runs on."""
    from scenes.libero.assets import tree_identity
    from scenes.libero.install import COMPLETE_TREE, default_dest

    root = default_dest()
    return root if root.is_dir() and tree_identity(root) == COMPLETE_TREE else None


def pytest_collection_modifyitems(config, items):
    """A test on LIBERO's complete tree (it takes the ``real`` fixture) is a ``real_assets`` test wherever it lives."""
    import pytest

    for item in items:
        if "real" in getattr(item, "fixturenames", ()) and not item.get_closest_marker("real_assets"):
            item.add_marker(pytest.mark.real_assets)


_real_assets: dict[
    str, str
] = {}  # nodeid -> outcome, in the process that prints the summary (xdist's controller)


def pytest_runtest_logreport(report):
    """Collect the outcome of every ``real_assets`` test (workers' reports reach the controller too)."""
    if "real_assets" not in report.keywords:
        return
    if report.when == "call" or (report.when == "setup" and not report.passed):
        _real_assets[report.nodeid] = "skipped" if report.skipped else report.outcome


def pytest_terminal_summary(terminalreporter):
    """Say how many tests ran on LIBERO's complete tree, and where that tree was: a fresh machine's ``make test``
    installs it under its own home, so the line shows which tree the tests used."""
    if not _real_assets:
        return
    ran = sum(v != "skipped" for v in _real_assets.values())
    failed = sum(v == "failed" for v in _real_assets.values())
    tree = complete_libero_tree()
    where = f" on {tree}" if tree is not None else ""
    line = f"LIBERO real-asset tests: {ran} ran{where} ({failed} failed), {len(_real_assets) - ran} skipped"
    if ran < len(_real_assets):
        line += f" ({REAL_ASSETS_SKIP})"
    terminalreporter.write_line(line)
