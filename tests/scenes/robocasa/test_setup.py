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
