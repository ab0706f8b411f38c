"""The local backend's process handling, on a real ``indgen evaluate`` process."""

import os
import signal
import subprocess
import sys
import tempfile
import time

from tests.fixtures.kill import processes, session_processes


def test_ctrl_c_while_the_fork_server_preloads_prints_one_line(tmp_path):
    """Ctrl-C on a terminal sends SIGINT to the whole foreground group, the fork server included; during its
    preload (seconds of simulator imports) it printed a KeyboardInterrupt traceback beside the one line."""
    argv = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--axis", "pick_y", "--levels", "0",
            "--episodes", "2", "--workers", "2", "--max-steps", "4", "--out", str(tmp_path / "run")]  # fmt: skip
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen([sys.executable, "-m", "indgen_vla.app.cli", *argv], stdout=subprocess.DEVNULL,
                                stderr=err, start_new_session=True)  # fmt: skip
        deadline = time.time() + 60
        while (
            time.time() < deadline
            and proc.poll() is None
            and not any(
                session == proc.pid and "multiprocessing.forkserver" in cmd
                for _, _, session, cmd in processes()
            )
        ):
            time.sleep(0.01)
        assert proc.poll() is None, "the run ended before its fork server started"
        time.sleep(0.2)  # the fork server is importing the simulator now
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(timeout=60)
        time.sleep(1.0)
        for line in session_processes(proc.pid):  # do not leave them to the rest of the suite
            os.kill(int(line.split()[0]), signal.SIGKILL)
        err.seek(0)
        said = err.read().decode(errors="replace")
    assert proc.returncode == 130, said
    assert "Traceback" not in said and "KeyboardInterrupt" not in said, said
    assert said.strip().splitlines()[-1] == (
        "interrupted: finished episodes are saved; re-run the same command to resume"
    )
