"""``indgen setup robocasa`` stopped part-way leaves nothing running: ``venv`` runs ensurepip, which runs pip."""

from __future__ import annotations

import signal
import time

import pytest

from tests.fixtures.kill import processes, stop_midway


def test_a_stopped_setup_leaves_no_installer_running(tmp_path):
    """SIGTERM while ``python -m venv`` runs ensurepip (no network needed yet); its children used to go on
    installing into the folder that the re-run removes."""
    from indgen_vla.core.errors import ConfigError
    from scenes.robocasa.environment import find_python312

    try:
        find_python312()
    except ConfigError:
        pytest.skip("no Python 3.12 to make the venv with")
    venv = tmp_path / "venv"

    def installing() -> bool:
        return any(str(venv) in cmd and "ensurepip" in cmd for *_, cmd in processes())

    # linger 1 s: ensurepip, orphaned, would end by itself a few seconds later (pip's download of the pins: minutes)
    stopped = stop_midway(["setup", "robocasa", "--venv", str(venv)], signal.SIGTERM, installing, timeout_s=60,
                          linger_s=1.0)  # fmt: skip
    assert stopped.returncode == 143, stopped.stderr
    assert stopped.stderr.strip().splitlines()[-1] == (
        "terminated (SIGTERM): 'indgen setup' keeps no partial output; re-run it to start over"
    )
    assert stopped.survivors == []  # in its session
    time.sleep(0.5)
    assert [
        cmd for _, state, _, cmd in processes() if str(venv) in cmd and state != "Z"
    ] == []  # or any other


@pytest.mark.parametrize("finder", ["python", "makefile"])
def test_the_312_finder_passes_over_a_shim_that_is_not_312(tmp_path, monkeypatch, finder):
    """A pyenv shim named python3.12 that fails (pyenv's global version is another) comes first on PATH: both
    finders run each candidate and return a real 3.12 executable, never the shim."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    from indgen_vla.core.errors import ConfigError
    from scenes.robocasa.environment import find_python312

    shims = tmp_path / "shims"
    shims.mkdir()
    for name in ("python3.12", "pyenv"):  # as a shim with global 3.11 answers, and `pyenv which` with it
        (shims / name).write_text('#!/bin/sh\necho "pyenv: python3.12: command not found" >&2\nexit 127\n')
        (shims / name).chmod(0o755)
    monkeypatch.setenv("PATH", f"{shims}{os.pathsep}{os.environ['PATH']}")
    if finder == "python":
        try:
            found = find_python312()
        except ConfigError:
            pytest.skip("no Python 3.12 on this machine")
    else:
        script = Path(__file__).resolve().parents[3] / "scripts" / "find_python312.sh"
        r = subprocess.run(["bash", str(script)], capture_output=True, text=True, cwd=tmp_path)
        if r.returncode:
            pytest.skip("no Python 3.12 on this machine")
        found = r.stdout.strip()
    assert not found.startswith(str(shims)), found
    out = subprocess.run(
        [found, "-c", "import sys; print(sys.version_info[:2])"], capture_output=True, text=True
    )
    assert out.stdout.strip() == "(3, 12)", (found, out)
    assert sys.version_info[:2] == (3, 12)
