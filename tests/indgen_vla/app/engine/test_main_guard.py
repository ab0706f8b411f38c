"""A script that evaluates at its unguarded top level is refused in one line before any worker starts (each worker
would import it and run it again); a guarded call, ``python -c`` and ``python -m package`` pass."""

from __future__ import annotations

import subprocess
import sys
import textwrap

from indgen_vla.app.engine.main_guard import guard_lines

CHECK = "from indgen_vla.app.engine.main_guard import check_main_guard\n"


def _run(tmp_path, code: str, *args: str) -> subprocess.CompletedProcess:
    (tmp_path / "script.py").write_text(textwrap.dedent(code))
    return subprocess.run([sys.executable, *args], cwd=tmp_path, capture_output=True, text=True, timeout=120)


def test_an_unguarded_evaluation_is_refused_before_any_worker_starts(tmp_path):
    """The api.md example as a script with two workers: one line naming the script's line and the guard, the
    script's top level ran once (no worker re-ran it), and no run directory was written."""
    r = _run(tmp_path, """
        import indgen_vla
        print("top level ran", flush=True)
        indgen_vla.evaluate(policy="standin:oracle", scene="pick_place", axis="pick_y", levels="0", episodes=2,
                            out="runs/x", workers=2, quiet=True)
        """, "script.py")  # fmt: skip
    assert r.returncode != 0 and r.stdout.count("top level ran") == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith(
        "indgen_vla.core.errors.ConfigError: script.py line 4 starts indgen's worker processes"
    )
    assert 'if __name__ == "__main__":' in last and "died" not in r.stderr
    assert not (tmp_path / "runs" / "x" / "episodes.parquet").exists()


def test_a_guarded_call_a_command_string_and_a_function_pass(tmp_path):
    guarded = _run(
        tmp_path, CHECK + 'if __name__ == "__main__":\n    check_main_guard()\n    print("ok")\n', "script.py"
    )
    assert guarded.returncode == 0 and guarded.stdout.strip() == "ok", guarded.stderr
    assert _run(tmp_path, "", "-c", CHECK + "check_main_guard(); print('ok')").stdout.strip() == "ok"
    # a function of the script called from its unguarded top level is refused at the calling line
    r = _run(tmp_path, CHECK + "def main():\n    check_main_guard()\n\n\nmain()\n", "script.py")
    assert r.returncode != 0 and "script.py line 6 starts" in r.stderr.strip().splitlines()[-1]


def test_guard_lines_finds_top_level_name_tests_only(tmp_path):
    f = tmp_path / "s.py"
    f.write_text('x = 1\nif __name__ == "__main__":\n    a = 1\n    b = 2\nif x:\n    if __name__ == "__main__":\n'
                 "        pass\n")  # fmt: skip
    assert guard_lines(str(f)) == ((2, 4),)
    (tmp_path / "bad.py").write_text("def (:\n")
    assert guard_lines(str(tmp_path / "bad.py")) is None  # unreadable source: nothing refused
