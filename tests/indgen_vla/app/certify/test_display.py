"""What ``indgen certify`` shows while it runs: a line per level when piped, evaluate's live rows on a terminal.

5 control steps cannot solve ``stack``, so each level stops at its first (failed) episode: cheap, and it checks
that a level the rule stops early shrinks the total.
"""

import io

import pytest

from indgen_vla.app.certify.display import CertifyDisplay
from indgen_vla.app.cli import main
from tests.fixtures.certify import run_certify


def test_piped_certify_prints_a_line_when_it_starts_and_per_level(tmp_path, capsys):
    argv = ["certify", "--scene", "stack", "--axis", "stack", "--levels", "0:1", "--episodes", "2", "--max-steps", "5",
            "--out", str(tmp_path)]  # fmt: skip
    assert main(argv) == 1  # every level failed
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith("certifying stack/orange_on_blue/stack: levels 0, 1 (at most 2 episodes each")
    assert [x.split(" (")[0] for x in err if x.startswith("stack/")] == [
        "stack/orange_on_blue/stack level 0: 0/1 CP95 lower 0.000 -> failed",
        "stack/orange_on_blue/stack level 1: 0/1 CP95 lower 0.000 -> failed",
    ]


def test_on_a_terminal_each_level_is_a_live_row_and_reused_levels_say_so(tmp_path):
    from rich.console import Console

    def run(levels: str) -> str:
        buf = io.StringIO()
        console = Console(file=buf, force_terminal=True, width=120, color_system=None)
        with CertifyDisplay("stack", "orange_on_blue", "stack", console=console) as d:
            assert d.live
            run_certify("stack", "stack", levels=levels, episodes=2, max_steps=5, path=tmp_path / "certify.json",
                    log=d.log, watch=d)  # fmt: skip
        return buf.getvalue().split("\r")[-1]  # the last refresh of the rows

    last = run("0:1")
    assert "all episodes" in last and "2/2" in last and "/4" not in last  # stopped early: the total shrank
    rows = {ln.split()[1]: ln for ln in last.splitlines() if ln.startswith("stack L")}
    assert set(rows) == {"L+0", "L+1"} and all("success 0/1 failed" in r for r in rows.values())
    last = run("0:2")
    rows = {ln.split()[1]: ln for ln in last.splitlines() if ln.startswith("stack L")}
    assert all("reused: failed" in rows[k] for k in ("L+0", "L+1")) and "success 0/1 failed" in rows["L+2"]


class Recorder:
    """A display that keeps what ``certify`` told it."""

    def __init__(self):
        self.started, self.episodes, self.levels = None, [], []

    def start(self, levels, reused, n_max):
        self.started = (list(levels), n_max)

    def episode(self, level, successes, n):
        self.episodes.append((level, successes, n))

    def level(self, row):
        self.levels.append(row["level"])

    def log(self, text):
        pass


@pytest.mark.slow  # two spawned workers import the simulator: ~20 s
def test_pool_workers_report_each_episode_while_they_run(tmp_path):
    seen = Recorder()
    run_certify(
        "pick_place", "pick_y", levels="0:1", episodes=2, workers=2, path=tmp_path / "c.json", watch=seen
    )
    assert seen.started == ([0, 1], 2) and sorted(seen.levels) == [0, 1]
    # the oracle solves pick_place: (level, successes, n) after each episode
    assert sorted(seen.episodes) == [(0, 1, 1), (0, 2, 2), (1, 1, 1), (1, 2, 2)]
