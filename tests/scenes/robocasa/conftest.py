"""One placeholder kitchen-asset tree per test process for every RoboCasa test module (writing it costs seconds)."""

from __future__ import annotations

import pytest


@pytest.fixture(scope="session")
def placeholder_tree(request, tmp_path_factory):
    """The tree, written once per test run: pytest-xdist's ``--dist loadfile`` interleaves this package's files with
    others', so a package-scoped tree was torn down and written again between them (about 6 s each time), and each
    worker process wrote its own; under xdist the workers share one, written by whichever asks first (a file lock in
    the run's temporary folder, which the workers' own folders sit in)."""
    from filelock import FileLock

    from scenes.robocasa.placeholders import write_placeholders

    if getattr(request.config, "workerinput", None) is None:  # one process: its own tree
        root = tmp_path_factory.mktemp("robocasa_assets")
        write_placeholders(root)
        return root
    run = tmp_path_factory.getbasetemp().parent  # this run's folder, shared by its workers
    root, done = run / "robocasa_assets", run / "robocasa_assets.written"
    with FileLock(str(run / "robocasa_assets.lock")):
        if not done.exists():
            write_placeholders(root)
            done.touch()
    return root


@pytest.fixture(scope="package")  # torn down when the package's tests end
def placeholders(placeholder_tree):
    """The tree, pointed at by INDGEN_ROBOCASA_ASSETS while the RoboCasa tests run, under RoboCasa365 split "all"
    with RoboCasa's own registries (``scenes.robocasa.splits.LEGACY``): the kitchens each seed draws, which the
    tests' seeds and the placeholder results in docs/ were chosen and measured under. test_splits sets its own."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("INDGEN_ROBOCASA_ASSETS", str(placeholder_tree))
        mp.setenv("INDGEN_ROBOCASA_SPLIT", "all")
        mp.delenv("INDGEN_ROBOCASA_OBJ_REGISTRIES", raising=False)
        yield placeholder_tree
