"""``indgen real record`` starting each episode itself: ``--episode-command`` runs a real subprocess per episode
(driven in a pseudo-terminal, Ctrl-C included) and ``--check-policy`` talks to loopback servers speaking openpi's
websocket and GR00T's ZMQ protocols; the operator still types every verdict."""

from __future__ import annotations

import json
import os
import shlex
import signal
import sys

import pyarrow.parquet as pq
import pytest

from indgen_vla.app.cli import main
from indgen_vla.app.real.design import RealRun
from indgen_vla.app.real.session import interactive
from indgen_vla.app.real_policy import PolicyCheck
from policy_wrappers import msgpack_numpy
from tests.indgen_vla.app.real.pty_session import PtySession, indgen
from tests.policy_wrappers.loopback import WebsocketServer

pytestmark = pytest.mark.timeout(60)
START = "start the episode [Enter], or s f v u q ?> "
AGAIN = "outcome [s f v u q ? r]> "
INSTRUCTION = "Place the orange block on the blue block"

# the user's per-episode script: it fails once (robot fault), hangs once (stopped with Ctrl-C), else "records"
# a video at the path it was given and prints it
EVAL = """\
import os, pathlib, sys, time
print("args", sys.argv[1:], flush=True)
run = pathlib.Path(os.environ["INDGEN_RUN"])
key = (os.environ["INDGEN_LEVEL"], os.environ["INDGEN_EPISODE"], os.environ["INDGEN_ATTEMPT"])
if key == ("0", "1", "0"):
    print("robot fault: joint 4 limit", flush=True)
    sys.exit(3)
if key == ("1", "0", "0") and not (run / "hung").exists():
    (run / "hung").touch()
    print("waiting for the robot ...", flush=True)
    time.sleep(60)
out = pathlib.Path(sys.argv[-1])
out.parent.mkdir(parents=True, exist_ok=True)
out.write_bytes(b"not really a video")
print(f"video={out}")
"""


def _plan(run, episodes: int = 2) -> None:
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", str(episodes), "--order",
                 "blocked", "--policy", "pi05-droid", "--operator", "alice", "--out", str(run)]) == 0  # fmt: skip


def test_episode_command_runs_per_episode_in_a_terminal_session(tmp_path, capsys):
    run = tmp_path / "run"
    _plan(run)
    (tmp_path / "eval.py").write_text(EVAL)  # run from where the session was started (the pty cwd)
    template = (f"{shlex.quote(sys.executable)} eval.py --level {{level}} --seed {{seed}} "
                "--instruction {instruction} --out {video}")  # fmt: skip
    pattern = "{run}/videos/{axis}_L{level}_e{episode}_a{attempt}.mp4"
    s = PtySession(indgen("real", "record", str(run), "--episode-command", template, "--video-pattern", pattern,
                          "--no-report"), tmp_path)  # fmt: skip
    rr = RealRun.open(run)
    s.expect("episode 0 of level 0")
    s.expect(f"  run    : {shlex.quote(sys.executable)} eval.py --level 0 --seed {rr.seeds[0]} "
             f"--instruction '{INSTRUCTION}' --out {run}/videos/stack_L0_e0_a0.mp4")  # fmt: skip
    s.expect(START)
    s.type("")  # Enter: the operator has set the scene up
    s.expect(f"args ['--level', '0', '--seed', '{rr.seeds[0]}', '--instruction', '{INSTRUCTION}', '--out'")
    s.expect("episode command exited 0 after ")
    s.expect(f"video {run}/videos/stack_L0_e0_a0.mp4; log real_logs/L0_e0_a0.log")
    s.expect(AGAIN)
    s.type("s")
    s.expect(f"saved: level 0 episode 0 success; video {run}/videos/stack_L0_e0_a0.mp4; command exit 0")
    s.expect(START)
    s.type("")
    s.expect("robot fault: joint 4 limit")
    s.expect("episode command exited 3 after ")
    s.expect(
        "the command did not exit 0: if the episode did not run as planned, type v with why, or r to run it again"
    )
    s.expect(AGAIN)
    s.type("v robot fault, joint 4")
    s.expect("saved: level 0 episode 1 VOID (robot fault, joint 4): re-queued")
    s.expect("episode 1 of level 0 (stack = 0 in), re-run after 1 void(s)")
    s.expect("--out " + str(run / "videos" / "stack_L0_e1_a1.mp4"))  # the re-run's own video path
    s.expect(START)
    s.type("r")
    s.expect("episode command exited 0")
    s.expect(AGAIN)
    s.type("f 4 toppled")
    s.expect("saved: level 0 episode 1 failure (misplaced); note toppled")
    s.expect(START)
    s.type("")
    s.expect("waiting for the robot ...")
    os.killpg(s.proc.pid, signal.SIGINT)  # what Ctrl-C on the terminal does: SIGINT to the foreground group
    s.expect("episode command was stopped (Ctrl-C) after ")
    s.expect("the command did not exit 0")
    s.expect(AGAIN)
    s.type("r")  # run it again (the scene was reset)
    s.expect("episode command exited 0")
    s.expect(AGAIN)
    s.type("s")
    s.expect(START)
    s.type("s")  # an episode may also be judged without the command (the operator ran it by hand)
    s.expect("run complete: every episode the plan needs is recorded.")
    assert s.wait() == 0

    entries = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
    assert [(e["level"], e["episode"], e["kind"]) for e in entries] == [
        (0, 0, "success"), (0, 1, "void"), (0, 1, "failure"), (1, 0, "success"), (1, 1, "success")]  # fmt: skip
    cmd = [e["trigger"].get("command", {}) for e in entries]
    assert [c.get("exit_code") for c in cmd] == [0, 3, 0, 0, None]
    assert [e["trigger"].get("starts") for e in entries] == [1, 1, 1, 2, None]  # 1 0: stopped, then run again
    assert cmd[0]["argv"][2:8] == ["--level", "0", "--seed", str(rr.seeds[0]), "--instruction", INSTRUCTION]
    assert cmd[0]["video"] == str(run / "videos" / "stack_L0_e0_a0.mp4") and cmd[1]["video"] == ""
    assert entries[4]["trigger"] == {} and entries[4]["video"] == str(run / "videos" / "stack_L1_e1_a0.mp4")
    log = (run / "real_logs" / "L0_e1_a0.log").read_text()
    assert "robot fault: joint 4 limit" in log and log.rstrip().endswith("# exit 3")
    assert (run / "real_logs" / "L1_e0_a0.log").read_text().count("# exit") == 2  # stopped, then run again
    rows = pq.read_table(run / "episodes.parquet").to_pylist()
    assert [(r["level"], r["episode"], r["success"], r["video"].rsplit("/", 1)[-1]) for r in rows] == [
        (0, 0, True, "stack_L0_e0_a0.mp4"), (0, 1, False, "stack_L0_e1_a1.mp4"),
        (1, 0, True, "stack_L1_e0_a0.mp4"), (1, 1, True, "stack_L1_e1_a0.mp4")]  # fmt: skip


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--episode-command", "python eval.py --seed {sed}"], "unknown field {sed} (did you mean {seed}?)"),
        (["--episode-command", "no-such-program-xyz {level}"], "program 'no-such-program-xyz' not found on PATH"),
        (["--episode-command", "python 'eval.py"], "check its quotes"),
        (["--episode-command", "python eval.py", "--outcome", "success"], "with --outcome, run the episode"),
        (["--video-pattern", "/v/{lvl}.mp4"], "--video-pattern '/v/{lvl}.mp4': unknown field {lvl} (did you mean"),
    ],
)  # fmt: skip
def test_bad_trigger_options_fail_in_one_line(tmp_path, capsys, extra, message):
    run = tmp_path / "run"
    _plan(run)
    capsys.readouterr()
    assert main(["real", "record", str(run), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and message in err and "\n" not in err
    assert not (run / "journal.jsonl").exists()


def openpi_server(connections: list):
    """openpi's websocket server as its clients see it: a metadata frame on connect, then request -> reply."""

    async def handler(ws):
        connections.append(1)
        await ws.send(msgpack_numpy.packb({"action_horizon": 10}))
        async for _ in ws:
            pass

    return WebsocketServer(handler)


class Operator:
    """Answers prompts from a script; a step may be a callable run first (e.g. stopping the server)."""

    def __init__(self, steps):
        self.steps, self.prompts, self.said = list(steps), [], []

    def ask(self, prompt: str) -> str:
        self.prompts.append(prompt)
        step = self.steps.pop(0)
        if callable(step):
            step = step()
        return step


def test_check_policy_against_a_loopback_openpi_server(tmp_path, capsys):
    run = tmp_path / "run"
    _plan(run, episodes=1)
    connections: list = []
    srv = openpi_server(connections).__enter__()
    spec = f"openpi:ws://127.0.0.1:{srv.port}"
    check = PolicyCheck(spec)
    assert len(connections) == 1  # loading the client is the first reachability check

    def stop_server():
        srv.__exit__(None, None, None)
        return ""

    op = Operator(["", "s", stop_server, "v policy server down", "q"])
    try:
        done = interactive(RealRun.open(run), ask=op.ask, say=op.said.append, triggers=[check], write=print)
    finally:
        check.close()
    assert not done and op.prompts == [START, AGAIN, START, START, START]
    said = "\n".join(op.said)
    assert f"  policy : {spec} (checked and reset with seed" in said
    assert len(connections) == 2  # Enter on episode 0: a fresh connection and its metadata frame
    assert f"policy {spec} answered and was reset" in said
    assert "policy check failed, the episode was not started: policy " in said
    assert "is the openpi server running?" in said or "cannot reach" in said
    assert "fix it and press Enter to try again" in said
    entries = [json.loads(x) for x in (run / "journal.jsonl").read_text().splitlines()]
    assert [(e["kind"], sorted(e["trigger"])) for e in entries] == [
        ("success", ["policy", "starts"]),
        ("void", []),
    ]
    assert (
        entries[0]["trigger"]["policy"]["spec"] == spec and entries[0]["trigger"]["policy"]["reset"] is True
    )


def test_check_policy_resets_a_loopback_groot_server_each_episode(tmp_path):
    pytest.importorskip("zmq")
    from tests.policy_wrappers.test_groot import GrootServer

    run = tmp_path / "run"
    _plan(run, episodes=1)
    with GrootServer(lambda data: None) as srv:
        check = PolicyCheck(f"groot:tcp://127.0.0.1:{srv.port}?api=n1.6")
        op = Operator(["", "s", "", "f 2"])
        try:
            assert interactive(
                RealRun.open(run), ask=op.ask, say=op.said.append, triggers=[check], write=print
            )
        finally:
            check.close()
        endpoints = [r["endpoint"] for r in srv.requests]
    # load: ping + modality config; each started episode: ping, then GR00T N1.6's reset endpoint
    assert endpoints == ["ping", "get_modality_config", "ping", "reset", "ping", "reset"]


def test_check_policy_cli_refuses_an_unreachable_server_before_the_session(tmp_path, capsys):
    import socket

    run = tmp_path / "run"
    _plan(run, episodes=1)
    with socket.socket() as sock:  # a port nothing listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    capsys.readouterr()
    rc = main(
        ["real", "record", str(run), "--check-policy", f"openpi:ws://127.0.0.1:{port}?connect_timeout=2"]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 4 and "\n" not in err  # exit 4: the policy server is unreachable (docs/cli.md "Exit codes")
    assert err.endswith(f"connection refused at ws://127.0.0.1:{port}; is the openpi server running?")
    assert not (run / "journal.jsonl").exists()


_SIGTERM_SESSION = """
import os, shlex, signal, sys, threading
from indgen_vla.core.errors import Terminated
from indgen_vla.app.interrupts import sigterm_raises
from indgen_vla.app.real.trigger import EpisodeCommand, EpisodeContext

hang = "import os, time; print(os.getpid(), flush=True); time.sleep(60)"
trigger = EpisodeCommand(f"{shlex.quote(sys.executable)} -c {shlex.quote(hang)}", sys.argv[1])
ctx = EpisodeContext(run=sys.argv[1], axis="stack", task="stack", level=0, param=0.0, unit="", episode=0, attempt=0,
                     seed=1, instruction="", placement="", policy="p", video="")
said = []
timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGTERM))

def sigterm_once_running(text):
    said.append(text)
    if not timer.is_alive() and not timer.finished.is_set():
        timer.start()

try:
    with sigterm_raises():
        trigger.start(ctx, sigterm_once_running)
except Terminated:
    print("terminated", said[0].split()[0], flush=True)
"""


def test_sigterm_to_the_session_stops_the_episode_command(tmp_path):
    """``kill PID`` of ``indgen real record`` (or a SIGTERM from a logout) while the robot's command runs: the
    session stops as on Ctrl-C and takes the command with it; it used to run on, orphaned, with no one watching.
    The session runs in a process of its own: a SIGTERM that missed its handler must not end the test runner."""
    import subprocess

    r = subprocess.run([sys.executable, "-c", _SIGTERM_SESSION, str(tmp_path)], capture_output=True, text=True,
                       timeout=60)  # fmt: skip
    assert r.returncode == 0 and r.stdout.startswith("terminated "), (
        r.returncode,
        r.stdout,
        r.stderr[-2000:],
    )
    pid = int(r.stdout.split()[1])
    with pytest.raises(ProcessLookupError):  # ended and reaped, not left running
        os.kill(pid, 0)


def test_a_bad_check_policy_spec_names_the_option(tmp_path, capsys):
    run = tmp_path / "run"
    assert main(["real", "plan", "--setup", "stack", "--levels", "0:1", "--episodes", "5", "--policy", "p",
                 "--out", str(run)]) == 0  # fmt: skip
    capsys.readouterr()
    assert main(["real", "record", str(run), "--check-policy", "bogus:ws://h:1"]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("error: --check-policy bogus:ws://h:1: unknown policy family 'bogus' (known: "), (
        line
    )
    assert "openpi" in line
    assert not (run / "journal.jsonl").exists()
