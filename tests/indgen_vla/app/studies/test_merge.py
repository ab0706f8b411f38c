"""``indgen merge``: shards made by the real ``indgen evaluate`` (pick_place, random stand-in, short episodes) merged into
one run whose report is the report of one unsharded run of the same protocol; the refusals; the shards stay as they
were."""

import hashlib
import json
import shlex
import shutil
from pathlib import Path

import pandas as pd
import pytest

from indgen_vla.app.cli import main
from indgen_vla.core.runs.records import EpisodeRecord, RunDir

pytestmark = pytest.mark.filterwarnings("ignore")

EVAL = ["evaluate", "--policy", "standin:random", "--scene", "pick_place", "--task", "milk", "--levels", "0:1",
        "--episodes", "2", "--max-steps", "5", "--workers", "1"]  # fmt: skip


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Two shards (pick_y, scale) and the unsharded run of both axes, each by ``indgen evaluate`` (~7 s on 2 cores)."""
    root = tmp_path_factory.mktemp("runs")
    for name, axis in (("pick_y", "pick_y"), ("scale", "scale"), ("whole", "pick_y,scale")):
        assert main([*EVAL, "--axis", axis, "--out", str(root / name)]) == 0
    return root


def snapshot(*dirs: Path) -> dict[str, str]:
    """Every file under ``dirs`` by path, with its content's hash and its modification time."""
    return {str(p): f"{hashlib.sha256(p.read_bytes()).hexdigest()} {p.stat().st_mtime_ns}"
            for d in dirs for p in sorted(d.rglob("*")) if p.is_file()}  # fmt: skip


def read(run: Path, name: str) -> dict:
    return json.loads((run / name).read_text())


def outcomes(run: Path) -> pd.DataFrame:
    """The episodes without what differs between two runs of one protocol (run id, wall time, and whether a level-0 row
    is another axis's rollout: the unsharded run shares T0, shards of one axis each cannot)."""
    df = pd.read_parquet(run / "episodes.parquet").drop(columns=["run_id", "wall_s", "shared_from"])
    return df.sort_values(["axis", "task", "level", "episode"]).reset_index(drop=True)


def copy_shard(src: Path, dest: Path, manifest=None, rows=None) -> Path:
    """A copy of a shard with its manifest and rows edited (a shard of another protocol, a partial one)."""
    shutil.copytree(src, dest)
    if manifest is not None:
        m = read(dest, "manifest.json")
        manifest(m)
        (dest / "manifest.json").write_text(json.dumps(m))
    if rows is not None:
        run = RunDir.open(dest)
        run.rewrite(EpisodeRecord(**r) for r in rows(run.rows()))
    return dest


def refusal(capsys, *argv) -> str:
    """The one ``error:`` line of a refused ``indgen ARGV`` (exit 2; evaluate may say which certificates it read
    first)."""
    assert main(list(argv)) == 2
    err = capsys.readouterr().err.strip()
    errors = [line for line in err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and "Traceback" not in err, err
    return errors[0]


def test_merged_shards_report_like_one_unsharded_run(runs, tmp_path, capsys):
    shards = [runs / "pick_y", runs / "scale"]
    before = snapshot(*shards)
    assert main(["merge", *map(str, shards), "--out", str(tmp_path / "merged")]) == 0
    printed = capsys.readouterr().out
    merged, whole = tmp_path / "merged", runs / "whole"
    assert read(merged, "summary.json") == read(whole, "summary.json")
    assert (merged / "report.md").read_text() == (whole / "report.md").read_text()
    pd.testing.assert_frame_equal(outcomes(merged), outcomes(whole))
    shared = {n: set(pd.read_parquet(r / "episodes.parquet").query("level == 0 and axis == 'scale'")["shared_from"])
              for n, r in (("merged", merged), ("whole", whole))}  # fmt: skip
    assert shared == {"merged": {""}, "whole": {"pick_y"}}  # the same outcomes, rolled out once or twice
    m, w = read(merged, "manifest.json"), read(whole, "manifest.json")
    for key in (
        "plan",
        "axes",
        "resolved",
        "fingerprint",
        "policy",
        "scene",
        "seed",
        "versions",
        "t0_sharing",
        "reads_observations",
    ):
        assert m[key] == w[key], (
            key
        )  # the union plan is the unsharded plan, its jobs' hash and T0 sharing included
    assert m["t0_sharing"]["groups"] == {"milk": [["pick_y", "scale"]]}  # what a resume would share
    shard_manifests = [read(s, "manifest.json") for s in shards]
    assert [(e["path"], e["run_id"], e["episodes"], e["kept"]) for e in m["merged_from"]["shards"]] == [
        (str(s.resolve()), sm["run_id"], 4, 4) for s, sm in zip(shards, shard_manifests, strict=True)
    ]
    assert m["merged_from"]["identical_duplicates"] == 0 and m["command"].startswith("indgen merge ")
    run_ids = set(pd.read_parquet(merged / "episodes.parquet")["run_id"])
    assert run_ids == {sm["run_id"] for sm in shard_manifests}  # each row names the shard that ran it
    assert "merged 2 shards: 8 finished episodes of 8 planned; tasks milk; axes pick_y, scale" in printed
    assert snapshot(*shards) == before  # read, never written


@pytest.mark.slow  # ~12 s: a shard run, cut and merged
def test_merge_resumes_what_a_shard_did_not_finish(runs, tmp_path, capsys):
    """A shard cut short (its level 1 unfinished): the merge names the one evaluate command of the union, which
    finishes exactly the missing episodes into the merged run; the refusal of another command names it too."""
    partial = copy_shard(
        runs / "scale", tmp_path / "scale_cut", rows=lambda rs: [r for r in rs if r["level"] == 0]
    )
    before = snapshot(partial)
    merged = tmp_path / "merged"
    assert main(["merge", str(runs / "pick_y"), str(partial), "--out", str(merged)]) == 0
    resume = read(merged, "manifest.json")["merged_from"]["resume"]
    assert f"2 planned episode(s) are not finished; to run them: {resume}" in capsys.readouterr().out
    assert resume == (f"indgen evaluate --policy standin:random --scene pick_place --task milk --axis pick_y,scale "
                      f"--levels 0:1 --episodes 2 --max-steps 5 --out {merged}")  # fmt: skip
    err = refusal(capsys, *EVAL, "--axis", "scale", "--out", str(merged))
    assert f"is a merge of shards (indgen merge): resume it with {resume}" in err
    sharing = read(merged, "manifest.json")["t0_sharing"]
    assert main([*shlex.split(resume)[1:], "--workers", "1"]) == 0
    assert read(merged, "manifest.json")["t0_sharing"] == sharing  # the resume records the setting it found
    assert read(merged, "summary.json") == read(runs / "whole", "summary.json")
    pd.testing.assert_frame_equal(outcomes(merged), outcomes(runs / "whole"))
    assert snapshot(partial) == before


def _sharing_off(m):
    m["t0_sharing"] = {
        "enabled": False,
        "reason": "off (--no-share-t0)",
        "groups": {},
        "rollouts": 4,
        "saved": 0,
    }


def test_the_merged_manifest_carries_the_shards_t0_sharing_and_refuses_two_settings(runs, tmp_path, capsys):
    """Shards run with --no-share-t0: the merge records sharing off and resumes with --no-share-t0; a shard that
    shares beside one that does not is refused in one line naming both."""
    off = [copy_shard(runs / a, tmp_path / a, manifest=_sharing_off) for a in ("pick_y", "scale")]
    assert main(["merge", *map(str, off), "--out", str(tmp_path / "merged")]) == 0
    m = read(tmp_path / "merged", "manifest.json")
    assert m["t0_sharing"] == {"enabled": False, "reason": "off (--no-share-t0)", "groups": {}, "rollouts": 8,
                               "saved": 0}  # fmt: skip
    assert m["config"]["share_t0"] is False
    assert m["merged_from"]["resume"].endswith(f"--no-share-t0 --out {tmp_path / 'merged'}")
    capsys.readouterr()
    err = refusal(capsys, "merge", str(runs / "pick_y"), str(off[1]), "--out", str(tmp_path / "mixed"))
    assert (
        f"{runs / 'pick_y'} shares level 0 across axes (manifest t0_sharing) and {off[1]} does not (off "
        in err
    )
    assert "resume one of them with the other's (--share-t0 or --no-share-t0" in err


def test_identical_duplicates_are_kept_once_and_retried_errors_give_way(runs, tmp_path, capsys):
    def one_error(rows):
        rows[0].update(status="error", success=False, error="RuntimeError: simulator", failure="error")
        return rows

    copy = copy_shard(runs / "pick_y", tmp_path / "pick_y_copy")  # e.g. a shard run twice, on two machines
    failed = copy_shard(runs / "scale", tmp_path / "scale_error", rows=one_error)
    merged = tmp_path / "merged"
    shards = [runs / "pick_y", failed, copy, runs / "scale"]
    assert main(["merge", *map(str, shards), "--out", str(merged)]) == 0
    said = capsys.readouterr().out
    assert "kept one copy of 7 episode(s) found in two shards with the same outcome" in said
    m = read(merged, "manifest.json")["merged_from"]
    assert (m["identical_duplicates"], m["retried_errors"]) == (4 + 3, 1)
    assert [e["kept"] for e in m["shards"]] == [4, 3, 0, 1]  # the error row gave way to the ok one
    assert read(merged, "summary.json") == read(runs / "whole", "summary.json")


def edit(path: str, value):
    """A manifest edit setting the dotted ``path`` (e.g. ``plan.seed``)."""

    def apply(m):
        *parents, leaf = path.split(".")
        for p in parents:
            m = m[p]
        m[leaf] = value

    return apply


@pytest.mark.parametrize(
    ("change", "says"),
    [
        (edit("plan.policy", "standin:noop"), "plan policy is standin:random vs standin:noop"),
        (edit("plan.seed", 7), "plan seed is 0 vs 7"),
        (edit("plan.episodes", 3), "plan episodes is 2 vs 3"),
        (edit("fingerprint.simulator.mujoco", "3.1.0"), "their protocols differ in simulator"),
        (edit("fingerprint.policy.conventions", "Conventions(chunk=10)"), "their protocols differ in policy.conventions"),
        (edit("measurement", "not a measurement (--smoke)"), "measurement is"),
    ],
    ids=["policy", "seed", "episodes", "simulator", "conventions", "smoke"],
)  # fmt: skip
def test_shards_of_another_protocol_are_refused(runs, tmp_path, capsys, change, says):
    other = copy_shard(runs / "scale", tmp_path / "other", manifest=change)
    err = refusal(capsys, "merge", str(runs / "pick_y"), str(other), "--out", str(tmp_path / "merged"))
    assert "are not shards of one protocol: " + says in err and "merge only the shards of one evaluate" in err
    assert not (tmp_path / "merged").exists()


def test_refusals_name_the_problem(runs, tmp_path, capsys):
    a, b, out = str(runs / "pick_y"), str(runs / "scale"), tmp_path / "merged"
    levels = copy_shard(
        runs / "pick_y", tmp_path / "levels", manifest=edit("plan.levels", {"pick_y": [0, 1, 2]})
    )
    assert "axis pick_y has levels [0, 1] vs [0, 1, 2]" in refusal(
        capsys, "merge", a, str(levels), "--out", str(out)
    )

    def flip(rows):
        rows[1]["success"] = not rows[1]["success"]
        return rows

    flipped = copy_shard(runs / "pick_y", tmp_path / "flipped", rows=flip)
    err = refusal(capsys, "merge", a, str(flipped), "--out", str(out))
    assert "both hold episode 1 of milk/pick_y level 0 with different outcomes (success False vs True)" in err

    def bread(m):
        m["plan"]["tasks"] = ["bread"]
        for c in m["resolved"]["cells"]:
            c["task"] = "bread"

    gap = copy_shard(runs / "scale", tmp_path / "bread", manifest=bread)
    assert "no shard plans task bread on axis pick_y" in refusal(
        capsys, "merge", a, str(gap), "--out", str(out)
    )
    assert "same run directory" in refusal(capsys, "merge", a, a + "/", "--out", str(out))
    assert "two or more shard" in refusal(capsys, "merge", a, "--out", str(out))
    assert "does not exist" in refusal(capsys, "merge", a, str(tmp_path / "nowhere"), "--out", str(out))
    assert "lies inside shard" in refusal(capsys, "merge", a, b, "--out", str(runs / "scale" / "merged"))
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert "exists and is not empty" in refusal(capsys, "merge", a, b, "--out", str(out))
    assert (out / "notes.txt").read_text() == "mine" and not any(tmp_path.glob(".merged.merging-*"))


@pytest.mark.slow  # 15 s: four real shards of the stack scene, one killed midway, and the unsharded run
def test_per_task_shards_with_one_killed_resume_as_task_all(tmp_path, capsys):
    """The cluster case: a SLURM array with one job per task, one killed. Merged in any order, the shards plan
    ``--task all`` in the scene's task order; its command finishes the killed shard's episodes in the merged run."""
    from tests.fixtures.kill import kill_midway

    args = ["evaluate", "--policy", "standin:random", "--scene", "stack", "--axis", "pick_y", "--levels", "0:1",
            "--episodes", "2", "--max-steps", "5", "--workers", "1"]  # fmt: skip
    tasks = ["orange_on_blue", "red_on_green", "yellow_on_red", "blue_on_yellow"]
    assert main([*args, "--task", "all", "--out", str(tmp_path / "whole")]) == 0
    for t in tasks[1:]:
        assert main([*args, "--task", t, "--out", str(tmp_path / t)]) == 0
    assert 0 < kill_midway([*args, "--task", tasks[0]], tmp_path / tasks[0], total=4) < 4
    shards = [str(tmp_path / t) for t in reversed(tasks)]
    assert main(["merge", *shards[:2], "--out", str(tmp_path / "two")]) == 0  # no command plans two tasks
    two = read(tmp_path / "two", "manifest.json")["merged_from"]
    assert two["resume"] is None and two["resume_note"].startswith("tasks blue_on_yellow, yellow_on_red are")
    merged = tmp_path / "merged"
    assert main(["merge", *shards, "--out", str(merged)]) == 0
    m = read(merged, "manifest.json")
    assert m["plan"] == read(tmp_path / "whole", "manifest.json")["plan"]  # the scene's task order, not ours
    assert "--task all" in m["merged_from"]["resume"]
    assert main([*shlex.split(m["merged_from"]["resume"])[1:], "--workers", "1"]) == 0
    assert read(merged, "summary.json") == read(tmp_path / "whole", "summary.json")


def test_a_killed_merges_temporary_tree_is_removed_by_the_next_merge(runs, tmp_path):
    """A merge killed before its rename leaves ``.OUT.merging-PID``; the next merge into OUT removes it when PID is
    gone, and leaves one whose process still runs (a merge in progress) alone."""
    import subprocess
    import sys

    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        stale, running = (tmp_path / f".merged.merging-{p.pid}" for p in (dead, live))
        for d in (stale, running):
            (d / "videos").mkdir(parents=True)
        assert (
            main(["merge", str(runs / "pick_y"), str(runs / "scale"), "--out", str(tmp_path / "merged")]) == 0
        )
        assert not stale.exists() and running.is_dir()
        assert (tmp_path / "merged" / "summary.json").is_file()
    finally:
        live.kill()
        live.wait()


@pytest.mark.slow  # ~10 s: a merge killed before its report
def test_a_merge_stopped_before_its_report_is_finished_by_running_it_again(runs, tmp_path, capsys):
    """Ctrl-C or a kill between the rename and the report leaves OUT with the merged episodes and no report; the same
    merge again writes the report (it used to refuse: "exists and is not empty"). Other shards still refuse."""
    shards, out = [str(runs / "pick_y"), str(runs / "scale")], tmp_path / "merged"
    assert main(["merge", *shards, "--out", str(out)]) == 0
    want = (out / "report.md").read_text()
    kept = {n: (out / n).stat().st_mtime_ns for n in ("episodes.parquet", "manifest.json")}
    (out / "report.md").unlink()
    shutil.rmtree(out / "plots")
    (out / "summary.json").unlink()
    assert main(["merge", *shards, "--out", str(out)]) == 0
    assert (out / "report.md").read_text() == want and (out / "plots").is_dir()
    assert {n: (out / n).stat().st_mtime_ns for n in kept} == kept  # the episodes are not written again
    capsys.readouterr()
    assert "exists and is not empty" in refusal(
        capsys, "merge", shards[0], str(runs / "whole"), "--out", str(out)
    )


def test_shards_on_other_numerics_merge_with_a_warning_and_keep_each_shards_numerics(runs, tmp_path, capsys):
    """A shard run where torch dispatched to another instruction set is the same protocol (merged), but the merge says
    so in a line and the merged manifest keeps each shard's numerics."""

    def avx2(m: dict) -> None:
        m["fingerprint"]["numerics"] = {**m["fingerprint"]["numerics"], "cpu_isa": "avx2"}

    other = copy_shard(runs / "scale", tmp_path / "scale_avx2", manifest=avx2)
    assert main(["merge", str(runs / "pick_y"), str(other), "--out", str(tmp_path / "merged")]) == 0
    printed = capsys.readouterr().out
    assert f"warning: {other} ran on other numerics (cpu_isa " in printed and "vs avx2" in printed
    entries = read(tmp_path / "merged", "manifest.json")["merged_from"]["shards"]
    assert entries[1]["numerics"]["cpu_isa"] == "avx2" != entries[0]["numerics"]["cpu_isa"]


def test_an_unavailable_episode_is_finished_in_a_merge(runs, tmp_path, capsys):
    """An episode its level rules out (status ``unavailable``) is finished: the merge counts it as such and asks for
    no run of it, as a resume would run none."""

    def rule_out_one(rows: list[dict]) -> list[dict]:
        first = dict(rows[0], status="unavailable", success=False, failure="unavailable", progress=None,
                     error="attempt 1: EpisodeUnavailableError: placement check")  # fmt: skip
        return [first, *rows[1:]]

    shard = copy_shard(runs / "pick_y", tmp_path / "pick_y_ruled_out", rows=rule_out_one)
    assert main(["merge", str(shard), str(runs / "scale"), "--out", str(tmp_path / "merged")]) == 0
    printed = capsys.readouterr().out
    assert "8 finished episodes (1 of them unavailable: ruled out by their level) of 8 planned" in printed
    assert "error rows" not in printed and "not finished" not in printed
