import os
import signal
import subprocess
import sys
import textwrap
import time

import pandas as pd
import pytest

from indgen_vla.core.errors import RunDirError
from indgen_vla.core.runs.records import COLUMNS, EPISODES, MANIFEST, EpisodeRecord, RunDir


def rec(level, episode, success=True, status="ok", task="t", axis="pick_y"):
    return EpisodeRecord(
        run_id="r", policy="standin:noop", data_regime="", scene="s", task=task, axis=axis, level=level,
        param=0.025 * level, episode=episode, seed=1000 + episode, success=success, steps=10, status=status,
        error="boom" if status == "error" else "",
    )  # fmt: skip


def test_append_and_resume(tmp_path):
    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0), rec(0, 1, success=False)])
    run.append([rec(1, 0, status="error")])
    df = pd.read_parquet(tmp_path / "run" / EPISODES)
    assert list(df.columns) == list(COLUMNS) and len(df) == 3
    again = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    assert again.done_keys() == {("t", "pick_y", 0, 0), ("t", "pick_y", 0, 1)}
    assert ("t", "pick_y", 1, 0) in again.done_keys(include_errors=True)
    again.append([rec(1, 0)])  # the retried episode replaces its error row
    df = RunDir.open(tmp_path / "run").episodes()
    assert len(df) == 3 and (df["status"] == "ok").all()
    with pytest.raises(RunDirError, match="already recorded"):
        again.append([rec(0, 0)])


def test_costly_rewrites_are_deferred_until_flush(tmp_path, monkeypatch):
    """Once a rewrite of episodes.parquet is costly (a long run), appends within the throttle window stay in
    memory (the run sees them) and ``flush()`` writes them; cheap rewrites happen per append (above)."""
    import indgen_vla.core.runs.records as records

    monkeypatch.setattr(records, "FLUSH_EVERY_ROWS", 0)  # every run counts as long
    monkeypatch.setattr(records, "FLUSH_SHARE", 1e-9)  # and the window after one is long
    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])  # the first append is written (no rewrite yet to wait after)
    run.append([rec(0, 1)])
    assert len(pd.read_parquet(tmp_path / "run" / EPISODES)) == 1 and len(run.episodes()) == 2
    assert run.done_keys() == {("t", "pick_y", 0, 0), ("t", "pick_y", 0, 1)}
    run.flush()
    assert len(pd.read_parquet(tmp_path / "run" / EPISODES)) == 2
    mtime = (tmp_path / "run" / EPISODES).stat().st_mtime_ns
    run.flush()  # nothing pending: no rewrite
    assert (tmp_path / "run" / EPISODES).stat().st_mtime_ns == mtime


def test_manifest_mismatch_refused(tmp_path):
    RunDir.create_or_resume(tmp_path, {"plan": {"seed": 0, "episodes": 5}})
    with pytest.raises(RunDirError, match="different plan .*episodes") as e:
        RunDir.create_or_resume(tmp_path, {"plan": {"seed": 0, "episodes": 6}})
    # the first difference's two values, so the user sees which command made the run
    assert "(differs in: episodes; episodes: 5 in the run, 6 now)" in str(e.value)
    with pytest.raises(RunDirError) as e:  # too long for one line: named, not printed
        RunDir.create_or_resume(tmp_path, {"plan": {"seed": 0, "episodes": 5, "tasks": ["t" * 80, "u" * 80]}})
    assert "(differs in: tasks); use a new --out" in str(e.value)
    with pytest.raises(RunDirError) as e:  # a secret in a spec stays masked in the line
        RunDir.create_or_resume(tmp_path, {"plan": {"seed": 0, "episodes": "openpi:ws://h:1?api_key=SECRET"}})
    assert "SECRET" not in str(e.value) and "api_key=***" in str(e.value)


def test_episodes_without_a_manifest_are_never_adopted(tmp_path):
    """A run dir whose manifest.json is gone holds rows no plan vouches for: a resume under any plan would
    report them as its own, so it is refused and the rows stay as they were."""
    import indgen_vla.core.runs.records as records

    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])
    (tmp_path / "run" / MANIFEST).unlink()
    before = (tmp_path / "run" / EPISODES).read_bytes()
    with pytest.raises(RunDirError, match="holds episodes but no manifest.json.*restore its manifest.json"):
        RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 1}})
    assert (tmp_path / "run" / EPISODES).read_bytes() == before and not (tmp_path / "run" / MANIFEST).exists()
    (tmp_path / "run" / EPISODES).unlink()  # rows only in the journal (killed between rewrites) count too
    (tmp_path / "run" / records.JOURNAL).write_text('{"task":"t","axis":"pick_y","level":0,"episode":1}\n')
    with pytest.raises(RunDirError, match="no manifest.json"):
        RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 1}})


def test_open_errors(tmp_path):
    with pytest.raises(RunDirError, match="does not exist"):
        RunDir.open(tmp_path / "nope")
    with pytest.raises(RunDirError, match="no manifest.json; .*pass the --out of an 'indgen evaluate' run"):
        RunDir.open(tmp_path)
    for name in ("b", "a"):  # a folder of runs (e.g. runs/): the line names the runs in it
        RunDir.create_or_resume(tmp_path / "runs" / name, {"plan": {}})
    with pytest.raises(RunDirError) as e:
        RunDir.open(tmp_path / "runs")
    assert str(e.value).endswith(
        f"; pass the runs in it instead: {tmp_path / 'runs' / 'a'} {tmp_path / 'runs' / 'b'}"
    )
    (tmp_path / MANIFEST).write_text("{not json")
    with pytest.raises(RunDirError, match="corrupt"):
        RunDir.open(tmp_path)
    (tmp_path / MANIFEST).write_text("{}")
    (tmp_path / EPISODES).write_bytes(b"PAR1garbage")
    with pytest.raises(RunDirError, match="corrupt"):
        RunDir.open(tmp_path)


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_unwritable(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(RunDirError, match="cannot write"):
        RunDir.create_or_resume(ro / "x", {"plan": {}})


def test_unwritable_file_target(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(RunDirError, match="cannot write"):
        RunDir.create_or_resume(blocker / "run", {"plan": {}})


def test_sigkill_never_corrupts(tmp_path):
    """A writer killed at arbitrary moments leaves a readable file holding a prefix of its episodes."""
    script = textwrap.dedent(f"""
        from indgen_vla.core.runs.records import RunDir, EpisodeRecord
        run = RunDir.create_or_resume({str(tmp_path)!r}, {{"plan": {{}}}})
        done = run.done_keys()
        for i in range(100000):
            if ("t", "a", 0, i) in done:
                continue
            run.append([EpisodeRecord("r", "p", "", "s", "t", "a", 0, 0.0, i, i, i % 2 == 0, 3)])
            if i == len(done):
                print("writing", flush=True)
    """)
    for delay in (0.1, 0.3, 0.6):
        proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline() == "writing\n"  # a row is down; kill mid-stream even under load
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        df = RunDir.open(tmp_path).episodes()
        # rows are exactly episodes 0..n-1: nothing lost in the middle, nothing duplicated
        assert sorted(df["episode"]) == list(range(len(df)))
    assert len(df) > 0
    RunDir.create_or_resume(tmp_path, {"plan": {}})  # resuming sweeps temp files a kill left behind
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".") and p != ".episodes.journal"]


def test_run_dir_from_before_the_failure_column_still_reads_and_resumes(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])
    old = pq.read_table(tmp_path / "run" / EPISODES).drop(["failure"])  # what an older release wrote
    pq.write_table(old, tmp_path / "run" / EPISODES)
    again = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    assert again.episodes()["failure"].tolist() == [""]  # not classified, not invented
    again.append([rec(0, 1)])
    assert pa.parquet.read_table(tmp_path / "run" / EPISODES).column("failure").to_pylist() == ["", ""]


def test_progress_column_round_trips_and_is_validated(tmp_path):
    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    r = rec(0, 0)
    run.append([type(r)(**{**r.__dict__, "progress": 4}), rec(0, 1)])  # rec() leaves progress unscored
    df = RunDir.open(tmp_path / "run").episodes()
    assert str(df["progress"].dtype) == "Int8"
    assert df["progress"].iloc[0] == 4 and df["progress"].isna().iloc[1]  # unscored stays missing, never 0
    for bad in (6, -1, True, 2.5):
        with pytest.raises(ValueError, match="progress must be an integer 0..5"):
            type(r)(**{**r.__dict__, "progress": bad})


def test_a_kill_between_deferred_rewrites_loses_no_episode(tmp_path, monkeypatch):
    """Deferred rows are journalled first: a run killed before its next rewrite (no flush) resumes with every
    finished episode, an error row later replaced stays replaced, and a torn last journal line is dropped."""
    import indgen_vla.core.runs.records as records

    monkeypatch.setattr(records, "FLUSH_EVERY_ROWS", 0)
    monkeypatch.setattr(records, "FLUSH_SHARE", 1e-9)
    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])  # written to episodes.parquet
    run.append([rec(0, 1, status="error")])  # deferred: only in the journal
    run.append([rec(0, 1), rec(1, 0)])  # the retry replaces the error row; still deferred
    assert len(pd.read_parquet(tmp_path / "run" / EPISODES)) == 1
    with open(tmp_path / "run" / records.JOURNAL, "ab") as f:
        f.write(b'{"run_id":"r","task":"t"')  # the kill cut this write short
    del run  # SIGKILL: no flush
    resumed = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    assert resumed.done_keys() == {("t", "pick_y", 0, 0), ("t", "pick_y", 0, 1), ("t", "pick_y", 1, 0)}
    resumed.append([rec(2, 0)])  # appends after the trimmed line are read back
    assert len(RunDir.open(tmp_path / "run").episodes()) == 4
    resumed.flush()
    assert len(pd.read_parquet(tmp_path / "run" / EPISODES)) == 4
    assert not (tmp_path / "run" / records.JOURNAL).exists()


def test_atomic_writes_follow_the_umask_not_mkstemps_0600(tmp_path):
    """A run directory's files get 0o666 less the umask, as a plain open() would: mkstemp's owner-only 0o600
    made every manifest, summary and plot unreadable to the rest of a team sharing the runs."""
    from indgen_vla.core.runs.records import atomic_write_json, atomic_write_text

    old = os.umask(0o022)
    try:
        atomic_write_json(tmp_path / "a.json", {"x": 1})
        atomic_write_text(tmp_path / "b.md", "hi\n")
        os.umask(0o077)
        atomic_write_text(tmp_path / "c.md", "private\n")
    finally:
        os.umask(old)
    assert (tmp_path / "a.json").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "b.md").stat().st_mode & 0o777 == 0o644
    assert (tmp_path / "c.md").stat().st_mode & 0o777 == 0o600


def _slow_episodes(path):
    """The episodes built from one dict per row (the path every writer takes), for comparison."""
    run = RunDir(path)
    run._load()
    return run.episodes()


def test_a_reader_gets_the_same_episodes_straight_from_the_parquet_table(tmp_path):
    """``episodes()`` of a run nobody appends to reads the Parquet table directly; it must equal the rows a writer
    keeps (dtypes, order, legacy files without the optional columns), and fall back whenever they could differ."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    run = RunDir.create_or_resume(tmp_path / "r", {"plan": {"seed": 0}})
    run.append([rec(1, 0), rec(0, 1, success=False), rec(0, 0, status="error"), rec(-1, 3, task="a")])
    reader = RunDir.open(tmp_path / "r")
    fast = reader.episodes()
    assert reader._rows is None  # it took the table, not the dicts
    pd.testing.assert_frame_equal(fast, _slow_episodes(tmp_path / "r"), check_exact=True)
    assert list(fast.dtypes.astype(str)) == list(_slow_episodes(tmp_path / "r").dtypes.astype(str))
    legacy = pq.read_table(tmp_path / "r" / EPISODES).drop(["failure", "progress"])
    pq.write_table(legacy, tmp_path / "r" / EPISODES)  # a run dir from before both columns
    pd.testing.assert_frame_equal(RunDir(tmp_path / "r").episodes(), _slow_episodes(tmp_path / "r"))
    dup = pa.concat_tables([legacy, legacy.slice(0, 1)])  # a key twice: the dicts keep the last row
    pq.write_table(dup, tmp_path / "r" / EPISODES)
    assert len(RunDir(tmp_path / "r").episodes()) == 4
    pd.testing.assert_frame_equal(RunDir(tmp_path / "r").episodes(), _slow_episodes(tmp_path / "r"))


def test_a_journal_or_an_append_sends_episodes_through_the_rows(tmp_path, monkeypatch):
    import indgen_vla.core.runs.records as records

    monkeypatch.setattr(records, "FLUSH_EVERY_ROWS", 0)
    monkeypatch.setattr(records, "FLUSH_SHARE", 1e-9)
    run = RunDir.create_or_resume(tmp_path / "r", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])
    run.append([rec(0, 1)])  # deferred: in the journal, not yet in episodes.parquet
    assert len(RunDir(tmp_path / "r").episodes()) == 2  # a reader replays the journal
    reader = RunDir(tmp_path / "r")
    run.flush()
    assert len(reader.episodes()) == 2 and reader._rows is None
    reader.append([rec(0, 2)])  # a reader turned writer keeps its rows from then on
    assert len(reader.episodes()) == 3 and reader._rows is not None


def test_a_reader_never_sees_a_run_being_rewritten_as_corrupt(tmp_path):
    """``indgen report`` on a live run: each append rewrites episodes.parquet by rename; a read by path could take the
    old file's size and the new file's bytes ("Page was smaller than expected": about 2 % of such reads here)."""
    import threading

    run = RunDir.create_or_resume(tmp_path / "run", {"plan": {"seed": 0}})
    run.append([rec(0, 0)])
    done, failures = threading.Event(), []

    def write() -> None:
        for i in range(1, 250):
            run.append(
                [rec(i % 7, i, task=f"t{i}")]
            )  # < FLUSH_EVERY_ROWS rows: every append rewrites the file
        done.set()

    writer = threading.Thread(target=write)
    writer.start()
    reads = 0
    while not done.is_set():
        try:
            RunDir(tmp_path / "run")._read_table()
        except RunDirError as e:
            failures.append(str(e))
        reads += 1
    writer.join()
    assert reads > 20 and not failures, (reads, failures[:1])
